"""Round trip: a re-read program's points, through the robot model, against the verified plan.

Each vendor reader returns its tool, work object and points (pose in the work object, plus the
configuration the program states). :func:`round_trip` turns every point into the robot
model's TCP in the description's base frame, solves the inverse kinematics *on the stated
configuration* (:func:`rfsw_plan.export.config.ik_on_branch`), and compares pose and joint
values with the plan sample the point was written from.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from rfsw_plan.exceptions import InfeasibleError
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: Round-trip tolerances: position [m], orientation [rad].
POS_TOL = 1e-5
ANG_TOL = math.radians(0.01)


@dataclass(frozen=True)
class ReadPoint:
    """One point re-read from a program.

    Attributes:
        name: The point's name in the program (``XP3``, ``P[3]``, ``p3``).
        pose: TCP pose in the program's work object frame [m], (4, 4).
        config: The configuration the program states (vendor keys: ``S``/``T``, ``CONFIG``,
            ``cf``).
    """

    name: str
    pose: FloatArray
    config: dict[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class RoundTrip:
    """Outcome of :func:`round_trip`.

    Attributes:
        q: Joint values recovered from the program [rad], (P, n).
        pose_error: TCP position difference to the plan sample [m], (P,).
        angle_error: TCP orientation difference [rad], (P,).
        joint_error: max |q - q_plan| per point [rad], (P,).
    """

    q: FloatArray
    pose_error: FloatArray
    angle_error: FloatArray
    joint_error: FloatArray

    @property
    def ok(self) -> bool:
        """Within 0.01 mm and 0.01 deg at every point, on the planned joint values."""
        return bool(np.all(self.pose_error <= POS_TOL) and np.all(self.angle_error <= ANG_TOL)
                    and np.all(self.joint_error <= ANG_TOL))

    def summary(self) -> str:
        """One line with the largest errors."""
        return (f"{len(self.q)} points, max {np.max(self.pose_error) * 1e3:.2e} mm, "
                f"{math.degrees(np.max(self.angle_error)):.2e} deg, joints "
                f"{math.degrees(np.max(self.joint_error)):.2e} deg")


def round_trip(
    robot: Robot, tool: FloatArray, work: FloatArray, points: list[ReadPoint],
    q_plan: FloatArray, matches: Callable[[ReadPoint, FloatArray], bool],
) -> RoundTrip:
    """Recover the joint values of re-read program points and compare them with the plan.

    Args:
        robot: The robot.
        tool: The program's tool: TCP in the controller's flange frame [m], (4, 4).
        work: The program's work object in the controller's base frame [m], (4, 4).
        points: The re-read points, in program order.
        q_plan: The plan samples' joint values the points were written from [rad], (P, n).
        matches: ``(point, q) -> bool``: q has the point's stated configuration.

    Raises:
        InfeasibleError: The number of points differs from the plan's.
    """
    from rfsw_plan.export.config import ik_on_branch

    if len(points) != len(q_plan):
        raise InfeasibleError(f"program has {len(points)} points, the plan {len(q_plan)}",
                              None, "round_trip", None)
    conv = robot.description.convention
    # Model TCP = controller flange * flange^-1 * description tool.
    to_model = np.linalg.inv(tool) @ np.linalg.inv(conv.flange) @ robot.description.tool
    Q = np.empty_like(q_plan)
    pos = np.empty(len(points))
    ang = np.empty(len(points))
    seed: FloatArray | None = None
    for k, p in enumerate(points):
        T = conv.base @ work @ p.pose @ to_model
        q = ik_on_branch(robot, T, lambda x, p=p: matches(p, x), seed)
        Q[k] = q
        seed = q
        ref = robot.fk(q_plan[k])
        pos[k] = float(np.linalg.norm(T[:3, 3] - ref[:3, 3]))
        ang[k] = float((Rotation.from_matrix(ref[:3, :3]).inv()
                        * Rotation.from_matrix(T[:3, :3])).magnitude())
    return RoundTrip(Q, pos, ang, np.max(np.abs(Q - q_plan), axis=1))
