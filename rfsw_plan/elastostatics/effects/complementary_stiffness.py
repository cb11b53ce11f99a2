"""Complementary stiffness Kc: the geometry change of the loaded arm (seed 000 eq. 6)."""

from __future__ import annotations

import numpy as np

from rfsw_plan.elastostatics.effects.base import Effect, FloatArray, PoseBatch


def batch_complementary_stiffness(batch: PoseBatch, wrench: FloatArray) -> FloatArray:
    """Kc = [dJ^T/dq_1 F ... dJ^T/dq_n F] for every pose (seed 000 eq. 6), shape (m, n, n).

    For revolute chain joints with unit axes z_k and TCP velocities v_k = z_k x (p - o_k)
    (base frame), dv_j/dq_i = z_min(i,j) x v_max(i,j) (Jacobi identity) and dz_j/dq_i =
    z_i x z_j for i < j, else 0. With F = [f; mu]:

        Kc_chain[j, i] = z_min . (v_max x f) + [i < j] z_i . (z_j x mu),

    and Kc = G^T Kc_chain G on the controller joints (q_chain = G q). Same numbers as
    :func:`rfsw_plan.elastostatics.compliance.complementary_stiffness` with
    :meth:`Robot.jacobian_derivatives`, without building dJ (O(m n^2)).

    Args:
        batch: Poses.
        wrench: Wrench at the TCP, base frame [N, N m], shape (m, 6).
    """
    robot = batch.robot
    n = robot.nq
    F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6))
    z = np.einsum("mjab,jb->mja", batch.frames[:, :, :3, :3], robot.geometry.axes)  # (m, n, 3)
    r = batch.T[:, None, :3, 3] - batch.frames[:, :, :3, 3]  # TCP minus joint origin [m]
    v = np.cross(z, r)
    A = np.einsum("mia,mja->mij", z, np.cross(v, F[:, None, :3]))  # z_i . (v_j x f)
    B = np.einsum("mia,mja->mij", z, np.cross(z, F[:, None, 3:]))  # z_i . (z_j x mu)
    upper = np.triu(np.ones((n, n), dtype=bool), k=1)  # [i, j]: i < j
    # Kc_chain[j, i]: entry (min, max) of A, plus B[i, j] when i < j.
    sym = np.where(upper, A, A.transpose(0, 2, 1))  # sym[i, j] = A[min(i,j), max(i,j)]
    Kc_chain = (sym + np.where(upper, B, 0.0)).transpose(0, 2, 1)
    G = robot.coupling
    if np.array_equal(G, np.eye(n)):
        return Kc_chain
    return np.einsum("ja,mjk,kb->mab", G, Kc_chain, G)


class ComplementaryStiffness(Effect):
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
    description = (
        "The loaded arm changes its geometry as the joints deflect, which changes the lever "
        "arms of the load (the complementary stiffness Kc of seed 000 eq. 6)."
    )
    kind = "compliance"

    def param_names(self) -> tuple[str, ...]:
        return ("gain",)

    def prior(self) -> FloatArray:
        return np.ones(1)

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6))
        k = np.asarray(self.robot.stiffness, dtype=float)
        Kc = batch_complementary_stiffness(batch, F)  # column k is dJ^T/dq_k F [N m/rad]
        tau = np.einsum("mak,ma->mk", batch.J, F)  # joint torques J^T F [N m]
        dq_full = np.linalg.solve(np.diag(k)[None] - Kc, tau[:, :, None])[:, :, 0]
        extra = dq_full - tau / k  # joint deflection the linear model misses [rad]
        return np.einsum("mak,mk->ma", batch.J, extra)[:, :, None]

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.deflection_regressor(batch, wrench, theta)[:, :, 0] * float(theta[0])
