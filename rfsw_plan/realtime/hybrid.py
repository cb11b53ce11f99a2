"""Hybrid: the offline plan, plus a real-time correction of only the force residual.

The offline plan already cancels the model deflection under the force it was planned for,
including the plunge and dwell ramp. What it cannot know is how the real process force
differs from that plan (drift along the seam, a harder batch of material). The hybrid
correction cancels the lateral part of the *residual* deflection

    dX_res,k = dX_model(q_k, F_measured,k) - dX_model(q_k, F_planned,k),

smoothed by the same exponential average as seed 000 but heavier (default 95 % per cycle,
a time constant of about 80 ms at 4 ms): the residual varies slowly, so a slow filter costs
little tracking and keeps the sensor noise out. At the weld start the residual is small (the
plan already holds the pin in the window), so there is no settling transient.
"""

from __future__ import annotations

from rfsw_plan.realtime.base import ControllerInputs, FloatArray
from rfsw_plan.realtime.force_feedback import ExponentialAverageCompensation, _lateral_target


class HybridResidual(ExponentialAverageCompensation):
    """Lateral correction of the model deflection under (measured - planned) wrench.

    corr_k = a corr_{k-1} + (1 - a) (-(dX_res,k . l_k) l_k), a = ``average_percent``/100.
    """

    name = "hybrid"
    description = "offline plan + averaged real-time correction of the force residual"

    def __init__(self, average_percent: float = 95.0, update_period_s: float | None = None) -> None:
        super().__init__(average_percent, update_period_s)

    def target(self, inputs: ControllerInputs) -> FloatArray:
        residual = inputs.model_deflection - inputs.model_deflection_planned
        return _lateral_target(residual, inputs.lateral)
