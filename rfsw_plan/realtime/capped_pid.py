"""Filtered PID with capped increments (seed 002 §4.2, Fig. 9): MAF + self-incrementing PID.

The control law: the model displacement at the measured joints and force is the error, a
moving-average filter smooths it, and a PID whose output is the capped increment of the offset
drives it to zero (:class:`FilteredCappedPID`, strategy ``realtime_seed002`` in
``rfsw-plan compare``).

Seed 002 runs the algorithm every 0.5 ms on an external PC; the KUKA controller exchanges data
over RSI every 4 ms (its interpolation cycle). Per algorithm step:

1. X_delta = X - X_m, the Cartesian displacement of the flexible model at the measured axis
   values and force (eq. 3). Here: the model deflection under the measured wrench at the
   reported joints, held between two 4 ms telegrams.
2. X_e = X_a - X_delta, the position error (eq. 4). The paper counts the actuated offset X_a
   positive when it opposes the displacement; with X_a as the offset *added* to the commanded
   pose (our convention, base frame), the same error is ``X_e = -X_a - X_delta``, which is
   zero when the offset cancels the displacement.
3. X_e,f = moving average of X_e over 320 algorithm steps (160 ms, 40 robot cycles).
4. PID per Cartesian direction (eq. 5, forward-Euler integrator and filtered derivative):
   u = K_P (X_e,f + K_I T_s sum(X_e,f) + K_D N (X_e,f - x_d)), x_d += T_s N (X_e,f - x_d).
5. Self-incrementing output: u is the change of the offset in one step, capped at
   ``max_rate * T_s``; X_a <- X_a + clip(u). X_a is sent to the robot at the next telegram.

Gains: seed 002's Table 1 values are not in the extracted text. The self-incrementing output
already integrates, so the loop is an integrator behind a 160 ms moving average (about 80 ms of
delay). We chose K_P = 2.5e-3 per 0.5 ms step (an integrator gain of 5 1/s, a 0.2 s time
constant, crossover well below the MAF's phase limit of about 13 rad/s), K_I = 0 (a second
integrator would only add overshoot) and a small derivative K_D = 0.02 s, N = 50 1/s, which
adds phase lead. Rate cap 10 mm/s. Tuned on the zk500 seam for a step response without
overshoot; each direction is treated alike, as in the paper.
"""

from __future__ import annotations

import numpy as np

from rfsw_plan.exceptions import InputError
from rfsw_plan.realtime.base import ControllerInputs, FloatArray, Strategy


class FilteredCappedPID(Strategy):
    """Filtered PID with capped increments (seed 002 Fig. 9): model displacement -> MAF ->
    PID -> self-incrementing capped offset. Strategy name ``realtime_seed002``.

    Args:
        algorithm_step_s: Step of the external control algorithm T_s [s] (seed 002: 0.5 ms).
        maf_samples: Moving-average length in algorithm steps (seed 002: 320).
        kp: Proportional gain K_P, offset change per step per metre of error [-].
        ki: Integral gain K_I [1/s].
        kd: Derivative gain K_D [s].
        derivative_filter: Derivative filter coefficient N [1/s].
        max_rate: Cap on the offset change per unit time [m/s] (per direction).
    """

    name = "realtime_seed002"
    description = "seed 002: model displacement -> 320-sample MAF -> self-incrementing capped PID"

    def __init__(
        self,
        algorithm_step_s: float = 0.5e-3,
        maf_samples: int = 320,
        kp: float = 2.5e-3,
        ki: float = 0.0,
        kd: float = 0.02,
        derivative_filter: float = 50.0,
        max_rate: float = 10e-3,
    ) -> None:
        if not algorithm_step_s > 0:
            raise InputError(self.name, "algorithm_step_s", f"got {algorithm_step_s:g}", "> 0")
        if maf_samples < 1:
            raise InputError(self.name, "maf_samples", f"got {maf_samples}", ">= 1")
        if not max_rate > 0:
            raise InputError(self.name, "max_rate", f"got {max_rate:g}", "> 0 m/s")
        if derivative_filter <= 0:
            raise InputError(self.name, "derivative_filter", f"got {derivative_filter:g}", "> 0")
        self.algorithm_step_s = float(algorithm_step_s)
        self.maf_samples = int(maf_samples)
        self.kp, self.ki, self.kd = float(kp), float(ki), float(kd)
        self.derivative_filter = float(derivative_filter)
        self.max_rate = float(max_rate)

    @property
    def filter_window_s(self) -> float:
        """Length of the moving-average filter [s] (seed 002: 160 ms)."""
        return self.maf_samples * self.algorithm_step_s

    def reset(self, inputs: ControllerInputs) -> None:
        dur = inputs.weld_duration
        if self.filter_window_s > dur:
            raise InputError(
                self.name, "maf_samples",
                f"filter window {self.filter_window_s * 1e3:g} ms "
                f"({self.maf_samples} x {self.algorithm_step_s * 1e3:g} ms) is longer than the "
                f"weld ({dur * 1e3:g} ms)",
                "a window shorter than the weld",
            )
        self._sub = max(1, round(inputs.dt / self.algorithm_step_s))
        L = self.maf_samples
        self._buf = [[0.0] * L for _ in range(3)]
        self._pos = 0
        self._sum = [0.0, 0.0, 0.0]
        self._xa = [0.0, 0.0, 0.0]
        self._int = [0.0, 0.0, 0.0]
        self._xd = [0.0, 0.0, 0.0]

    def step(self, k: int, inputs: ControllerInputs) -> FloatArray:
        if not inputs.active[k]:
            return np.array(self._xa)
        d = inputs.model_deflection[k]
        xdelta = (float(d[0]), float(d[1]), float(d[2]))
        Ts = self.algorithm_step_s
        L = self.maf_samples
        kp, ki, kd, N = self.kp, self.ki, self.kd, self.derivative_filter
        cap = self.max_rate * Ts
        buf, s, xa, integ, xd = self._buf, self._sum, self._xa, self._int, self._xd
        pos = self._pos
        for _ in range(self._sub):
            for i in range(3):
                e = -xa[i] - xdelta[i]  # eq. 4 in our sign convention
                b = buf[i]
                s[i] += e - b[pos]
                b[pos] = e
                ef = s[i] / L  # MAF, zero initial condition (Simulink default)
                deriv = N * (ef - xd[i])
                xd[i] += Ts * deriv
                u = kp * (ef + ki * integ[i] + kd * deriv)  # eq. 5
                integ[i] += Ts * ef
                if u > cap:
                    u = cap
                elif u < -cap:
                    u = -cap
                xa[i] += u  # self-incrementing output
            pos += 1
            if pos == L:
                pos = 0
        self._pos = pos
        return np.array(xa)
