"""Hysteresis of one joint under a load cycle: loading and unloading branches differ."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch
from rfsw_plan.elastostatics.effects.lost_motion import K_SIGMA, TAU_ROUND_NM
from rfsw_plan.elastostatics.effects.play import JointPlay

#: Samples needed on each branch (loading, unloading) to identify the hysteresis.
MIN_SAMPLES_PER_BRANCH = 3


class LoadHysteresis(JointPlay):
    """Joint N deflects less while its load rises than while it falls (friction in the gear:
    a Masing-type loop of width h around the elastic line):

        dq_N = -(h / 2) sign(d tau_N),   d tau_N = J_N^T dF,   dX = J_N dq_N

    (base frame [m, rad]), dF the last change of the logged wrench at the same pose
    (:attr:`PoseBatch.load_change`: from the time order of the samples) and J_N^T dF the
    change of the joint's torque it caused. On the loading branch (d tau > 0) friction holds
    the output back by h/2, on the unloading branch it holds it forward. A change within
    K_SIGMA sqrt(2) sigma_F l_N (the noise of the difference of two force readings through the
    lever arm) has no known sign and contributes nothing; so does a sample without load
    history (the first at a pose: there the joint's motion decides,
    :class:`~rfsw_plan.elastostatics.effects.lost_motion.LostMotion`).

    Seed 002 measured its joints "with a slowly increased, decreased and re-increased force" so
    as to "enable the modeling of hysteresis effects"; this is that effect, separate from lost
    motion because a load cycle of one sign never crosses the play. Linear in h.
    """

    name = "load_hysteresis"
    description = (
        "Friction in the joint's gear: under a load cycle the joint deflects less while the "
        "load rises than while it falls, so the TCP traces a loop."
    )
    param = "h"
    #: Hysteresis loop width [rad]: >= 0, at most 0.01 rad.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {"h": (0.0, 0.01)}
    param_units: ClassVar[Mapping[str, str]] = {"h": "rad"}

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """A loop 0.5-2 arcmin wide (seed 002's KR600 joints under forming loads)."""
        return {"h": float(np.radians(rng.uniform(0.5, 2.0) / 60.0))}

    def branch(self, batch: PoseBatch) -> FloatArray:
        """+1 on the loading branch, -1 on the unloading one, 0 unknown, shape (m,)."""
        assert self.joint is not None
        if batch.load_change is None:
            return np.zeros(len(batch))
        col = batch.J[:, :, self.joint]
        dtau = np.einsum("ma,ma->m", col, batch.load_change)
        lever = np.linalg.norm(col[:, :3], axis=1)
        noise = 0.0 if np.isinf(batch.force_noise) else batch.force_noise
        th = np.maximum(K_SIGMA * np.sqrt(2.0) * noise * lever, TAU_ROUND_NM)
        out: FloatArray = np.where(np.abs(dtau) > th, np.sign(dtau), 0.0)
        return out

    def side(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """-branch: the loading branch lags (-1), the unloading one leads (+1), shape (m,)."""
        out: FloatArray = -self.branch(batch)
        return out

    def identifiable(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        b = self.branch(batch)
        up, down = int(np.sum(b > 0)), int(np.sum(b < 0))
        if min(up, down) >= MIN_SAMPLES_PER_BRANCH:
            return None
        assert self.joint is not None
        return (f"joint {self.joint + 1}'s load rises in {up} and falls in {down} samples at "
                f"a pose (a load cycle needs at least {MIN_SAMPLES_PER_BRANCH} of each)")

    def what_to_add(self, batch: PoseBatch, wrench: FloatArray, plus: int, minus: int) -> str:
        # side +1 = unloading (falling) branch, -1 = loading (rising) branch
        return (f"add load cycles at some poses: raise the load in steps, then lower it, "
                f"reading the TCP at every step, with loads that turn {self._joint_name()} "
                f"(the data has {minus} rising and {plus} falling samples; at least 3 of each)")
