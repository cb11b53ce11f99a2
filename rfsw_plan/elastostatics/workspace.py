"""Workspace maps of elastostatic indices: Kc influence nu_p and dexterity kappa_f.

Seed 000 §3.2.3-3.2.5 draws kappa_f (eq. 5, Fig. 12) and nu_p (eq. 9, Fig. 13) as isocontours
over the robot's vertical workspace plane: q1 = 0, the wrist joints fixed (45 deg), and the
two arm joints swept over their ranges. :func:`sample_joint_grid` builds such a grid and
:func:`index_map` evaluates both indices on it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rfsw_plan.elastostatics.compliance import dexterity
from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.kinematics import Robot


@dataclass(frozen=True)
class JointGrid:
    """Configurations on a regular grid of two swept joints, the others fixed.

    Attributes:
        q: Controller joint values [rad], shape (m, n), m = shape[0] * shape[1].
        position: TCP positions in the base frame [m], shape (m, 3).
        swept: 0-based indices of the two swept joints.
        axes: Values of the two swept joints [rad], shapes (shape[0],) and (shape[1],).
        shape: Grid shape (len(axes[0]), len(axes[1])); ``q`` is in row-major order.
    """

    q: FloatArray
    position: FloatArray
    swept: tuple[int, int]
    axes: tuple[FloatArray, FloatArray]
    shape: tuple[int, int]


@dataclass(frozen=True)
class IndexMap:
    """nu_p and kappa_f over a :class:`JointGrid`.

    Attributes:
        grid: The configurations.
        wrench: Wrench at the TCP, base frame [N, N m], shape (6,).
        Kq: Joint stiffness matrix used [N m/rad], shape (n, n).
        nu_p: Influence index of Kc on the TCP translation (seed 000 eq. 9), shape (m,);
            NaN where Kq - Kc is singular.
        kappa_f: Dexterity (seed 000 eq. 5), shape (m,); inf at singularities.
        dx: Translational deflection without Kc [m], shape (m,) (eq. 11).
        dx_kc: Translational deflection with Kc [m], shape (m,) (eq. 6).
    """

    grid: JointGrid
    wrench: FloatArray
    Kq: FloatArray
    nu_p: FloatArray
    kappa_f: FloatArray
    dx: FloatArray
    dx_kc: FloatArray

    def percentiles(self, values: Sequence[float] = (50.0, 90.0, 99.0)) -> dict[str, float]:
        """Percentiles and max of the finite nu_p values, keyed ``p50``..., ``max``."""
        v = self.nu_p[np.isfinite(self.nu_p)]
        if v.size == 0:
            return {"max": float("nan")}
        out = {f"p{x:g}": float(np.percentile(v, x)) for x in values}
        out["max"] = float(v.max())
        return out


def sample_joint_grid(
    robot: Robot,
    q_fixed: FloatArray,
    swept: tuple[int, int] = (1, 2),
    n_points: tuple[int, int] = (41, 41),
    margin: float = 0.0,
) -> JointGrid:
    """Regular grid of two joints over their limits, the other joints at ``q_fixed``.

    Args:
        robot: The robot (limits from its description).
        q_fixed: Values of all joints [rad], shape (n,); the swept entries are overwritten.
        swept: 0-based indices of the two swept joints (seed 000 Fig. 12-13: q2, q3).
        n_points: Grid points per swept joint (>= 2 each).
        margin: Distance kept from each limit [rad].

    Raises:
        InputError: Wrong joint count, bad joint index or fewer than two points.
    """
    q0 = robot.check_q(q_fixed, "q_fixed")
    if len(set(swept)) != 2 or not all(0 <= j < robot.nq for j in swept):
        raise InputError("swept", "", f"got {swept}", f"two different joints in 0..{robot.nq - 1}")
    if min(n_points) < 2:
        raise InputError("n_points", "", f"got {n_points}", "at least 2 per joint")
    d = robot.description
    axes = tuple(
        np.linspace(d.lower[j] + margin, d.upper[j] - margin, n)
        for j, n in zip(swept, n_points, strict=True)
    )
    A, B = np.meshgrid(axes[0], axes[1], indexing="ij")
    Q = np.tile(q0, (A.size, 1))
    Q[:, swept[0]] = A.ravel()
    Q[:, swept[1]] = B.ravel()
    T, _ = robot.batch_fk_jacobian(Q)
    return JointGrid(Q, T[:, :3, 3].copy(), (swept[0], swept[1]), (axes[0], axes[1]),
                     (int(n_points[0]), int(n_points[1])))


def index_map(
    robot: Robot, grid: JointGrid, wrench: FloatArray, Kq: FloatArray | None = None,
    length_scale: float = 1.0,
) -> IndexMap:
    """nu_p (seed 000 eq. 9) and kappa_f (eq. 5) at every grid configuration.

    Args:
        robot: The robot; J and dJ/dq are taken wrt its controller (motor) joints.
        grid: Configurations from :func:`sample_joint_grid`.
        wrench: Wrench the environment applies at the TCP, base frame [N, N m], shape (6,).
        Kq: Joint stiffness matrix on the controller side [N m/rad], shape (n, n) or (n,);
            the robot's stiffness if None.
        length_scale: Passed to :func:`dexterity` (seed 000 uses 1 m).
    """
    F = np.asarray(wrench, dtype=float)
    if F.shape != (6,):
        raise InputError("wrench", "", f"has shape {F.shape}", "6 values fx..mz")
    K = np.diag(robot.stiffness) if Kq is None else np.asarray(Kq, dtype=float)
    if K.ndim == 1:
        K = np.diag(K)
    if K.shape != (robot.nq, robot.nq):
        raise InputError("Kq", "", f"has shape {K.shape}", f"({robot.nq}, {robot.nq})")
    _, J = robot.batch_fk_jacobian(grid.q)
    m = grid.q.shape[0]
    kappa = np.array([dexterity(J[i], length_scale) for i in range(m)])
    Kc = np.einsum("mkaj,a->mjk", robot.batch_jacobian_derivatives(grid.q), F)  # eq. 6
    tau = np.einsum("maj,a->mj", J, F)  # J^T F [N m]
    dx = np.linalg.norm(np.einsum("maj,mj->ma", J[:, :3], np.linalg.solve(K, tau.T).T), axis=1)
    dx_kc = np.full(m, np.nan)
    for i in range(m):  # one solve per pose so that a singular Kq - Kc only loses that pose
        try:
            dq = np.linalg.solve(K - Kc[i], tau[i])
        except np.linalg.LinAlgError:
            continue
        dx_kc[i] = np.linalg.norm(J[i, :3] @ dq)
    nu = np.abs(dx_kc - dx) / np.maximum(dx, dx_kc)  # eq. 9; NaN where dx_kc is NaN
    return IndexMap(grid, F, K, nu, kappa, dx, dx_kc)
