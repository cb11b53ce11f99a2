"""Compliance of one joint about the two axes normal to its rotation axis (seed 002 Fig. 5)."""

from __future__ import annotations

import numpy as np

from rfsw_plan.elastostatics.effects.base import Effect, FloatArray, PoseBatch


def _normal_axes(axis: FloatArray) -> FloatArray:
    """Two unit axes t1, t2 normal to a joint axis, in the joint frame, shape (2, 3).

    For the usual z axis they are the joint frame's x and y axes.
    """
    a = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = helper - a * (helper @ a)
    t1 /= np.linalg.norm(t1)
    return np.stack([t1, np.cross(a, t1)])


class TiltingCompliance(Effect):
    """Joint N tilts about its frame's t1 and t2 axes under the moment it carries.

    Each tilting direction is a rotational spring through the joint origin o_N about the base-
    frame axis u: its TCP twist is j_u = [u x (p - o_N); u], and dX = sum_u c_u j_u (j_u^T F).
    Parameters c_t1, c_t2 are tilting compliances [rad/(N m)]; seed 002 eq. 2.
    """

    name = "tilting_compliance"
    description = (
        "The joint's bearing is not rigid against bending: the moment normal to the joint axis "
        "tilts the joint about its two normal axes and swings the TCP."
    )
    kind = "compliance"
    per_joint = True

    def param_names(self) -> tuple[str, ...]:
        return ("c_t1", "c_t2")

    def prior(self) -> FloatArray:
        # Prior: bearings stiffer than the drive; 1/4 of the rotational compliance.
        assert self.joint is not None
        return np.full(2, 0.25 / float(self.robot.stiffness[self.joint]))

    def tilt_twists(self, batch: PoseBatch) -> FloatArray:
        """TCP twists of unit tilts about t1 and t2, base frame, shape (m, 6, 2)."""
        assert self.joint is not None
        i = self.joint
        local = _normal_axes(self.robot.geometry.axes[i])  # (2, 3) in joint frame
        R = batch.frames[:, i, :3, :3]
        u = np.einsum("mab,tb->mta", R, local)  # (m, 2, 3)
        r = batch.T[:, None, :3, 3] - batch.frames[:, i, None, :3, 3]
        out = np.empty((len(batch), 6, 2))
        out[:, :3, :] = np.cross(u, r).transpose(0, 2, 1)
        out[:, 3:, :] = u.transpose(0, 2, 1)
        return out

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        jt = self.tilt_twists(batch)
        moment = np.einsum("mat,ma->mt", jt, wrench)  # tilting moments [N m]
        return jt * moment[:, None, :]

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return np.einsum("mat,t->ma", self.deflection_regressor(batch, wrench, theta), theta)

    def cartesian_compliance(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        jt = self.tilt_twists(batch)
        return np.einsum("mat,t,mbt->mab", jt, theta, jt)
