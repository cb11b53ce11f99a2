"""Lost motion (backlash) of one joint: the side of the play from the torque, or from the
direction the joint last moved in when the torque is too small to know its sign."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.effects.base import ComplianceEffect, FloatArray, PoseBatch

#: The torque's sign is known where |tau| exceeds this many standard deviations of its noise.
K_SIGMA = 3.0
#: Torques below this [N m] are rounding (a vertical axis under gravity), never a sign.
TAU_ROUND_NM = 1e-6
#: Samples needed on each side of the play to identify it.
MIN_SAMPLES_PER_SIDE = 3


def load_torque(batch: PoseBatch, wrench: FloatArray, joint: int) -> FloatArray:
    """Load torque on a joint, tau = (J^T F + tau_g)[joint] [N m], shape (m,): the true wrench
    at the TCP (base frame) through the joint's twist, plus the links' own weight when the
    robot description gives link masses (cached in the batch)."""
    F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6))
    tau = np.einsum("ma,ma->m", batch.J[:, :, joint], F)
    if batch.robot.has_link_masses:
        if "link_gravity" not in batch.cache:
            batch.cache["link_gravity"] = batch.robot.gravity_torque(batch.q)
        tau = tau + batch.cache["link_gravity"][:, joint]
    out: FloatArray = tau
    return out


class LostMotion(ComplianceEffect):
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
    description = (
        "Play in the joint's gears: the output sits on the flank the load presses it to, or, "
        "under too little load, the flank its last motion left it on, so the TCP is off by "
        "half the play one way or the other."
    )
    per_joint = True

    #: Lost motion [rad] (or [m] for a prismatic joint): >= 0, at most 0.1 (5.7 deg).
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {"b": (0.0, 0.1)}
    param_units: ClassVar[Mapping[str, str]] = {"b": "rad"}

    def param_names(self) -> tuple[str, ...]:
        return ("b",)

    def prior(self) -> FloatArray:
        return np.zeros(1)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Lost motion of 1-4 arcmin (a worn or loosely preloaded heavy-duty gear)."""
        return {"b": float(np.radians(rng.uniform(1.0, 4.0) / 60.0))}

    def joint_torque(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """tau_N = (J^T F + tau_g)_N [N m], shape (m,) (tau_g: the links' weight, if any)."""
        assert self.joint is not None
        return load_torque(batch, wrench, self.joint)

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

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        assert self.joint is not None
        s, _ = self.sides(batch, wrench)
        return (batch.J[:, :, self.joint] * (0.5 * s)[:, None])[:, :, None]

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.deflection_regressor(batch, wrench, theta)[:, :, 0] * float(theta[0])

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
