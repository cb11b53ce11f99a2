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


#: Key of the links' gravity moments in a batch's cache (they depend on the poses only).
_GRAVITY_KEY = "link_gravity_moments"


def link_gravity_moments(batch: PoseBatch) -> FloatArray:
    """Moment of the weight of the links beyond each chain joint about the joint's origin, in
    the joint's frame [N m], shape (m, n, 3); zeros when the robot file has no link masses.

        M_i = sum_{k >= i} (c_k - o_i) x m_k g = (S_i - o_i M_i) x g,

    S_i = sum_{k >= i} m_k c_k [kg m] and M_i = sum_{k >= i} m_k [kg], c_k the centre of mass of
    link k (base frame, from the batch's joint frames and the model's inertias), o_i the
    joint's origin, g = 9.81 m/s^2 along -Z of the base (Pinocchio's gravity, as
    :meth:`Robot.gravity_torque`). Written in joint i's frame, it is what the joint carries:
    the component along its axis loads the gear (``gravity_torque``), the normal ones the
    bearing. Vectorised over the samples; kept in ``batch.cache``.
    """
    got: FloatArray | None = batch.cache.get(_GRAVITY_KEY)
    if got is not None:
        return got
    robot = batch.robot
    m, n = len(batch), robot.nq
    out = np.zeros((m, n, 3))
    if robot.has_link_masses:
        R = batch.frames[:, :, :3, :3]  # (m, n, 3, 3)
        origin = batch.frames[:, :, :3, 3]  # (m, n, 3): o_i
        # A prismatic joint's body sits further along its axis by its travel (chain value).
        axes = np.asarray(robot.geometry.axes, dtype=float)  # (n, 3) in the joint frames
        travel = robot.chain_q(batch.q) * np.asarray(robot.prismatic, dtype=float)  # (m, n)
        lever = np.array([robot.model.inertias[i + 1].lever for i in range(n)])  # (n, 3)
        mass = np.array([float(robot.model.inertias[i + 1].mass) for i in range(n)])  # (n,)
        local = lever[None] + travel[:, :, None] * axes[None]  # c_k in frame k, (m, n, 3)
        com = origin + np.einsum("mnab,mnb->mna", R, local)  # (m, n, 3) base frame
        weighted = mass[None, :, None] * com  # m_k c_k, (m, n, 3)
        first = np.flip(np.cumsum(np.flip(weighted, axis=1), axis=1), axis=1)  # S_i
        total = np.flip(np.cumsum(np.flip(mass)))  # M_i, (n,)
        g = np.array([0.0, 0.0, -float(np.linalg.norm(robot.model.gravity.linear))])
        base = np.cross(first - origin * total[None, :, None], g)  # (m, n, 3)
        out = np.einsum("mnba,mnb->mna", R, base)  # R_i^T M_i
    batch.cache[_GRAVITY_KEY] = out
    return out


class TiltingCompliance(ComplianceEffect):
    """Joint N tilts about its frame's t1 and t2 axes under the moment it carries.

    Each tilting direction is a rotational spring through the joint origin o_N about the base-
    frame axis u: its TCP twist is j_u = [u x (p - o_N); u], and

        dX = sum_u c_u j_u (j_u^T F + u . M_g),

    the tilting moment being the process wrench's j_u^T F plus the moment M_g of the weight of
    the links beyond the joint about o_N (:func:`link_gravity_moments`; zero without link
    masses in the robot file): the bearing carries both. Parameters c_t1, c_t2 are tilting
    compliances [rad/(N m)]; seed 002 eq. 2.
    """

    name = "tilting_compliance"
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

    def tilt_moments(self, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """Tilting moments about t1 and t2, process wrench and links' weight [N m], (m, 1, 2)."""
        assert self.joint is not None
        jt = self.tilt_twists(batch)
        F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6))
        moment = np.matmul(F[:, None, :], jt)  # from the process wrench
        if batch.robot.has_link_masses:
            gravity = link_gravity_moments(batch)[:, self.joint] @ self._local_axes().T
            moment = moment + gravity[:, None, :]
        return moment

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        return self.tilt_twists(batch) * self.tilt_moments(batch, wrench)

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.deflection_regressor(batch, wrench, theta) @ theta

    def cartesian_compliance(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        jt = self.tilt_twists(batch)
        return np.matmul(jt * theta, jt.transpose(0, 2, 1))
