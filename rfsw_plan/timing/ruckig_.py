"""Ruckig adapter: jerk-limited one-degree-of-freedom profiles.

The only module that imports ``ruckig``. Open-source Ruckig plans point-to-point (or to a target
velocity) motions with velocity, acceleration and jerk limits; the planner uses it on scalar
coordinates (depth along the tool axis, arc length along the seam) and maps them to joints.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InfeasibleError

FloatArray = NDArray[np.float64]


def profile_1dof(
    x0: float, x1: float | None, v0: float, v1: float, vmax: float, amax: float, jmax: float,
    dt: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Sampled jerk-limited profile of one coordinate.

    Args:
        x0: Start position.
        x1: Target position, or None to only reach the target velocity (velocity interface).
        v0: Start velocity.
        v1: Target velocity.
        vmax, amax, jmax: Limits of velocity, acceleration and jerk (> 0).
        dt: Sample time [s].

    Returns:
        (t, x, v, a) sampled every dt including both ends, t from 0.
    """
    from ruckig import ControlInterface, InputParameter, Result, Ruckig, Trajectory

    inp = InputParameter(1)
    inp.current_position = [x0]
    inp.current_velocity = [v0]
    inp.current_acceleration = [0.0]
    inp.target_velocity = [v1]
    inp.target_acceleration = [0.0]
    inp.max_velocity = [vmax]
    inp.max_acceleration = [amax]
    inp.max_jerk = [jmax]
    if x1 is None:
        inp.control_interface = ControlInterface.Velocity
        inp.target_position = [x0]
    else:
        inp.target_position = [x1]
    traj = Trajectory(1)
    res = Ruckig(1).calculate(inp, traj)
    if res not in (Result.Working, Result.Finished):
        raise InfeasibleError(f"Ruckig could not plan a profile ({res})", constraint="ruckig")
    T = float(traj.duration)
    n = max(int(np.ceil(T / dt)), 1)
    t = np.linspace(0.0, T, n + 1)
    out = np.array([[v[0] for v in traj.at_time(float(ti))] for ti in t])
    return t, out[:, 0], out[:, 1], out[:, 2]
