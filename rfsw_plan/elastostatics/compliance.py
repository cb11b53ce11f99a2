"""Joint-compliance elastostatics: deflection, Cartesian stiffness, Kc, nu_p, kappa_f.

Pure functions on Jacobians and joint compliance matrices. All wrenches are the wrench the
environment applies to the tool at the TCP, in the base frame, ``[f; m]`` [N, N m]; all
displacements are small TCP twists ``[dp; dtheta]`` in the base frame [m, rad].
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def deflection(J: FloatArray, Cq: FloatArray, wrench: FloatArray) -> FloatArray:
    """TCP deflection under a wrench, dX = J Cq J^T F (seed 000 eq. 11, seed 001 eq. 7).

    Args:
        J: TCP Jacobian, base frame, shape (6, n) or (m, 6, n).
        Cq: Joint compliance matrix [rad/(N m)], shape (n, n) (diagonal K^-1 for a plain arm).
        wrench: Wrench at the TCP, base frame [N, N m], shape (6,) or (m, 6).

    Returns:
        TCP deflection [m, rad], base frame, shape (6,) or (m, 6).
    """
    J = np.asarray(J, dtype=float)
    F = np.asarray(wrench, dtype=float)
    tau = np.einsum("...ji,...j->...i", J, F)  # joint torques J^T F [N m]
    dq = tau @ Cq.T  # joint deflections [rad]
    return np.einsum("...ij,...j->...i", J, dq)


def cartesian_compliance(J: FloatArray, Cq: FloatArray) -> FloatArray:
    """Cartesian compliance matrix C_X = J Cq J^T [m/N, ...], shape (6, 6) or (m, 6, 6)."""
    return J @ Cq @ np.swapaxes(J, -1, -2)


def cartesian_stiffness(
    J: FloatArray, Kq: FloatArray, Kc: FloatArray | None = None
) -> FloatArray:
    """Cartesian stiffness K_X = J^-T (Kq - Kc) J^-1 (seed 000 eq. 6; eq. 7 when Kc = 0).

    Args:
        J: Square TCP Jacobian, shape (6, 6).
        Kq: Joint stiffness matrix [N m/rad], shape (6, 6).
        Kc: Complementary stiffness [N m/rad], shape (6, 6), or None for eq. 7.
    """
    K = Kq if Kc is None else Kq - Kc
    Jinv = np.linalg.inv(J)
    return Jinv.T @ K @ Jinv


def complementary_stiffness(dJ: FloatArray, wrench: FloatArray) -> FloatArray:
    """Complementary stiffness Kc = [dJ^T/dq_1 F ... dJ^T/dq_n F] (seed 000 eq. 6).

    Args:
        dJ: Jacobian derivatives dJ/dq_k, shape (n, 6, n) (``Robot.jacobian_derivatives``).
        wrench: Wrench at the TCP, base frame [N, N m], shape (6,).

    Returns:
        Kc [N m/rad], shape (n, n); column k is (dJ/dq_k)^T F.
    """
    return np.einsum("kaj,a->jk", dJ, wrench)


def deflection_with_kc(
    J: FloatArray, Kq: FloatArray, Kc: FloatArray, wrench: FloatArray
) -> FloatArray:
    """TCP deflection including the geometry change, dX = J (Kq - Kc)^-1 J^T F [m, rad].

    This is K_X^-1 F with K_X from seed 000 eq. 6.
    """
    tau = J.T @ wrench
    return J @ np.linalg.solve(Kq - Kc, tau)


def kc_influence_index(
    J: FloatArray, Kq: FloatArray, Kc: FloatArray, wrench: FloatArray
) -> float:
    """Influence index nu_p of Kc on the translational displacement (seed 000 eq. 8-9).

    nu_p = | ||dX_Kc|| - ||dX_noKc|| | / max(||dX_Kc||, ||dX_noKc||), translations only.
    """
    with_kc = deflection_with_kc(J, Kq, Kc, wrench)[:3]
    without = J @ np.linalg.solve(Kq, J.T @ wrench)
    a, b = float(np.linalg.norm(with_kc)), float(np.linalg.norm(without[:3]))
    return abs(a - b) / max(a, b)


def dexterity(J: FloatArray, length_scale: float = 1.0) -> float:
    """Kinetostatic index kappa_f = (1/6) sqrt(tr(J^T J) tr((J^T J)^-1)) (seed 000 eq. 5).

    kappa_f >= 1; it grows towards singularities (inf at one). Translational rows are divided
    by ``length_scale`` [m] to make the mixed units of J homogeneous (seed 000 uses 1).
    """
    Jn = np.array(J, dtype=float)
    Jn[:3] /= length_scale
    A = Jn.T @ Jn
    try:
        inv_tr = float(np.trace(np.linalg.inv(A)))
    except np.linalg.LinAlgError:
        return float("inf")
    if not np.isfinite(inv_tr) or inv_tr <= 0:
        return float("inf")
    return float(np.sqrt(np.trace(A) * inv_tr) / Jn.shape[1])


def directional_stiffness(C_X: FloatArray, direction: FloatArray) -> FloatArray:
    """Translational stiffness along a unit direction, k = 1 / (l^T C_tt l) [N/m].

    Args:
        C_X: Cartesian compliance, shape (6, 6) or (m, 6, 6).
        direction: Unit direction in the base frame, shape (3,) or (m, 3).
    """
    C_tt = np.asarray(C_X)[..., :3, :3]
    lvec = np.asarray(direction, dtype=float)
    compliance = np.einsum("...i,...ij,...j->...", lvec, C_tt, lvec)
    return 1.0 / compliance
