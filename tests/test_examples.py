"""Smoke tests: every user example in examples/ runs as written and its outputs check out."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from rfsw_plan.planfiles.folder import PlanFolder
from rfsw_plan.planfiles.waypoints import PLAN_OUTPUTS
from rfsw_plan.robot.description import load_robot_description

ROOT = Path(__file__).resolve().parents[1]


def _run(script: str, *args: str) -> str:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / script), *args],
                          capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


def test_plan_my_seam_writes_a_verified_plan_folder(tmp_path: Path) -> None:
    out = _run("plan_my_seam.py", str(tmp_path))
    assert "max |lateral error|" in out
    rec = PlanFolder.open(tmp_path / "plan").record  # every vouched file present and unchanged
    assert rec["problem"] == "my_weld"
    assert rec["robot_file"].endswith("zk500.toml")
    assert set(rec["sha256"]) | {"plan.json"} == set(PLAN_OUTPUTS)
    samples = PlanFolder.open(tmp_path / "plan").samples
    assert len(samples.t) > 100


@pytest.fixture(scope="module")
def simulated_validation(validate_my_data_example: tuple[str, Path]) -> tuple[str, Path]:
    """``validate_my_data.py "" zk500 DIR`` (a simulated campaign) run once for the session
    (conftest): its stdout and DIR (read, never changed)."""
    return validate_my_data_example


def test_validate_my_data_names_the_hidden_effect_and_saves_a_loadable_robot(
        simulated_validation: tuple[str, Path]) -> None:
    out, folder = simulated_validation
    assert "verdict missing" in out and "with payload_gravity" in out
    desc = load_robot_description(folder / "improved_robot.toml")  # the strict reader
    assert any(e.name == "payload_gravity" for e in desc.effects)


def test_validate_my_data_reads_a_given_file(tmp_path: Path,
                                            simulated_validation: tuple[str, Path]) -> None:
    out = _run("validate_my_data.py", str(simulated_validation[1] / "campaign.csv"), "zk500",
               str(tmp_path / "b"))
    assert "simulated" not in out and (tmp_path / "b" / "improved_robot.toml").is_file()


def test_compare_my_weld_prints_every_strategy() -> None:
    out = _run("compare_my_weld.py")
    for name in ("none", "offline", "realtime_seed000", "realtime_seed002", "hybrid"):
        assert f"\n  {name} " in out


def test_python_api_writes_the_same_files_as_the_cli(tmp_path: Path) -> None:
    from rfsw_plan.cli.main import main

    _run("python_api.py", str(tmp_path / "api"))
    api = PlanFolder.open(tmp_path / "api").record
    assert main(["-q", "plan", "zk500_table6_seam", "-o", str(tmp_path / "cli"),
                 "--force-uncertainty", "0.1"]) == 0
    cli = PlanFolder.open(tmp_path / "cli").record
    assert set(api["sha256"]) == set(cli["sha256"])
    # Same planner, same options: the same waypoints file, byte for byte.
    assert api["sha256"]["waypoints.csv"] == cli["sha256"]["waypoints.csv"]


def test_plan_result_write_refuses_a_file_as_folder(tmp_path: Path) -> None:
    from rfsw_plan.exceptions import OutputPathError
    from rfsw_plan.planfiles.waypoints import write_plan_folder

    f = tmp_path / "f"
    f.write_text("x")
    with pytest.raises(OutputPathError):
        write_plan_folder(f, None)  # type: ignore[arg-type]  # checked before the result is used


def test_virtual_trial_weld_refuses_a_folder_without_a_plan(tmp_path: Path) -> None:
    """The stand-in for a real trial weld (run in full by the trial-weld page's block under
    -m slow) answers a folder without a plan with one line and exit 2."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / "virtual_trial_weld.py"),
                           str(tmp_path), str(tmp_path / "weld")],
                          capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and "plan.json" in proc.stderr
    assert not (tmp_path / "weld").exists()


#: Every script under examples/ (the plug-in module too: run, it says how to load it).
SCRIPTS = sorted(str(p.relative_to(ROOT / "examples")) for p in (ROOT / "examples").rglob("*.py"))


def _tracked_state() -> str:
    return subprocess.run(["git", "status", "--porcelain", "--untracked-files=all", "--",
                           "robots", "problems", "examples", "docs"], cwd=ROOT,
                          capture_output=True, text=True, check=True).stdout


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_example_answers_help_without_side_effects(tmp_path: Path, script: str) -> None:
    """``--help`` prints a usage and does nothing else: no folder named ``--help``, no run
    (issue 33, wall 3). Run from an empty folder, which stays empty."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    before = _tracked_state()
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / script), "--help"],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.startswith("usage: "), proc.stdout[:500]
    assert "Traceback" not in proc.stderr
    assert list(tmp_path.iterdir()) == []  # nothing written where it was run
    assert _tracked_state() == before  # nor into the repository's tracked folders


@pytest.mark.parametrize("argv, names", [
    (["compare_my_weld.py", "no_such_problem"], "no_such_problem"),
    (["validate_my_data.py", "no_such_file.csv"], "no_such_file.csv"),
    (["plan_my_seam.py", "{out}/a_file"], "a_file"),
    (["trial_weld_loop.py", "{out}/a_file"], "a_file"),
])
def test_examples_end_a_wrong_input_in_one_line(tmp_path: Path, argv: list[str],
                                                names: str) -> None:
    """A wrong name or an output that is a file: one error line naming it, exit 2, never a
    traceback (issue 33, wall 3)."""
    (tmp_path / "a_file").write_text("not a folder\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    args = [a.replace("{out}", str(tmp_path)) for a in argv]
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / args[0]), *args[1:]],
                          capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert proc.returncode == 2, (proc.stdout[-1000:], proc.stderr[-2000:])
    assert "Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert names in proc.stderr and "error" in proc.stderr, proc.stderr[-2000:]
