"""Time parameterisation of a plan: constant weld speed, TOPPRA limits, Ruckig pieces."""

from rfsw_plan.timing.trajectory import TimedTrajectory, TimingLimits, time_parameterise

__all__ = ["TimedTrajectory", "TimingLimits", "time_parameterise"]
