"""Force-feedback filtered correction (seed 000 Fig. 14): force -> elastostatic model -> average.

The control law: the measured process wrench, through the elastostatic model, gives the lateral
deflection to cancel; an exponential average filters it (:class:`ForceFeedbackFilteredCorrection`,
strategy ``realtime_seed000`` in ``rfsw-plan compare``).

Seed 000 §3.2.6: the load cell in the FSW end effector measures the process wrench; the
identified elastostatic model (eq. 11, dX = J C J^T F) turns it into the lateral tool deviation
Δy_m; the controller shifts the path by -Δy_m. "Because of measurement noise, an average
correction is done. The average is a percentage between 1 and 100 % [...] A lowest value of the
average results in a fast correction. However, wobbling on the path can appear. [...] the
percentage is fixed to 50 %."

Our reading (the paper gives no formula): the percentage ``a`` is the weight of the previous
correction in an exponential average,

    corr_j = a corr_{j-1} + (1 - a) (-(dX_j . l_j) l_j),

so a low percentage follows the model fast but passes the noise (the "wobbling"), and a high
one is smooth but slow. The correction is applied (held) every controller cycle; the model +
average is updated every ``update_period_s``. The paper does not give that period. It cannot be
the 4 ms interpolation cycle: at 4 ms a 50 % average settles within about 20 ms (0.1 mm of
travel at 6 mm/s), which would show neither the visible delay between Δy_r and Δy_m in
Figs. 16-17 ("due to the average calculation") nor the settling at weld start in Fig. 21.
We assume a controller-program loop of 0.25 s (default), which gives a delay of a few tenths
of a second and a settling of a few mm; pass ``update_period_s=None`` (CLI:
``--seed000-update-ms 0``) for the literal per-cycle reading.

The correction is switched on at the start of the ``weld`` phase (``active`` in the
:class:`~rfsw_plan.realtime.base.ControllerInputs`): it is a path correction, and seed 000
reports "a lateral tool deviation of about 7 mm when the pin enters into the material"
(Fig. 20), i.e. nothing is corrected during plunge and dwell. The settling transient of
Fig. 21 follows: the pin starts the weld at the uncompensated deviation and converges at the
rate the average allows.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from rfsw_plan.exceptions import InputError
from rfsw_plan.realtime.base import ControllerInputs, FloatArray, Strategy


def _lateral_target(dX: FloatArray, lateral: FloatArray) -> FloatArray:
    """Correction that cancels the lateral part of a deflection: -(dX . l) l, shape (K, 3)."""
    return -np.einsum("ki,ki->k", dX[:, :3], lateral)[:, None] * lateral


class ExponentialAverageCompensation(Strategy):
    """Lateral correction from the model deflection, smoothed by an exponential average.

    Shared machinery of :class:`ForceFeedbackFilteredCorrection` (the full model deflection)
    and the hybrid residual correction (:mod:`rfsw_plan.realtime.hybrid`). Subclasses choose
    the deflection to cancel in :meth:`target`.

    Args:
        average_percent: Weight of the previous correction [%], 0 <= a < 100 (seed 000: 50).
        update_period_s: Period of the model + average update [s]; None = every controller
            cycle. Between updates the last correction is held.
    """

    name = "exponential_average"
    description = "lateral model correction, exponential average"

    def __init__(self, average_percent: float = 50.0, update_period_s: float | None = None) -> None:
        if not 0.0 <= average_percent < 100.0:
            raise InputError(
                self.name, "average_percent", f"got {average_percent:g}", "0 <= percent < 100"
            )
        if update_period_s is not None and not update_period_s > 0:
            raise InputError(self.name, "update_period_s", f"got {update_period_s:g}", "> 0")
        self.average_percent = float(average_percent)
        self.update_period_s = update_period_s
        self._corr = np.zeros(3)
        self._n_active = 0
        self._every = 1

    def target(self, inputs: ControllerInputs) -> FloatArray:
        """Instantaneous correction to approach, base frame [m], shape (K, 3)."""
        return _lateral_target(inputs.model_deflection, inputs.lateral)

    def _period_cycles(self, inputs: ControllerInputs) -> int:
        if self.update_period_s is None:
            return 1
        return max(1, round(self.update_period_s / inputs.dt))

    def reset(self, inputs: ControllerInputs) -> None:
        self._corr = np.zeros(3)
        self._n_active = 0
        self._every = self._period_cycles(inputs)
        self._target = self.target(inputs)

    def step(self, k: int, inputs: ControllerInputs) -> FloatArray:
        if inputs.active[k]:
            if self._n_active % self._every == 0:
                a = self.average_percent / 100.0
                self._corr = a * self._corr + (1.0 - a) * self._target[k]
            self._n_active += 1
        return self._corr.copy()

    def run(self, inputs: ControllerInputs) -> FloatArray:
        """Vectorised :meth:`step` loop (same numbers): an IIR filter over the update cycles."""
        self.reset(inputs)
        K = len(inputs)
        out = np.zeros((K, 3))
        idx = np.flatnonzero(inputs.active)
        if idx.size == 0:
            return out
        upd = idx[:: self._every]
        a = self.average_percent / 100.0
        y = lfilter([1.0 - a], [1.0, -a], self._target[upd], axis=0)
        # Hold each update until the next one (inactive cycles freeze the correction too).
        last = np.searchsorted(upd, np.arange(K), side="right") - 1
        has = last >= 0
        out[has] = y[last[has]]
        return out


class ForceFeedbackFilteredCorrection(ExponentialAverageCompensation):
    """Force feedback through the model, filtered (seed 000 Fig. 14): measured force ->
    elastostatic model -> exponentially averaged lateral correction. Strategy name
    ``realtime_seed000`` (the paper it reproduces).

    corr_k = a corr_{k-1} + (1 - a) (-(dX_m,k . l_k) l_k) with dX_m,k = J C J^T F_m,k the
    model deflection under the measured wrench (seed 000 eq. 11) and a the averaging
    percentage (default 50 %), updated every ``update_period_s`` (default 0.25 s, see the
    module docstring for why it is not every 4 ms cycle).
    """

    name = "realtime_seed000"
    description = "seed 000: force sensor -> elastostatic model -> 50 % averaged lateral correction"

    def __init__(self, average_percent: float = 50.0, update_period_s: float | None = 0.25) -> None:
        super().__init__(average_percent, update_period_s)
