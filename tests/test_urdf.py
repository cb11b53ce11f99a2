"""URDF loading: vendor URDFs with mimic joints, xacro files, tip links and URDF limits.

Uses the public M-900iB/700 (ROS-Industrial, with mimic joints for the parallelogram bar and
balancers, nq = 18) and KR 600 R2830 (KUKA) URDFs in ``tests/data/vendor/`` (SOURCE.md there).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.description import load_robot_description
from rfsw_plan.robot.kinematics import load_robot

VENDOR = Path(__file__).parent / "data" / "vendor"

FANUC_TOML = f"""
name = "m900ib700_urdf"
[kinematics]
urdf = "{VENDOR / 'fanuc_m900ib700.urdf'}"
tip_link = "tool0"
[tool]
xyz_mm = [0, 0, 450]
[controller]
# ROS-I joint_3 = J3 + J2: the URDF's own values, so sign +1 and the coupling below.
axes = ["J1", "J2", "J3", "J4", "J5", "J6"]
base_xyz_mm = [0, 0, 940]
[joints]
acceleration_deg_s2 = [200, 200, 200, 300, 300, 450]
lower_deg = [-180, -64, -130, -360, -122, -360]
upper_deg = [180, 90, 30, 360, 122, 360]
velocity_deg_s = [80, 80, 80, 100, 100, 160]
coupling = [[1,0,0,0,0,0],[0,1,0,0,0,0],[0,1,1,0,0,0],[0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]]
[stiffness]
k_Nm_per_rad = [5.73e6, 5.37e6, 1.49e6, 5.8e4, 8.5e4, 5.8e4]
"""

KUKA_TOML = f"""
name = "kr600_urdf"
[kinematics]
urdf = "{VENDOR / 'kuka_kr600_r2830.urdf'}"
tip_link = "{{tip}}"
[controller]
axes = ["A1", "A2", "A3", "A4", "A5", "A6"]
[joints]
acceleration_deg_s2 = [180, 160, 160, 250, 250, 350]
{{limits}}
[stiffness]
k_Nm_per_rad = [2.3e6, 8.6e6, 2.8e6, 3.0e6, 0.2e6, 0.9e6]
"""


def _write(tmp_path: Path, text: str, name: str = "robot.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_fanuc_urdf_with_mimic_joints_loads_as_six_axes(tmp_path: Path) -> None:
    """18 URDF joint values (mimic bar and balancers) reduce to the 6-joint actuated chain,
    and its TCP agrees with the bundled FANUC description at the same J1..J6 to 1e-9 mm."""
    robot = load_robot(load_robot_description(_write(tmp_path, FANUC_TOML)))
    bundled = load_robot("fanuc_s900ib_400")
    assert robot.nq == 6
    rng = np.random.default_rng(3)
    for J in rng.uniform(np.radians(-60), np.radians(30), size=(30, 6)):
        ours = np.linalg.inv(robot.description.convention.base) @ robot.fk(J)
        ref = np.linalg.inv(bundled.description.convention.base) @ bundled.fk(J)
        np.testing.assert_allclose(ours, ref, atol=1e-12)
        np.testing.assert_allclose(robot.jacobian(J), bundled.jacobian(J), atol=1e-12)


def test_kuka_urdf_uses_urdf_limits_and_matches_bundled(tmp_path: Path) -> None:
    """No TOML limits: the URDF's are used (= the bundled KR600's); FLANGE agrees to 1e-12."""
    desc = load_robot_description(_write(tmp_path, KUKA_TOML.format(tip="flange", limits="")))
    bundled = load_robot("kuka_kr600_r2830")
    np.testing.assert_allclose(np.degrees(desc.lower), np.degrees(bundled.description.lower),
                               atol=0.01)
    np.testing.assert_allclose(np.degrees(desc.upper), np.degrees(bundled.description.upper),
                               atol=0.01)
    np.testing.assert_allclose(np.degrees(desc.velocity),
                               np.degrees(bundled.description.velocity), atol=0.01)
    robot = load_robot(desc)
    conv = bundled.description.convention
    for A in np.random.default_rng(4).uniform(-1.5, 0.3, size=(30, 6)):
        ref = bundled.fk(A) @ np.linalg.inv(bundled.description.tool) @ conv.flange
        np.testing.assert_allclose(robot.fk(A), ref, atol=1e-12)


def test_toml_limit_outside_urdf_is_reported(tmp_path: Path) -> None:
    limits = ("lower_deg = [-185, -130, -100, -350, -120, -350]\n"
              "upper_deg = [185, 20, 150, 350, 120, 350]")
    path = _write(tmp_path, KUKA_TOML.format(tip="flange", limits=limits))
    with pytest.raises(InputError, match=r"upper_deg: joint 3 is 150 deg, outside the URDF's "
                                         r"limit 144 deg"):
        load_robot_description(path)


def test_tip_that_is_not_the_chain_end_is_accepted(tmp_path: Path) -> None:
    """The chain simply ends at the tip: link_3 gives a 3-joint arm."""
    limits = "lower_deg = [-185, -130, -100]\nupper_deg = [185, 20, 144]"
    text = KUKA_TOML.format(tip="link_3", limits=limits).replace(
        "[180, 160, 160, 250, 250, 350]", "[180, 160, 160]").replace(
        "[2.3e6, 8.6e6, 2.8e6, 3.0e6, 0.2e6, 0.9e6]", "[2.3e6, 8.6e6, 2.8e6]").replace(
        '"A1", "A2", "A3", "A4", "A5", "A6"', '"A1", "A2", "A3"')
    robot = load_robot(load_robot_description(_write(tmp_path, text)))
    assert robot.nq == 3


def test_unknown_tip_lists_link_names_only(tmp_path: Path) -> None:
    path = _write(tmp_path, KUKA_TOML.format(tip="link_9", limits=""))
    with pytest.raises(InputError) as exc:
        load_robot_description(path)
    msg = str(exc.value)
    assert "no link 'link_9'" in msg and "link_6" in msg and "tool0" in msg
    assert "joint_1" not in msg and "universe" not in msg and "\n" not in msg


def test_xacro_gets_one_line_and_exit_2(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    xacro = tmp_path / "m900ib700.urdf.xacro"
    xacro.write_text('<robot xmlns:xacro="http://wiki.ros.org/xacro"/>')
    code = main(["predict", "--robot", str(xacro), "--q-deg", "0,0,0,0,0,0",
                 "--wrench", "0,0,1000"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and "expand it first with the xacro command" in err
    toml = _write(tmp_path, FANUC_TOML.replace("fanuc_m900ib700.urdf", "m.urdf.xacro"))
    with pytest.raises(InputError, match="expand it first with the xacro command"):
        load_robot_description(toml)
