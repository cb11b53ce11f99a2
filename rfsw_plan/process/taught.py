"""The taught configuration along a seam: what the robot is commanded without compensation.

At each waypoint the commanded TCP pose is the seam point with the orientation of
:func:`~rfsw_plan.process.frames.tcp_orientation` (TCP z = -n, x along travel turned by the
tool rotation). Inverse kinematics runs waypoint by waypoint, each seeded with the previous
solution (the first with the problem's ``q_seed``), so the path stays on one branch.
"""

from __future__ import annotations

import numpy as np

from rfsw_plan.exceptions import UnreachableError
from rfsw_plan.process.frames import FloatArray, SeamFrames, tcp_orientation
from rfsw_plan.robot.ik import solve_ik
from rfsw_plan.robot.kinematics import Robot

#: Accepted IK residuals: position [m] and orientation [rad].
POSITION_TOL = 1e-6
ROTATION_TOL = 1e-5


def taught_poses(frames: SeamFrames, tool_rotation: FloatArray | float = 0.0) -> FloatArray:
    """Commanded TCP poses along the seam, base frame, shape (k, 4, 4) [m]."""
    R = tcp_orientation(frames, tool_rotation)
    T = np.tile(np.eye(4), (len(frames), 1, 1))
    T[:, :3, :3] = R
    T[:, :3, 3] = frames.p
    return T


def taught_path(
    robot: Robot,
    frames: SeamFrames,
    q_seed: FloatArray,
    tool_rotation: FloatArray | float = 0.0,
) -> FloatArray:
    """Joint values that put the TCP on the seam with the commanded orientation.

    Args:
        robot: The robot.
        frames: Seam waypoint frames (k rows), base frame.
        q_seed: Configuration that picks the IK branch [rad], shape (n,).
        tool_rotation: Rotation about the tool axis [rad], scalar or shape (k,).

    Returns:
        Joint values [rad], shape (k, n).

    Raises:
        UnreachableError: IK fails at a waypoint; names the first one and the remaining
            position and orientation error.
    """
    q = robot.check_q(q_seed, "q_seed_deg").copy()
    T = taught_poses(frames, tool_rotation)
    out = np.empty((len(frames), robot.nq))
    for k in range(len(frames)):
        res = solve_ik(robot, T[k], q, max_iter=300 if k == 0 else 100)
        if not res.converged or res.position_error > POSITION_TOL or \
                res.rotation_error > ROTATION_TOL:
            p = frames.p[k] * 1e3
            lo, hi = robot.description.lower, robot.description.upper
            at = np.flatnonzero((res.q <= lo + 1e-6) | (res.q >= hi - 1e-6))
            lim = "".join(f"; joint {j + 1} at its limit {np.rad2deg(res.q[j]):.1f} deg"
                          for j in at)
            raise UnreachableError(
                f"waypoint {k + 1} of {len(frames)} (s = {frames.s[k] * 1e3:.1f} mm, "
                f"at ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm) is unreachable for "
                f"{robot.name}: IK misses it by {res.position_error * 1e3:.3g} mm and "
                f"{np.rad2deg(res.rotation_error):.3g} deg from the previous configuration{lim}"
            )
        q = res.q
        out[k] = q
    return out


def joints_at(s_query: FloatArray, s_way: FloatArray, Q: FloatArray) -> FloatArray:
    """Joint values between waypoints, linear in arc length (clipped at the ends).

    Args:
        s_query: Arc lengths [m], shape (N,).
        s_way: Waypoint arc lengths [m], shape (k,), increasing.
        Q: Waypoint joint values [rad], shape (k, n).

    Returns:
        Joint values [rad], shape (N, n).
    """
    if len(s_way) == 1:
        return np.repeat(Q, len(s_query), axis=0)
    return np.stack([np.interp(s_query, s_way, Q[:, j]) for j in range(Q.shape[1])], axis=-1)
