"""The bundled robots against the vendors' public descriptions (``tests/data/vendor/``).

The URDFs are KUKA's own KR 600 R2830 (kroshu/kuka_robot_descriptions) and ROS-Industrial's
FANUC M-900iB/700; SOURCE.md there gives commits and licences. The checks: forward kinematics
of the vendor URDF at controller joint values equals ours at the same values (geometry and the
joint convention of ``[controller]``), the controller flange and base frames match, and the
joint limits and speeds are the vendor's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from rfsw_plan.robot.description import load_robot_description
from rfsw_plan.robot.kinematics import load_robot

DATA = Path(__file__).parent / "data" / "vendor"
KUKA_URDF = DATA / "kuka_kr600_r2830.urdf"
FANUC_URDF = DATA / "fanuc_m900ib700.urdf"


def _urdf_pose(path: Path, frame: str, values: dict[str, float]) -> np.ndarray:
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    q = pin.neutral(model)
    for name, v in values.items():
        jid = model.getJointId(name)
        j = model.joints[jid]
        if j.nq == 2:  # continuous joint: (cos, sin)
            q[j.idx_q:j.idx_q + 2] = np.cos(v), np.sin(v)
        else:
            q[j.idx_q] = v
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId(frame)].homogeneous.copy()


def _random_q(robot, n: int, seed: int) -> np.ndarray:  # type: ignore[no-untyped-def]
    rng = np.random.default_rng(seed)
    lo, hi = robot.description.lower, robot.description.upper
    return rng.uniform(np.maximum(lo, -np.pi), np.minimum(hi, np.pi), size=(n, robot.nq))


def _controller_flange(robot, q: np.ndarray) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Controller flange frame in the controller base frame at controller values q."""
    conv = robot.description.convention
    T = robot.fk(q) @ np.linalg.inv(robot.description.tool) @ conv.flange
    return np.linalg.inv(conv.base) @ T


def test_kuka_fk_matches_kukas_urdf_at_axis_values() -> None:
    """KR 600 R2830: FK of KUKA's URDF at A1..A6 = ours at the same A1..A6 (flange frame)."""
    robot = load_robot("kuka_kr600_r2830")
    for A in _random_q(robot, 50, seed=1):
        ours = _controller_flange(robot, A)
        theirs = _urdf_pose(KUKA_URDF, "flange", {f"joint_{i + 1}": A[i] for i in range(6)})
        assert np.abs(ours[:3, 3] - theirs[:3, 3]).max() < 1e-12
        assert np.abs(ours[:3, :3] - theirs[:3, :3]).max() < 1e-12


def test_fanuc_fk_matches_ros_industrial_urdf_with_j2_j3_interaction() -> None:
    """M-900iB/700: ROS-I joint_3 = J3 + J2; tool0 (faceplate) in the 'base' (world) frame."""
    robot = load_robot("fanuc_s900ib_400")
    for J in _random_q(robot, 50, seed=2):
        vals = {f"joint_{i + 1}": J[i] for i in range(6)}
        vals["joint_3"] = J[2] + J[1]
        vals["pjoint_1"], vals["pjoint_2"] = -vals["joint_3"], vals["joint_3"]  # the mimics
        world = _urdf_pose(FANUC_URDF, "base", vals)
        theirs = np.linalg.inv(world) @ _urdf_pose(FANUC_URDF, "tool0", vals)
        ours = _controller_flange(robot, J)
        assert np.abs(ours[:3, 3] - theirs[:3, 3]).max() < 1e-12
        assert np.abs(ours[:3, :3] - theirs[:3, :3]).max() < 1e-12


@pytest.mark.parametrize(("name", "urdf"), [("kuka_kr600_r2830", KUKA_URDF),
                                            ("fanuc_s900ib_400", FANUC_URDF)])
def test_limits_and_speeds_are_the_vendors(name: str, urdf: Path) -> None:
    """Joint ranges [deg] and speeds [deg/s] equal the vendor URDF's <limit> (to 0.01)."""
    desc = load_robot_description(name)
    model = pin.buildModelFromUrdf(str(urdf))
    lo = np.array([model.lowerPositionLimit[model.joints[model.getJointId(f"joint_{i}")].idx_q]
                   for i in range(1, 7)])
    hi = np.array([model.upperPositionLimit[model.joints[model.getJointId(f"joint_{i}")].idx_q]
                   for i in range(1, 7)])
    v = np.array([model.velocityLimit[model.joints[model.getJointId(f"joint_{i}")].idx_v]
                  for i in range(1, 7)])
    np.testing.assert_allclose(np.degrees(desc.lower), np.degrees(lo), atol=0.02)
    np.testing.assert_allclose(np.degrees(desc.upper), np.degrees(hi), atol=0.02)
    np.testing.assert_allclose(np.degrees(desc.velocity), np.degrees(v), atol=0.01)


def test_zk500_q_is_seed_001_table_2() -> None:
    """ZK-500: q = theta_i of seed 001 Table 1 (no sign or offset), axis names J1..J6."""
    conv = load_robot_description("zk500").convention
    assert conv.kind == "controller" and conv.axes == ("J1", "J2", "J3", "J4", "J5", "J6")
    assert np.all(conv.sign == 1) and np.all(conv.offset == 0)
