"""Vectorised inverse kinematics over many placements and waypoints at once.

A damped Newton (Levenberg-Marquardt) iteration on every pose of a batch at the same time, with
the batch forward kinematics and Jacobian of
:meth:`~rfsw_plan.robot.kinematics.Robot.batch_fk_jacobian`:

    e = (p* - p(q), log(R* R(q)^T)),  dq = J^T (J J^T + lambda^2 I)^-1 clip(e)

where ``clip`` shortens the task-space step to at most ``step_pos`` [m] and ``step_rot`` [rad]
(a continuation toward a far target, so the iteration stays on the seed's configuration branch),
and the joint step to ``step_joint`` [rad].
Only the poses that have not converged are iterated; a pose whose error stops falling is given
up (unreachable). Joint limits are not enforced here: the caller checks them, so a pose that is
only reachable outside the limits is reported as a limit violation, not as unreachable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class BatchIK:
    """Result of :func:`solve_poses`.

    Attributes:
        q: Joint values [rad], shape (N, n) (the last iterate where not converged).
        converged: Position and rotation errors below the tolerances, shape (N,).
        position_error: |p* - p(q)| [m], shape (N,).
        rotation_error: Angle of R* R(q)^T [rad], shape (N,).
        iterations: Newton iterations run (on the slowest pose).
        T: TCP poses at the last evaluated iterate [m], (N, 4, 4) (at ``q`` where converged).
        J: Base-frame TCP Jacobians there, (N, 6, n).
    """

    q: FloatArray
    converged: BoolArray
    position_error: FloatArray
    rotation_error: FloatArray
    iterations: int
    T: FloatArray
    J: FloatArray


def rotation_error(R_target: FloatArray, R: FloatArray) -> FloatArray:
    """Rotation vectors log(R_target R^T) [rad], shape (N, 3), for (N, 3, 3) inputs.

    The angle comes from atan2(|v|, (tr - 1) / 2) with v the vee of the skew part, so it is
    exact up to 180 deg (where the direction is undefined and a zero vector is returned).
    """
    E = np.matmul(R_target, np.transpose(R, (0, 2, 1)))
    v = 0.5 * np.stack([E[:, 2, 1] - E[:, 1, 2], E[:, 0, 2] - E[:, 2, 0],
                        E[:, 1, 0] - E[:, 0, 1]], axis=1)
    s = np.linalg.norm(v, axis=1)
    c = 0.5 * (np.trace(E, axis1=1, axis2=2) - 1.0)
    ang = np.arctan2(s, c)
    scale = np.where(s > 1e-12, ang / np.maximum(s, 1e-300), 1.0)
    return v * scale[:, None]


def solve_poses(
    robot: Robot, R_target: FloatArray, p_target: FloatArray, q_seed: FloatArray,
    tol: float = 1e-7, max_iter: int = 40, step_pos: float = 0.15, step_rot: float = 0.4,
    damping: float = 1e-3, step_joint: float = 0.3,
) -> BatchIK:
    """TCP poses (R_target, p_target) reached from seeds q_seed, all at once.

    Args:
        robot: The robot.
        R_target: Target TCP rotations, base frame, shape (N, 3, 3).
        p_target: Target TCP positions, base frame [m], shape (N, 3).
        q_seed: Seeds [rad], shape (N, n).
        tol: Convergence tolerance on position [m] and rotation [rad].
        max_iter: Iteration cap.
        step_pos: Largest task-space position step per iteration [m].
        step_rot: Largest task-space rotation step per iteration [rad].
        damping: Levenberg-Marquardt damping lambda (SI mix of m and rad).
        step_joint: Largest joint step per iteration [rad] (near a singularity the
            least-squares step would otherwise leave the branch).
    """
    Q = np.array(q_seed, dtype=float)
    N = Q.shape[0]
    pos_err = np.full(N, np.inf)
    rot_err = np.full(N, np.inf)
    done = np.zeros(N, dtype=bool)
    active = np.arange(N)
    history: list[FloatArray] = []  # error of every pose per iteration, for stagnation
    n_iter = 0
    eye = np.eye(6) * damping ** 2
    T_all = np.zeros((N, 4, 4))
    J_all = np.zeros((N, 6, Q.shape[1]))
    for it in range(1, max_iter + 1):
        n_iter = it
        T, J = robot.batch_fk_jacobian(Q[active])
        T_all[active] = T
        J_all[active] = J
        ep = p_target[active] - T[:, :3, 3]
        er = rotation_error(R_target[active], T[:, :3, :3])
        npos = np.linalg.norm(ep, axis=1)
        nrot = np.linalg.norm(er, axis=1)
        pos_err[active] = npos
        rot_err[active] = nrot
        ok = (npos < tol) & (nrot < tol)
        done[active[ok]] = True
        total = npos + nrot
        keep = ~ok
        # Give up on poses whose error has not halved over the last 8 iterations.
        history.append(np.full(N, np.inf))
        history[-1][active] = total
        if len(history) > 9:
            history.pop(0)
        if len(history) > 8:
            old = history[0][active]
            keep &= ~(total > 0.5 * old)
        active = active[keep]
        if active.size == 0:
            break
        ep, er, J = ep[keep], er[keep], J[keep]
        fp = np.minimum(1.0, step_pos / np.maximum(np.linalg.norm(ep, axis=1), 1e-300))
        fr = np.minimum(1.0, step_rot / np.maximum(np.linalg.norm(er, axis=1), 1e-300))
        e = np.hstack([ep * fp[:, None], er * fr[:, None]])
        A = np.matmul(J, np.transpose(J, (0, 2, 1))) + eye
        y = np.linalg.solve(A, e[:, :, None])
        dq = np.matmul(np.transpose(J, (0, 2, 1)), y)[:, :, 0]
        big = np.max(np.abs(dq), axis=1)
        dq *= np.minimum(1.0, step_joint / np.maximum(big, 1e-300))[:, None]
        Q[active] += dq
    return BatchIK(Q, done, pos_err, rot_err, n_iter, T_all, J_all)
