"""Complementary stiffness Kc: the geometry change of the loaded arm (seed 000 eq. 6)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import (
    ComplianceEffect,
    FloatArray,
    PoseBatch,
    cross3,
)

#: Largest basis (floats) kept in :attr:`PoseBatch.cache`: 2e7 floats = 160 MB, i.e.
#: ~9e4 poses of a six-axis robot; larger batches recompute it per call.
BASIS_CACHE_MAX = 20_000_000


def complementary_stiffness_basis(batch: PoseBatch) -> FloatArray:
    """Kc_chain per unit wrench component: Kc_chain = basis @ F, shape (m, n * n, 6).

    Kc is linear in the wrench (seed 000 eq. 6). With the scalar triple product,
    z_i . (v_j x f) = f . (z_i x v_j) and z_i . (z_j x mu) = mu . (z_i x z_j), so
    (see :func:`batch_complementary_stiffness`)

        Kc_chain[j, i] = [z_min x v_max; [i < j] z_i x z_j] . F,

    and row ``j * n + i`` of the basis holds that 6-vector. It depends only on the poses and
    is kept in ``batch.cache`` (unless larger than :data:`BASIS_CACHE_MAX`).
    """
    cached: FloatArray | None = batch.cache.get(ComplementaryStiffness.name)
    if cached is not None:
        return cached
    robot = batch.robot
    n = robot.nq
    R = batch.frames[:, :, :3, :3]
    z = np.matmul(R, robot.geometry.axes[:, :, None])[..., 0]  # joint axes, (m, n, 3)
    r = batch.T[:, None, :3, 3] - batch.frames[:, :, :3, 3]  # TCP minus joint origin [m]
    v = cross3(z, r)  # TCP velocity of a unit joint rate, (m, n, 3)
    zv = cross3(z[:, :, None, :], v[:, None, :, :])  # [i, j] = z_i x v_j, (m, n, n, 3)
    zz = cross3(z[:, :, None, :], z[:, None, :, :])  # [i, j] = z_i x z_j
    upper = np.triu(np.ones((n, n), dtype=bool), k=1)[None, :, :, None]  # [i, j]: i < j
    basis = np.empty((len(batch), n, n, 6))  # [m, i, j] = Kc_chain[j, i] per component
    basis[..., :3] = np.where(upper, zv, zv.transpose(0, 2, 1, 3))  # zv[min(i,j), max(i,j)]
    basis[..., 3:] = np.where(upper, zz, 0.0)
    out = np.ascontiguousarray(basis.transpose(0, 2, 1, 3)).reshape(len(batch), n * n, 6)
    if out.size <= BASIS_CACHE_MAX:
        batch.cache[ComplementaryStiffness.name] = out
    return out


def batch_complementary_stiffness(batch: PoseBatch, wrench: FloatArray) -> FloatArray:
    """Kc = [dJ^T/dq_1 F ... dJ^T/dq_n F] for every pose (seed 000 eq. 6), shape (m, n, n).

    For revolute chain joints with unit axes z_k and TCP velocities v_k = z_k x (p - o_k)
    (base frame), dv_j/dq_i = z_min(i,j) x v_max(i,j) (Jacobi identity) and dz_j/dq_i =
    z_i x z_j for i < j, else 0. With F = [f; mu]:

        Kc_chain[j, i] = z_min . (v_max x f) + [i < j] z_i . (z_j x mu),

    and Kc = G^T Kc_chain G on the controller joints (q_chain = G q). Same numbers as
    :func:`rfsw_plan.elastostatics.compliance.complementary_stiffness` with
    :meth:`Robot.jacobian_derivatives`, without building dJ (O(m n^2)); the wrench-independent
    part is :func:`complementary_stiffness_basis`, computed once per batch.

    Args:
        batch: Poses.
        wrench: Wrench at the TCP, base frame [N, N m], shape (m, 6) or (6,).
    """
    robot = batch.robot
    n = robot.nq
    F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6))
    basis = complementary_stiffness_basis(batch)
    Kc_chain = np.matmul(basis, F[:, :, None]).reshape(len(batch), n, n)
    G = robot.coupling
    if np.array_equal(G, np.eye(n)):
        return Kc_chain
    return np.matmul(G.T, np.matmul(Kc_chain, G))


class ComplementaryStiffness(ComplianceEffect):
    """Extra deflection from the load-induced geometry change, scaled by a gain g.

    Seed 000 eq. 6: K_X = J^-T (Kq - Kc) J^-1 with Kc = [dJ^T/dq_1 F ... dJ^T/dq_n F], so the
    full deflection is J (Kq - Kc)^-1 J^T F. This effect adds what the base model misses:

        dX = g [J (Kq - Kc(F))^-1 J^T F - J Kq^-1 J^T F],

    base frame [m, rad], F the true wrench at the TCP (base frame). g = 1 is the physics; g is
    a free gain so that identification can confirm (g ~ 1) or reject (g ~ 0) the effect, and the
    contribution is linear in g (exact regressor). Kq is the robot description's joint
    stiffness (the nominal one, not the joint_compliance parameters being identified: the term
    is second order in the compliance, so the mismatch during identification is negligible).
    """

    name = "complementary_stiffness"
    uses_frames = True
    description = (
        "The loaded arm changes its geometry as the joints deflect, which changes the lever "
        "arms of the load (the complementary stiffness Kc of seed 000 eq. 6)."
    )
    fixed_size = True

    #: Gain g [-]: 1 is the physics; identification may move it, never by an order.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {"gain": (-10.0, 10.0)}

    def param_names(self) -> tuple[str, ...]:
        return ("gain",)

    def prior(self) -> FloatArray:
        return np.ones(1)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """The physics itself, g = 1 (:attr:`fixed_size`: never scaled to be visible)."""
        return {"gain": 1.0}

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6))
        k = np.asarray(self.robot.stiffness, dtype=float)
        Kc = batch_complementary_stiffness(batch, F)  # column k is dJ^T/dq_k F [N m/rad]
        tau = np.matmul(F[:, None, :], batch.J)[:, 0]  # joint torques J^T F [N m]
        dq_full = np.linalg.solve(np.diag(k)[None] - Kc, tau[:, :, None])[:, :, 0]
        extra = dq_full - tau / k  # joint deflection the linear model misses [rad]
        return np.matmul(batch.J, extra[:, :, None])

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.deflection_regressor(batch, wrench, theta)[:, :, 0] * float(theta[0])
