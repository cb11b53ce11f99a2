"""Lost motion of one joint that follows the sign of its torque."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import ComplianceEffect, FloatArray, PoseBatch
from rfsw_plan.elastostatics.effects.lost_motion import load_torque

#: Torque over which the lost motion is taken up [N m] (smooths the sign function).
TAU_EPS_NM = 20.0
#: Samples needed on each side of zero torque (|tau| > 3 TAU_EPS_NM) to identify backlash.
MIN_SAMPLES_PER_SIGN = 3


class JointBacklash(ComplianceEffect):
    """Joint N sits at +b/2 or -b/2 inside its gear play depending on the sign of its torque.

        dq_N = (b / 2) tanh(tau_N / TAU_EPS_NM),   tau_N = (J^T F + tau_g)_N,   dX = J_N dq_N

    (base frame [m, rad]); b [rad] is the total lost motion, tau_g the links' own weight when
    the robot description gives link masses (zero otherwise). The tanh is a smooth sign so the
    model stays differentiable; it is linear in b. Near zero torque (|tau| within TAU_EPS_NM,
    the order of a force sensor's noise times the lever arm) the side of the play is undefined
    and the model predicts less than the full offset, zero at zero torque. With the torque
    always of one sign the effect is a constant joint offset, so :meth:`identifiable` asks for
    both signs. On data with a history (approach directions),
    :class:`~rfsw_plan.elastostatics.effects.lost_motion.LostMotion` supersedes it: it also
    places the samples whose torque is too small to know its sign.
    """

    name = "joint_backlash"
    description = (
        "Play in the joint's gears: when its torque changes sign the joint crosses its "
        "backlash and the TCP jumps by the lost motion."
    )
    per_joint = True

    #: Lost motion [rad]: >= 0, at most 0.1 rad (5.7 deg).
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {"b": (0.0, 0.1)}
    param_units: ClassVar[Mapping[str, str]] = {"b": "rad"}

    def param_names(self) -> tuple[str, ...]:
        return ("b",)

    def prior(self) -> FloatArray:
        return np.zeros(1)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Lost motion of 0.5-2 arcmin (a worn or loosely preloaded heavy-duty gear)."""
        return {"b": float(np.radians(rng.uniform(0.5, 2.0) / 60.0))}

    def joint_torque(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """tau_N = (J^T F + tau_g)_N [N m], shape (m,) (tau_g: the links' weight, if any)."""
        assert self.joint is not None
        return load_torque(batch, wrench, self.joint)

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        assert self.joint is not None
        side = 0.5 * np.tanh(self.joint_torque(batch, wrench) / TAU_EPS_NM)
        return (batch.J[:, :, self.joint] * side[:, None])[:, :, None]

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.deflection_regressor(batch, wrench, theta)[:, :, 0] * float(theta[0])

    def identifiable(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        tau = self.joint_torque(batch, wrench)
        pos = int(np.sum(tau > 3 * TAU_EPS_NM))
        neg = int(np.sum(tau < -3 * TAU_EPS_NM))
        if min(pos, neg) >= MIN_SAMPLES_PER_SIGN:
            return None
        lo, hi = (float(tau.min()), float(tau.max())) if tau.size else (0.0, 0.0)
        assert self.joint is not None
        return (
            f"joint {self.joint + 1}'s torque does not change sign in the data ({pos} samples "
            f"above +{3 * TAU_EPS_NM:g} N m, {neg} below -{3 * TAU_EPS_NM:g} N m, range "
            f"{lo:.4g}..{hi:.4g} N m); backlash needs at least {MIN_SAMPLES_PER_SIGN} of each"
        )
