"""Lost motion of one joint that follows the sign of its torque."""

from __future__ import annotations

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch
from rfsw_plan.elastostatics.effects.play import JointPlay

#: Torque over which the lost motion is taken up [N m] (smooths the sign function).
TAU_EPS_NM = 20.0
#: Samples needed on each side of zero torque (|tau| > 3 TAU_EPS_NM) to identify backlash.
MIN_SAMPLES_PER_SIGN = 3


class JointBacklash(JointPlay):
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

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Lost motion of 0.5-2 arcmin (a worn or loosely preloaded heavy-duty gear)."""
        return {"b": float(np.radians(rng.uniform(0.5, 2.0) / 60.0))}

    def side(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """tanh(tau_N / TAU_EPS_NM): the torque's smooth sign, shape (m,)."""
        out: FloatArray = np.tanh(self.joint_torque(batch, wrench) / TAU_EPS_NM)
        return out

    def _signs(self, batch: PoseBatch, wrench: FloatArray) -> tuple[int, int, FloatArray]:
        tau = self.joint_torque(batch, wrench)
        return (int(np.sum(tau > 3 * TAU_EPS_NM)), int(np.sum(tau < -3 * TAU_EPS_NM)), tau)

    def sides_seen(self, batch: PoseBatch, wrench: FloatArray) -> tuple[int, int]:
        """Samples with the torque above +3 TAU_EPS_NM and below -3 TAU_EPS_NM."""
        pos, neg, _ = self._signs(batch, wrench)
        return pos, neg

    def identifiable(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        pos, neg, tau = self._signs(batch, wrench)
        if min(pos, neg) >= MIN_SAMPLES_PER_SIGN:
            return None
        lo, hi = (float(tau.min()), float(tau.max())) if tau.size else (0.0, 0.0)
        return (
            f"{self._joint_name()}'s torque does not change sign in the data ({pos} samples "
            f"above +{3 * TAU_EPS_NM:g} N m, {neg} below -{3 * TAU_EPS_NM:g} N m, range "
            f"{lo:.4g}..{hi:.4g} N m); backlash needs at least {MIN_SAMPLES_PER_SIGN} of each"
        )

    def what_to_add(self, batch: PoseBatch, wrench: FloatArray, plus: int, minus: int) -> str:
        sign = "negative" if minus < plus else "positive"
        return (f"add at least {MIN_SAMPLES_PER_SIGN} samples whose load turns "
                f"{self._joint_name()} with a {sign} torque beyond {3 * TAU_EPS_NM:g} N m "
                f"(the data has {plus} +, {minus} -): reverse the load at some poses, or use "
                f"poses where the same load has the other lever on that joint")
