"""Joint stiffness that changes with the joint's torque (seed 002 Fig. 7)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import ComplianceEffect, FloatArray, PoseBatch

#: Reference torque that normalises the polynomial [N m]: s = tau / TAU_REF_NM.
TAU_REF_NM = 1.0e4


class TorqueDependentStiffness(ComplianceEffect):
    """Deflection of joint N beyond linear, as an odd polynomial in its torque.

    Seed 002 Fig. 7 fits each joint's angular displacement phi(tau) with a polynomial; the
    linear term is the joint compliance, so this effect adds the higher odd terms:

        dq_N = d2 s|s| + d3 s^3,   s = tau_N / TAU_REF_NM,   tau_N = (J^T F)_N,

    and moves the TCP by dX = J_N dq_N (base frame [m, rad]). d2 and d3 [rad] are the extra
    deflection at tau_N = TAU_REF_NM (10 kN m); d < 0 is a joint that stiffens with load,
    d > 0 one that softens. Linear in (d2, d3).
    """

    name = "torque_dependent_stiffness"
    description = (
        "The joint's stiffness changes with the torque it carries (gears and bearings stiffen "
        "as they load), so its deflection is a polynomial in its torque, not a straight line."
    )
    per_joint = True

    #: Extra deflection at 10 kN m [rad]; wrist joints never carry 10 kN m, so their fitted
    #: d is an extrapolation and can be large (1 rad) while the real deflection is small.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {"d": (-1e3, 1e3)}
    param_units: ClassVar[Mapping[str, str]] = {"d": "rad"}

    def param_names(self) -> tuple[str, ...]:
        return ("d2", "d3")

    def prior(self) -> FloatArray:
        return np.zeros(2)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Sized on the campaign's own torques: at the 90th percentile s90 of |s|, each term
        adds 10-30 % of the joint's linear deflection s90 TAU_REF_NM / k, with a random sign
        (stiffening or softening), so the non-linearity is of the size seed 002 Fig. 7 shows
        wherever the data has torque."""
        s = self.normalised_torque(batch, wrench)
        s90 = max(float(np.percentile(np.abs(s), 90)), 1e-6)
        assert self.joint is not None
        linear = s90 * TAU_REF_NM / float(self.robot.stiffness[self.joint])  # [rad]
        sign = rng.choice([-1.0, 1.0], size=2)
        lo, hi = self.param_ranges["d"]
        d = np.clip([sign[0] * rng.uniform(0.1, 0.3) * linear / s90**2,
                     sign[1] * rng.uniform(0.1, 0.3) * linear / s90**3], lo, hi)
        return dict(zip(self.param_names(), d.tolist(), strict=True))

    def normalised_torque(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """s = tau_N / TAU_REF_NM for every sample, shape (m,)."""
        assert self.joint is not None
        F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6))
        return np.einsum("ma,ma->m", batch.J[:, :, self.joint], F) / TAU_REF_NM

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        assert self.joint is not None
        s = self.normalised_torque(batch, wrench)
        basis = np.stack([s * np.abs(s), s**3], axis=1)  # (m, 2)
        return batch.J[:, :, self.joint, None] * basis[:, None, :]

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        """The regressor's two columns times (d2, d3), summed column by column: the numbers
        of ``einsum("map,p->ma", regressor, theta)`` bit for bit (the products J_N s|s| and
        J_N s^3, each times its d, added, then added to 0 as einsum's output is, so that a
        -0 sum is +0), without the (m, 6, 2) regressor and einsum's per-element loop over
        two terms (issue 41; ``tests/test_effects.py`` compares both)."""
        assert self.joint is not None
        s = self.normalised_torque(batch, wrench)
        Jn = batch.J[:, :, self.joint]
        out = (Jn * (s * np.abs(s))[:, None]) * theta[0]
        out += (Jn * (s**3)[:, None]) * theta[1]
        out += 0.0
        return np.asarray(out)
