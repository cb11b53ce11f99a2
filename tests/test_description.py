"""Robot description files: round trips and bad-input errors (issue 2 §2 and §9)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from rfsw_plan.exceptions import InputError, UnknownNameError
from rfsw_plan.robot.description import (
    ModifiedDH,
    RobotDescription,
    bundled_robot_names,
    load_robot_description,
    save_robot_description,
)
from rfsw_plan.robot.kinematics import load_robot

DATA = Path(__file__).parent / "data"
ROBOTS = ["zk500", "fanuc_s900ib_400", "kuka_kr600_r2830"]


def assert_same(a: RobotDescription, b: RobotDescription) -> None:
    assert (a.name, a.title, a.euler, a.n_joints) == (b.name, b.title, b.euler, b.n_joints)
    if isinstance(a.chain, ModifiedDH):
        assert isinstance(b.chain, ModifiedDH)
        for f in ("a", "d", "alpha", "theta0"):
            np.testing.assert_allclose(getattr(a.chain, f), getattr(b.chain, f), atol=1e-9)
    else:
        assert a.chain.path.resolve() == b.chain.path.resolve()  # type: ignore[union-attr]
        assert a.chain.tip_link == b.chain.tip_link  # type: ignore[union-attr]
    for f in ("tool", "coupling", "lower", "upper", "velocity", "acceleration", "jerk"):
        np.testing.assert_allclose(getattr(a, f), getattr(b, f), atol=1e-9, err_msg=f)
    np.testing.assert_allclose(a.stiffness, b.stiffness, rtol=1e-6)
    assert [e.name for e in a.effects] == [e.name for e in b.effects]
    for ea, eb in zip(a.effects, b.effects, strict=True):
        assert ea.params == pytest.approx(eb.params, rel=1e-12)
    assert a.sources == b.sources


@pytest.mark.parametrize("name", ROBOTS)
def test_bundled_round_trip(tmp_path: Path, name: str) -> None:
    d = load_robot_description(name)
    back = load_robot_description(save_robot_description(d, tmp_path / f"{name}.toml"))
    assert_same(d, back)
    # Same kinematics after the round trip.
    q = np.radians([10.0, 20.0, -30.0, 40.0, 50.0, 60.0])
    np.testing.assert_allclose(load_robot(back).fk(q), load_robot(d).fk(q), atol=1e-9)


def test_urdf_description_round_trip(tmp_path: Path) -> None:
    d = load_robot_description(DATA / "zk500_urdf.toml")
    back = load_robot_description(save_robot_description(d, tmp_path / "u.toml"))
    assert_same(d, back)


def test_tool_rotation_round_trip(tmp_path: Path) -> None:
    raw = tomllib.loads((DATA / "zk500_urdf.toml").read_text())
    raw["kinematics"]["urdf"] = str(DATA / "zk500_like.urdf")
    raw["tool"]["rpy_deg"] = [10.0, -20.0, 30.0]
    p = tmp_path / "r.toml"
    p.write_text(tomli_w.dumps(raw))
    d = load_robot_description(p)
    back = load_robot_description(save_robot_description(d, tmp_path / "r2.toml"))
    np.testing.assert_allclose(back.tool, d.tool, atol=1e-9)


def test_with_stiffness_round_trip(tmp_path: Path) -> None:
    d = load_robot_description("zk500").with_stiffness(np.arange(1.0, 7.0) * 1e6, "test")
    back = load_robot_description(save_robot_description(d, tmp_path / "k.toml"))
    np.testing.assert_allclose(back.stiffness, np.arange(1.0, 7.0) * 1e6)
    assert back.sources["stiffness"] == "test"


def test_unknown_robot_lists_bundled_robots() -> None:
    with pytest.raises(UnknownNameError) as exc:
        load_robot_description("zk5000")
    msg = str(exc.value)
    assert "zk5000" in msg
    for name in bundled_robot_names():
        assert name in msg
    assert "\n" not in msg


def _edited(tmp_path: Path, edit: dict[str, dict[str, object]]) -> Path:
    raw = tomllib.loads((Path(load_robot_description("zk500").path)).read_text())  # type: ignore[arg-type]
    for section, values in edit.items():
        if values is None:
            raw.pop(section)
        else:
            raw[section].update(values)
    p = tmp_path / "edited.toml"
    p.write_text(tomli_w.dumps(raw))
    return p


@pytest.mark.parametrize(
    ("edit", "pattern"),
    [
        ({"stiffness": {"k_Nm_per_rad": [1e6, 0, 1e6, 1e6, 1e6, 1e6]}},
         r"stiffness\.k_Nm_per_rad: joint 2 is 0 \(expected a number in \[1, 1e\+12\]"),
        ({"stiffness": {"k_Nm_per_rad": [1e6, 1e6, -5, 1e6, 1e6, 1e6]}},
         r"joint 3 is -5"),
        ({"stiffness": {"k_Nm_per_rad": [1e6, 1e6, 1e6, 1e6, 1e6]}},
         r"k_Nm_per_rad: has 5 values \(expected a list of 6 numbers\)"),
        ({"joints": {"lower_deg": [-185, -80, -120, -350, -125]}}, r"lower_deg: has 5 values"),
        ({"joints": {"lower_deg": [-185, 90, -120, -350, -125, -350]}},
         r"joint 2: lower 90 >= upper 85"),
        ({"joints": {"velocity_deg_s": [80, 75, 0, 110, 110, 170]}},
         r"velocity_deg_s: joint 3 is 0"),
        ({"joints": {"coupling": [[1, 0, 0, 0, 0, 0]] * 6}}, r"coupling: is singular"),
        ({"kinematics": {"d_mm": "1050"}}, r"kinematics\.d_mm: got '1050'"),
        ({"stiffness": None}, r"stiffness: missing table"),
    ],
)
def test_bad_description_one_line_error(tmp_path: Path, edit: dict, pattern: str) -> None:
    p = _edited(tmp_path, edit)
    with pytest.raises(InputError, match=pattern) as exc:
        load_robot_description(p)
    assert str(p) in str(exc.value) and "\n" not in str(exc.value)


def test_not_toml_and_bad_effects(tmp_path: Path) -> None:
    p = tmp_path / "broken.toml"
    p.write_text("name = [unclosed\n")
    with pytest.raises(InputError, match="not valid TOML"):
        load_robot_description(p)
    raw = tomllib.loads(Path(load_robot_description("zk500").path).read_text())  # type: ignore[arg-type]
    raw["effects"] = [{"name": "tilting_compliance:j2", "params": {"c_t1": "soft"}}]
    p.write_text(tomli_w.dumps(raw))
    with pytest.raises(InputError, match=r"effects\[1\]\.params\.c_t1: got .soft."):
        load_robot_description(p)
