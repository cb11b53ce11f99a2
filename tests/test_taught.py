"""Taught configuration along the seam."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.exceptions import UnreachableError
from rfsw_plan.process.seam import Seam
from rfsw_plan.process.taught import joints_at, taught_path, taught_poses
from rfsw_plan.robot.kinematics import load_robot


def test_taught_path_reaches_every_waypoint() -> None:
    robot = load_robot("fanuc_s900ib_400")
    fr = Seam(np.array([[1.7, -0.125, 0.6], [1.7, 0.125, 0.6]])).frames(0.025)
    Q = taught_path(robot, fr, np.deg2rad([-4, 11, 36, 0, 54, -4]), np.pi / 2)
    T = taught_poses(fr, np.pi / 2)
    for q, Tk in zip(Q, T, strict=True):
        np.testing.assert_allclose(robot.fk(q), Tk, atol=1e-6)
    # Continuation: no jumps between neighbouring waypoints.
    assert np.max(np.abs(np.diff(Q, axis=0))) < np.deg2rad(5)
    np.testing.assert_allclose(joints_at(fr.s, fr.s, Q), Q)


def test_unreachable_names_waypoint() -> None:
    robot = load_robot("fanuc_s900ib_400")
    fr = Seam(np.array([[1.7, 0.0, 0.6], [4.0, 0.0, 0.6]])).frames(0.25)
    with pytest.raises(UnreachableError, match=r"waypoint \d+ of 11 .*misses it by"):
        taught_path(robot, fr, np.deg2rad([0, 11, 36, 0, 54, 0]))
