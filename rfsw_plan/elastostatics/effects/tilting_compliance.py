"""Compliance of one joint about the two axes normal to its rotation axis (seed 002 Fig. 5)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import ComplianceEffect, FloatArray, PoseBatch


def _normal_axes(axis: FloatArray) -> FloatArray:
    """Two unit axes t1, t2 normal to a joint axis, in the joint frame, shape (2, 3).

    For the usual z axis they are the joint frame's x and y axes.
    """
    a = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = helper - a * (helper @ a)
    t1 /= np.linalg.norm(t1)
    return np.stack([t1, np.cross(a, t1)])


class TiltingCompliance(ComplianceEffect):
    """Joint N tilts about its frame's t1 and t2 axes under the moment it carries.

    Each tilting direction is a rotational spring through the joint origin o_N about the base-
    frame axis u: its TCP twist is j_u = [u x (p - o_N); u], and dX = sum_u c_u j_u (j_u^T F).
    Parameters c_t1, c_t2 are tilting compliances [rad/(N m)]; seed 002 eq. 2.
    """

    name = "tilting_compliance"
    uses_frames = True
    description = (
        "The joint's bearing is not rigid against bending: the moment normal to the joint axis "
        "tilts the joint about its two normal axes and swings the TCP."
    )
    per_joint = True

    #: Tilting compliance [rad/(N m)]: >= 0 (0 = rigid bearing); 1e-3 is 1 rad per kN m.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {"c_t": (0.0, 1e-3)}
    param_units: ClassVar[Mapping[str, str]] = {"c_t": "rad/(N m)"}

    def param_names(self) -> tuple[str, ...]:
        return ("c_t1", "c_t2")

    def prior(self) -> FloatArray:
        # Prior: bearings stiffer than the drive; 1/4 of the rotational compliance.
        assert self.joint is not None
        return np.full(2, 0.25 / float(self.robot.stiffness[self.joint]))

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Each tilting compliance 0.5-2 times the prior (1/4 of the joint's compliance)."""
        lo, hi = self.param_ranges["c_t"]
        c = np.clip(self.prior() * rng.uniform(0.5, 2.0, 2), lo, hi)
        return dict(zip(self.param_names(), c.tolist(), strict=True))

    def tilt_twists(self, batch: PoseBatch) -> FloatArray:
        """TCP twists of unit tilts about t1 and t2, base frame, shape (m, 6, 2)."""
        assert self.joint is not None
        i = self.joint
        local = self._local_axes()  # (2, 3) in joint frame
        R = batch.frames[:, i, :3, :3]
        u = np.matmul(R, local.T)  # (m, 3, 2) base frame
        r = batch.T[:, :3, 3] - batch.frames[:, i, :3, 3]  # (m, 3) [m]
        out = np.empty((len(batch), 6, 2))
        # u x r, written out (np.cross costs ~20 us of overhead per call on small arrays).
        out[:, 0, :] = u[:, 1] * r[:, 2, None] - u[:, 2] * r[:, 1, None]
        out[:, 1, :] = u[:, 2] * r[:, 0, None] - u[:, 0] * r[:, 2, None]
        out[:, 2, :] = u[:, 0] * r[:, 1, None] - u[:, 1] * r[:, 0, None]
        out[:, 3:, :] = u
        return out

    def joint_springs(self) -> FloatArray:
        """The two tilting axes t1, t2 in the joint frame, shape (2, 3)."""
        return self._local_axes()

    def _local_axes(self) -> FloatArray:
        """t1, t2 in the joint frame, shape (2, 3) (constant; computed once)."""
        cached: FloatArray | None = getattr(self, "_local_cache", None)
        if cached is None:
            assert self.joint is not None
            cached = _normal_axes(self.robot.geometry.axes[self.joint])
            self._local_cache = cached
        return cached

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        jt = self.tilt_twists(batch)
        moment = np.matmul(wrench[:, None, :], jt)  # tilting moments [N m], (m, 1, 2)
        return jt * moment

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.deflection_regressor(batch, wrench, theta) @ theta

    def cartesian_compliance(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        jt = self.tilt_twists(batch)
        return np.matmul(jt * theta, jt.transpose(0, 2, 1))
