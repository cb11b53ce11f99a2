"""What the three forms of backlash share: a joint offset of half a width, one way or the other.

Gear play shows in three ways, each an effect of this folder:

* :class:`~rfsw_plan.elastostatics.effects.joint_backlash.JointBacklash`: the side follows the
  sign of the joint's load torque (loaded data without history);
* :class:`~rfsw_plan.elastostatics.effects.lost_motion.LostMotion`: the side follows the load
  torque where it is clear, else the direction the joint last moved in (the approach);
* :class:`~rfsw_plan.elastostatics.effects.load_hysteresis.LoadHysteresis`: under a load cycle
  at one pose, the loading and unloading branches differ.

Each is dq_N = w s / 2 with w >= 0 the width [rad] (or [m] for a prismatic joint) and
s in [-1, 1] the side of each sample; dX = J_N dq_N (base frame). :class:`JointPlay` holds the
parameter, the regressor and the identifiability check on the sides; a subclass gives
:meth:`JointPlay.side` and what a campaign needs to show the sides
(:meth:`JointPlay.campaign_advice`).
"""

from __future__ import annotations

import abc
from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import ComplianceEffect, FloatArray, PoseBatch

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


class JointPlay(ComplianceEffect):
    """dq_N = (w / 2) s with s = :meth:`side` in [-1, 1] per sample (module docstring).

    Linear in the one parameter; a subclass sets :attr:`param` (its name), ``param_ranges``,
    ``param_units``, ``plausible_params`` and :meth:`side`.
    """

    per_joint = True
    offset_like = True
    #: The width's name.
    param: ClassVar[str] = "b"
    #: Width [rad] (or [m] for a prismatic joint): >= 0, at most 0.1 (5.7 deg).
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {"b": (0.0, 0.1)}
    param_units: ClassVar[Mapping[str, str]] = {"b": "rad"}

    def param_names(self) -> tuple[str, ...]:
        return (self.param,)

    def prior(self) -> FloatArray:
        return np.zeros(1)

    def joint_torque(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """tau_N = (J^T F + tau_g)_N [N m], shape (m,) (tau_g: the links' weight, if any)."""
        assert self.joint is not None
        return load_torque(batch, wrench, self.joint)

    @abc.abstractmethod
    def side(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """The side of the play of every sample, s in [-1, 1] (0: unknown), shape (m,)."""

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        assert self.joint is not None
        s = 0.5 * self.side(batch, wrench)
        return (batch.J[:, :, self.joint] * s[:, None])[:, :, None]

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.deflection_regressor(batch, wrench, theta)[:, :, 0] * float(theta[0])

    def sides_seen(self, batch: PoseBatch, wrench: FloatArray) -> tuple[int, int]:
        """Samples clearly on the + side (s > 1/2) and on the - side (s < -1/2)."""
        s = self.side(batch, wrench)
        return int(np.sum(s > 0.5)), int(np.sum(s < -0.5))

    def campaign_advice(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        """What to add to the campaign so that it shows both sides, or None if it does."""
        plus, minus = self.sides_seen(batch, wrench)
        if min(plus, minus) >= MIN_SAMPLES_PER_SIDE or not self.visible(batch):
            return None
        return self.what_to_add(batch, wrench, plus, minus)

    def state_spread(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        """J_v,N max(w, 0) / 2 [m], shape (m, 3): a sample whose side is unknown
        (:meth:`~rfsw_plan.elastostatics.effects.base.Effect.unknown_state`) sits anywhere
        between the two flanks, s in [-1, 1]."""
        assert self.joint is not None
        out: FloatArray = batch.J[:, :3, self.joint] * (0.5 * max(float(theta[0]), 0.0))
        return out

    def visible(self, batch: PoseBatch) -> bool:
        """The joint moves the TCP in some sample (its lever arm |J_v,N| is above 1 um/rad):
        else no campaign of these poses shows its play."""
        assert self.joint is not None
        return bool(np.any(np.linalg.norm(batch.J[:, :3, self.joint], axis=1) > 1e-6))

    @abc.abstractmethod
    def what_to_add(self, batch: PoseBatch, wrench: FloatArray, plus: int, minus: int) -> str:
        """The poses, approach directions or load signs that would show the missing side."""

    def _joint_name(self) -> str:
        assert self.joint is not None
        return f"joint {self.joint + 1}"


__all__ = ["MIN_SAMPLES_PER_SIDE", "JointPlay", "load_torque"]
