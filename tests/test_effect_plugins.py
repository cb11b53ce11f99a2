"""User-defined effects (issue 27): ``--effects FILE.py`` and entry points of group
``rfsw_plan.effects``, recorded with their SHA-256 in saved robot files.

The proof case: a campaign whose hidden physics (the upper arm bending as a beam) is not in
the library is "unexplained"; with the documented example file it is named and the held-out
error falls to the noise floor.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.elastostatics import plugins
from rfsw_plan.elastostatics.effects.base import EFFECTS
from rfsw_plan.io.measurements import write_measurements
from rfsw_plan.robot.description import load_robot_description
from rfsw_plan.validation import run_campaign

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "effects" / "link_bending.py"
DOC = ROOT / "docs" / "dev" / "writing-an-effect.md"


@pytest.fixture(autouse=True)
def _clean_registry() -> Iterator[None]:
    """Every test starts and ends with the library's effects only."""
    effects = dict(EFFECTS)
    yield
    EFFECTS.clear()
    EFFECTS.update(effects)
    plugins._LOADED.clear()
    plugins._PROVIDER.clear()


@pytest.fixture
def campaign(tmp_path: Path) -> Path:
    """A ZK-500 campaign whose upper arm bends (hidden: link_bending:j2 of the example)."""
    plugins.load_effect_file(EXAMPLE)
    camp = run_campaign("zk500", ["link_bending:j2"], poses=30, loads_per_pose=4,
                        noise_mm=0.01, seed=4)
    assert camp.contribution_rms_mm["link_bending:j2"] > 0.5
    del EFFECTS["link_bending"]  # the library as shipped does not have it
    return write_measurements(tmp_path / "bending.csv", camp.data)


def _validate(args: list[str], capsys: pytest.CaptureFixture[str]) -> dict:
    assert main(["validate", "--no-report", "--json", *args]) == 0
    out: dict = json.loads(capsys.readouterr().out)
    return out


def test_unexplained_without_the_file_named_and_at_the_floor_with_it(
        campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    common = ["--robot", "zk500", "--data", str(campaign)]
    before = _validate(common, capsys)["diagnosis"]
    assert before["verdict"] == "unexplained"
    assert all(c["label"] != "link_bending:j2" for c in before["candidates"])
    after = _validate([*common, "--effects", str(EXAMPLE)], capsys)["diagnosis"]
    assert after["verdict"] == "missing"
    assert after["candidates"][0]["label"] == "link_bending:j2"
    saved = tmp_path / "bent.toml"
    added = _validate([*common, "--effects", str(EXAMPLE), "--add", "link_bending:j2",
                       "--save-robot", str(saved)], capsys)["diagnosis"]
    assert added["verdict"] == "adequate"
    floor = added["noise"]["sigma_mm"]
    assert added["heldout_rms_mm"] <= 1.1 * floor
    # The saved robot names the file and its hash ...
    desc = load_robot_description(saved)
    (plugin,) = desc.plugins
    assert plugin.kind == "file" and Path(plugin.ref) == EXAMPLE.resolve()
    assert plugin.sha256 == hashlib.sha256(EXAMPLE.read_bytes()).hexdigest()
    assert plugin.effects == ("link_bending",)
    # ... and loads it by itself: no --effects needed to use the robot afterwards.
    del EFFECTS["link_bending"]
    plugins._LOADED.clear()
    again = _validate(["--robot", str(saved), "--data", str(campaign)], capsys)["diagnosis"]
    assert again["verdict"] == "adequate"


def test_changed_or_missing_file_is_one_line(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    mine = tmp_path / "my_bending.py"
    shutil.copy(EXAMPLE, mine)
    robot = tmp_path / "r.toml"
    data = tmp_path / "d.csv"
    plugins.load_effect_file(mine)
    camp = run_campaign("zk500", ["link_bending:j2"], poses=12, loads_per_pose=2, seed=1)
    write_measurements(data, camp.data)
    assert main(["validate", "--robot", "zk500", "--data", str(data), "--no-report",
                 "--effects", str(mine), "--add", "link_bending:j2", "--save-robot",
                 str(robot)]) == 0
    capsys.readouterr()
    del EFFECTS["link_bending"]
    plugins._LOADED.clear()
    mine.write_text(mine.read_text() + "# edited\n")
    code = main(["predict", "--robot", str(robot), "--q-deg", "0,-30,60,0,30,0",
                 "--wrench", "0,0,-1000"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "changed since the robot was saved" in err and "effect_plugins[1]" in err
    mine.unlink()
    code = main(["predict", "--robot", str(robot), "--q-deg", "0,-30,60,0,30,0",
                 "--wrench", "0,0,-1000"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and "not found" in err


@pytest.mark.parametrize("text, expected", [
    ("import nothing_such_module\n", "could not be loaded: ModuleNotFoundError"),
    ("x = 1\n", "defines no effect"),
    ("def f(:\n", "could not be loaded: SyntaxError"),
])
def test_bad_effect_files(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str,
                          expected: str) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text(text)
    code = main(["predict", "--robot", "zk500", "--q-deg", "0,-30,60,0,30,0", "--wrench", "0,0,0",
                 "--effects",
                 str(bad)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and expected in err, err


def test_an_entry_point_is_loaded_and_recorded(tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """A package that declares its effect under group rfsw_plan.effects (an installed
    distribution's entry_points.txt) is loaded without --effects and recorded with the hash
    of its module."""
    shutil.copy(EXAMPLE, tmp_path / "bending_pkg.py")
    info = tmp_path / "bending_pkg-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: bending-pkg\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[rfsw_plan.effects]\nlink_bending = bending_pkg:LinkBending\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    (loaded,) = [x for x in plugins.load_entry_points() if "bending_pkg" in x.spec.ref]
    assert loaded.spec.kind == "entry_point" and "link_bending" in EFFECTS
    assert loaded.spec.sha256 == hashlib.sha256(
        (tmp_path / "bending_pkg.py").read_bytes()).hexdigest()
    assert plugins.plugins_of(["joint_compliance", "link_bending"]) == (
        plugins.PluginSpec("entry_point", loaded.spec.ref, loaded.spec.sha256,
                           ("link_bending",)),)


def test_the_documented_example_is_the_file_the_tests_run() -> None:
    """docs/dev/writing-an-effect.md shows the example file verbatim."""
    assert EXAMPLE.read_text().strip() in DOC.read_text()
