"""Numeric inverse kinematics with Pinocchio (damped least squares, joint limits respected).

Used to find taught configurations along a seam and to seed the planner. Branch selection
(elbow up/down, wrist flip, shoulder front/back) is done by the caller through the seed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from rfsw_plan.robot.kinematics import FloatArray, Robot


@dataclass(frozen=True)
class IKResult:
    """Outcome of :func:`solve_ik`.

    Attributes:
        q: Joint values [rad], shape (n,).
        converged: True if both errors are below tolerance.
        position_error: Remaining TCP position error [m].
        rotation_error: Remaining orientation error [rad].
        iterations: Iterations used.
    """

    q: FloatArray
    converged: bool
    position_error: float
    rotation_error: float
    iterations: int


def solve_ik(
    robot: Robot,
    target: FloatArray,
    q_seed: FloatArray,
    axis_only: bool = False,
    tol_pos: float = 1e-7,
    tol_rot: float = 1e-7,
    max_iter: int = 200,
    damping: float = 1e-6,
) -> IKResult:
    """Joint values that put the TCP at a target pose.

    Args:
        robot: The robot.
        target: Target TCP pose in the base frame, 4x4 [m].
        q_seed: Start configuration [rad]; the solution stays on its branch when possible.
        axis_only: Only match position and the TCP z axis (the free rotation of an
            axisymmetric tool about its axis is left to the seed).
        tol_pos: Position tolerance [m].
        tol_rot: Orientation tolerance [rad].
        max_iter: Iteration cap.
        damping: Levenberg damping of the least-squares step.
    """
    q = np.array(q_seed, dtype=float)
    lo, hi = robot.description.lower, robot.description.upper
    Rt = target[:3, :3]
    pt = target[:3, 3]
    it = 0
    ep = er = np.inf
    for it in range(1, max_iter + 1):
        T, J = robot.fk_jacobian(q)
        e_p = pt - T[:3, 3]
        if axis_only:
            e_r = np.cross(T[:3, 2], Rt[:, 2])
            # The rotation about the tool axis is free: drop that row direction.
            z = T[:3, 2]
            P = np.eye(3) - np.outer(z, z)
            Jr = P @ J[3:]
            e_r = P @ e_r
        else:
            e_r = pin.log3(Rt @ T[:3, :3].T)
            Jr = J[3:]
        ep, er = float(np.linalg.norm(e_p)), float(np.linalg.norm(e_r))
        if ep < tol_pos and er < tol_rot:
            return IKResult(q, True, ep, er, it)
        A = np.vstack([J[:3], Jr])
        b = np.concatenate([e_p, e_r])
        dq = A.T @ np.linalg.solve(A @ A.T + damping * np.eye(6), b)
        step = np.max(np.abs(dq))
        if step > 0.3:
            dq *= 0.3 / step
        q = np.clip(q + dq, lo, hi)
    return IKResult(q, False, ep, er, it)
