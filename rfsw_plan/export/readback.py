"""Round trip: a re-read program's points, through the robot model, against the verified plan.

Each vendor reader returns its tool, work object and points (pose in the work object, plus the
configuration the program states). :func:`round_trip` turns every point into the robot
model's TCP in the description's base frame, solves the inverse kinematics *on the stated
configuration* (:func:`rfsw_plan.export.config.ik_on_branch`), and compares pose and joint
values with the plan sample the point was written from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InfeasibleError
from rfsw_plan.robot.kinematics import Robot

if TYPE_CHECKING:
    from rfsw_plan.export.format import ControllerFormat, ReadProgram
    from rfsw_plan.export.program import Samples

FloatArray = NDArray[np.float64]

#: Round-trip tolerances: position [m], orientation [rad].
POS_TOL = 1e-5
ANG_TOL = math.radians(0.01)


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
        return (f"{len(self.q)} moved-to points, max {np.max(self.pose_error) * 1e3:.2e} mm, "
                f"{math.degrees(np.max(self.angle_error)):.2e} deg, joints "
                f"{math.degrees(np.max(self.joint_error)):.2e} deg")


def round_trip(robot: Robot, fmt: ControllerFormat, read: ReadProgram,
               expected: Samples) -> RoundTrip:
    """Recover the joint values of a re-read program's points and compare them with the plan.

    A joint target's values are taken as written; a Cartesian point goes through the robot
    model's inverse kinematics on the posture the program states (``fmt.matches``), started
    from the joint values planned for it (one or two Newton steps when the point is right; the
    postures of all these solutions in one pass of the forward kinematics,
    :func:`~rfsw_plan.export.config.seeded_on_branch`; the configuration branches are searched
    only where that solution has another posture).

    Args:
        robot: The robot.
        fmt: The program's format.
        read: The re-read program (tool, work object, points).
        expected: The plan samples the points were written from, in order.

    Raises:
        InfeasibleError: The number of points differs from the plan's.
    """
    from rfsw_plan.export.config import ik_on_branch, seeded_on_branch
    from rfsw_plan.robot.rotation import Rotation

    points = read.points
    q_plan = expected.q
    if len(points) != len(q_plan):
        raise InfeasibleError(f"program has {len(points)} points, the plan {len(q_plan)}",
                              None, "round_trip", None)
    conv = robot.description.convention
    # Model TCP = controller flange * flange^-1 * description tool.
    to_model = np.linalg.inv(read.tool) @ np.linalg.inv(conv.flange) @ robot.description.tool
    Q = np.empty_like(q_plan)
    targets: dict[int, FloatArray] = {}
    for k, p in enumerate(points):
        if p.q is None:
            assert p.pose is not None
            targets[k] = conv.base @ read.work @ p.pose @ to_model
    cart = list(targets)
    first = dict(zip(cart, seeded_on_branch(
        robot, np.array([targets[k] for k in cart]), [points[k].config for k in cart],
        fmt.postures, q_plan[cart]), strict=True))
    for k, p in enumerate(points):
        if p.q is not None:
            Q[k] = p.q
        elif (q := first[k]) is not None:  # on the stated posture from the planned joints
            Q[k] = q
        else:  # at a boundary or on another branch: the search
            Q[k] = ik_on_branch(robot, targets[k], lambda x, p=p: fmt.matches(robot, p, x),
                                q_plan[k])
    T_prog = robot.batch_fk_jacobian(Q)[0]
    T_plan = robot.batch_fk_jacobian(q_plan)[0]
    pos = np.linalg.norm(T_prog[:, :3, 3] - T_plan[:, :3, 3], axis=1)
    ang = (Rotation.from_matrix(T_plan[:, :3, :3]).inv()
           * Rotation.from_matrix(T_prog[:, :3, :3])).magnitude()
    return RoundTrip(Q, pos, np.atleast_1d(ang), np.max(np.abs(Q - q_plan), axis=1))
