"""Lost motion (backlash) of one joint: the side of the play from the torque, or from the
direction the joint last moved in when the torque is too small to know its sign."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch
from rfsw_plan.elastostatics.effects.play import MIN_SAMPLES_PER_SIDE, JointPlay

#: The torque's sign is known where |tau| exceeds this many standard deviations of its noise.
K_SIGMA = 3.0
#: Torques below this [N m] are rounding (a vertical axis under gravity), never a sign.
TAU_ROUND_NM = 1e-6
class LostMotion(JointPlay):
    """Joint N sits on one flank of its gear play, +b/2 or -b/2 from where its encoder says.

        dq_N = (b / 2) s,   dX = J_N dq_N   (base frame [m, rad]),

        s = sign(tau_N)   where |tau_N| > tau_th = K_SIGMA sigma_F l_N,
        s = -a_N          elsewhere,

    with tau_N = (J^T F + tau_g)_N the load torque on the joint [N m] (tau_g the links' own
    weight when the robot description gives link masses), l_N = |J_v,N| the lever arm from
    joint N to the TCP [m] (a force error dF moves tau_N by at most l_N |dF|), sigma_F the
    logged force's noise per axis [N] (:attr:`PoseBatch.force_noise`: given, or from the
    zero-load readings) and a_N the joint's approach direction (+1 when it last moved up;
    :mod:`rfsw_plan.elastostatics.approach`). A clear load presses the output against the
    flank it pushes towards; without one, the motor's last motion left the output lagging
    behind by half the play (a motor-side encoder reads q + b/2 when moving up). Without
    force readings (sigma_F = inf: a motion-capture session) the side is the approach
    direction's everywhere; a planned path (no history, sigma_F = 0) takes the torque's sign.

    Linear in b. :meth:`identifiable` counts the samples on each side of each mechanism; with
    none in the approach regime it is joint_backlash's torque model and says so.
    Supersedes :class:`~rfsw_plan.elastostatics.effects.joint_backlash.JointBacklash` on
    data with history (approach directions); that one remains for torque-only loaded data.
    """

    name = "lost_motion"
    uses_approach = True
    description = (
        "Play in the joint's gears: the output sits on the flank the load presses it to, or, "
        "under too little load, the flank its last motion left it on, so the TCP is off by "
        "half the play one way or the other."
    )
    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Lost motion of 1-4 arcmin (a worn or loosely preloaded heavy-duty gear)."""
        return {"b": float(np.radians(rng.uniform(1.0, 4.0) / 60.0))}

    def threshold(self, batch: PoseBatch) -> FloatArray:
        """tau_th = K_SIGMA sigma_F l_N [N m], shape (m,) (inf without force readings)."""
        assert self.joint is not None
        lever = np.linalg.norm(batch.J[:, :3, self.joint], axis=1)
        if np.isinf(batch.force_noise):
            return np.full(len(batch), np.inf)
        return np.maximum(K_SIGMA * batch.force_noise * lever, TAU_ROUND_NM)

    def sides(
        self, batch: PoseBatch, wrench: FloatArray
    ) -> tuple[FloatArray, NDArray[np.bool_]]:
        """(side s in {-1, 0, +1}, True where the torque decides), each shape (m,)."""
        assert self.joint is not None
        tau = self.joint_torque(batch, wrench)
        loaded: NDArray[np.bool_] = np.abs(tau) > self.threshold(batch)
        a = (np.zeros(len(batch)) if batch.approach is None
             else batch.approach[:, self.joint])
        return np.where(loaded, np.sign(tau), -a), loaded

    def side(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """s = sign(tau_N) where the torque is clear, else -a_N (class docstring)."""
        return self.sides(batch, wrench)[0]

    def side_counts(self, batch: PoseBatch, wrench: FloatArray) -> dict[str, int]:
        """Samples on each side of each mechanism: ``torque+``, ``torque-``, ``approach+``,
        ``approach-`` (the side, not the direction: approach+ = the joint last moved down)
        and ``unknown`` (no torque sign and no approach direction)."""
        s, loaded = self.sides(batch, wrench)
        return {"torque+": int(np.sum(loaded & (s > 0))), "torque-": int(np.sum(loaded & (s < 0))),
                "approach+": int(np.sum(~loaded & (s > 0))),
                "approach-": int(np.sum(~loaded & (s < 0))),
                "unknown": int(np.sum(s == 0))}

    def identifiable(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        n = self.side_counts(batch, wrench)
        plus, minus = n["torque+"] + n["approach+"], n["torque-"] + n["approach-"]
        assert self.joint is not None
        if min(plus, minus) >= MIN_SAMPLES_PER_SIDE and n["approach+"] + n["approach-"] > 0:
            return None
        if min(plus, minus) >= MIN_SAMPLES_PER_SIDE:
            return (f"the torque sets joint {self.joint + 1}'s side of the play in every sample "
                    f"(none below the threshold, where the approach direction would): this is "
                    f"joint_backlash:j{self.joint + 1}'s torque-only model")
        th = self.threshold(batch)
        where = ("no force readings: the side is the approach direction's" if np.isinf(th).all()
                 else f"torque threshold {np.median(th):.3g} N m median")
        return (
            f"joint {self.joint + 1} sits on one side of its play in almost every sample "
            f"({n['torque+']} / {n['torque-']} by the torque's sign +/-, {n['approach+']} / "
            f"{n['approach-']} by the approach direction, {n['unknown']} unknown; {where}); "
            f"lost motion needs at least {MIN_SAMPLES_PER_SIDE} samples on each side"
        )

    def campaign_advice(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        """Both sides, and some of them set by the approach direction (else this is
        joint_backlash's model): what to add if not."""
        n = self.side_counts(batch, wrench)
        plus, minus = n["torque+"] + n["approach+"], n["torque-"] + n["approach-"]
        if ((min(plus, minus) >= MIN_SAMPLES_PER_SIDE and n["approach+"] + n["approach-"] > 0)
                or not self.visible(batch)):
            return None
        return self.what_to_add(batch, wrench, plus, minus)

    def what_to_add(self, batch: PoseBatch, wrench: FloatArray, plus: int, minus: int) -> str:
        n = self.side_counts(batch, wrench)
        j = self._joint_name()
        if n["approach+"] + n["approach-"] == 0:
            how = (f"unloaded samples (or loads below the torque threshold on {j}) reached "
                   f"with {j} moving up at some poses and down at others")
        else:
            side = "down (its last motion negative)" if plus < minus else "up"
            how = f"samples reached with {j} moving {side}, unloaded"
        return (f"add at least {MIN_SAMPLES_PER_SIDE} {how}, or loads that reverse {j}'s "
                f"torque (the data has {plus} samples on the + side, {minus} on the -)")
