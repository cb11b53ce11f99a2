"""The fitted penetration law is cached in memory and on disk by everything it depends on (issue
41): a task rebuilt for the same problem (``check``, ``validate-weld``, the placement map) takes
the law fitted before, in this process or an earlier one (``$RFSW_PLAN_CACHE``), the same one a
cold fit gives bit for bit; a changed input or a changed fitting code fits again; a damaged or
foreign cache file is ignored and refitted, never a traceback."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from rfsw_plan.process import deviation
from rfsw_plan.process.problem import load_problem

PROBLEM = "zk500_table6_seam"
PACKAGE = Path(deviation.__file__).resolve().parents[1]


@pytest.fixture
def counted_fits(monkeypatch, tmp_path) -> list[object]:
    """An empty memory and disk cache (``$RFSW_PLAN_CACHE`` in ``tmp_path``); every fit that
    runs is appended to the returned list."""
    monkeypatch.setenv("RFSW_PLAN_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(deviation, "_LAW_CACHE", type(deviation._LAW_CACHE)())
    fits: list[object] = []
    fit = deviation._fit_problem_law

    def counted(problem, coupling):
        fits.append(problem)
        return fit(problem, coupling)

    monkeypatch.setattr(deviation, "_fit_problem_law", counted)
    return fits


def _bits(law) -> tuple[str, ...]:
    return tuple(float(getattr(law, k)).hex() for k in deviation._LAW_FIELDS)


def test_a_cached_law_is_the_cold_fit_and_a_changed_problem_fits_again(counted_fits,
                                                                         tmp_path) -> None:
    fits = counted_fits
    cold = deviation.problem_penetration_law(load_problem(PROBLEM))
    warm = deviation.problem_penetration_law(load_problem(PROBLEM))  # loaded again: equal inputs
    assert len(fits) == 1 and warm is cold
    pb = load_problem(PROBLEM)
    obs = pb.coupling.calibration
    softer = (dataclasses.replace(obs[0], penetration=obs[0].penetration * 0.9), *obs[1:])
    other = deviation.problem_penetration_law(dataclasses.replace(
        pb, coupling=dataclasses.replace(pb.coupling, calibration=softer)))
    assert len(fits) == 2 and other != cold
    assert len(list((tmp_path / "cache").glob("penetration_law_*.json"))) == 2
    deviation._LAW_CACHE.clear()  # a new process: the disk has it, bit for bit
    disk = deviation.problem_penetration_law(load_problem(PROBLEM))
    assert len(fits) == 2 and _bits(disk) == _bits(cold)
    deviation._LAW_CACHE.clear()
    shutil.rmtree(tmp_path / "cache")
    assert _bits(deviation.problem_penetration_law(load_problem(PROBLEM))) == _bits(cold)
    assert len(fits) == 3  # fitted afresh


@pytest.mark.parametrize("damage", ["empty", "garbage", "truncated", "a list", "another key",
                                    "another format", "a field missing", "a negative stiffness",
                                    "a folder"])
def test_a_damaged_or_foreign_cache_file_is_ignored_and_refitted(counted_fits, damage) -> None:
    """Whatever lies under the cache file's name, the law is fitted again (the same bits) and
    the file rewritten whole; nothing raises."""
    fits = counted_fits
    pb = load_problem(PROBLEM)
    cold = deviation.problem_penetration_law(pb)
    key = deviation._law_key(pb)
    assert key is not None
    path = deviation._law_file(key)
    good = path.read_text()
    rec = json.loads(good)
    text = {"empty": "", "garbage": "\x00\xff not json", "truncated": good[:len(good) // 2],
            "a list": "[1, 2, 3]",
            "another key": json.dumps({**rec, "key": "0" * 64}),
            "another format": json.dumps({**rec, "format": "something else"}),
            "a field missing": json.dumps({k: v for k, v in rec.items() if k != "ref_force"}),
            "a negative stiffness": json.dumps({**rec, "stiffness": (-1.0).hex()})}.get(damage)
    if text is None:  # a folder where the file should be: read fails, the write cannot replace
        path.unlink()
        path.mkdir()
    else:
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
    deviation._LAW_CACHE.clear()
    again = deviation.problem_penetration_law(load_problem(PROBLEM))
    assert len(fits) == 2 and _bits(again) == _bits(cold)
    if text is not None:
        assert path.read_text() == good  # rewritten whole
        deviation._LAW_CACHE.clear()
        deviation.problem_penetration_law(load_problem(PROBLEM))
        assert len(fits) == 2  # and read back


def test_an_unwritable_cache_is_only_a_cache(counted_fits, monkeypatch, tmp_path) -> None:
    """``$RFSW_PLAN_CACHE`` naming a file (no folder can be made there): the law is fitted and
    returned, every time."""
    (tmp_path / "a_file").write_text("x")
    monkeypatch.setenv("RFSW_PLAN_CACHE", str(tmp_path / "a_file"))
    first = deviation.problem_penetration_law(load_problem(PROBLEM))
    deviation._LAW_CACHE.clear()
    assert deviation.problem_penetration_law(load_problem(PROBLEM)) == first
    assert len(counted_fits) == 2


def test_the_key_covers_the_fitting_code_and_the_robot_file(tmp_path) -> None:
    """A change of any module that fits the law (the co-simulation's fit, the elastostatic
    model, the kinematics, the problem reader) gives a new code digest; a module outside
    them does not. A problem on a robot file with other bytes has another key."""
    root = tmp_path / "rfsw_plan"
    root.mkdir()
    for f in PACKAGE.glob("*.py"):
        shutil.copy(f, root / f.name)
    for d in (*deviation.LAW_CODE, "export"):
        shutil.copytree(PACKAGE / d, root / d, ignore=shutil.ignore_patterns("__pycache__"))
    base = deviation.code_digest(root)
    assert base == deviation.code_digest(PACKAGE)
    with (root / "export" / "krl.py").open("a") as fh:
        fh.write("\n# not on the fit's path\n")
    assert deviation.code_digest(root) == base
    for module in ("process/cosim.py", "elastostatics/model.py", "robot/kinematics.py",
                   "process/problem.py", "numfmt.py"):
        text = (root / module).read_bytes()
        (root / module).write_bytes(text + b"\n# changed\n")
        assert deviation.code_digest(root) != base, module
        (root / module).write_bytes(text)
    assert deviation.code_digest(root) == base
    pb = load_problem(PROBLEM)
    robot = tmp_path / "robot.toml"
    robot.write_bytes(pb.robot.path.read_bytes())
    moved = dataclasses.replace(pb, robot=dataclasses.replace(pb.robot, path=robot))
    key = deviation._law_key(moved)
    robot.write_bytes(robot.read_bytes() + b"\n# a comment\n")
    assert deviation._law_key(moved) != key


def test_check_warm_and_cold_print_the_same_and_warm_never_imports_the_fit(
        plan_with_programs, monkeypatch, tmp_path, capsys) -> None:
    """``rfsw-plan check`` (text and ``--json``) of the zk500 program with an empty cache (the
    law fitted) and with the law only on disk prints the same bytes, with the same law bit for
    bit; a new process with the cache warm never imports ``scipy.optimize``."""
    import os

    from rfsw_plan.cli.main import main

    monkeypatch.setenv("RFSW_PLAN_CACHE", str(tmp_path / "cache"))
    folder, _ = plan_with_programs(PROBLEM)
    argv = ["check", str(folder / f"rfsw_{PROBLEM}.src"), "--plan", str(folder)]
    capsys.readouterr()  # the plan's own output, when this test planned it
    runs = {}
    for run in ("cold", "warm"):
        monkeypatch.setattr(deviation, "_LAW_CACHE", type(deviation._LAW_CACHE)())
        if run == "cold":
            shutil.rmtree(tmp_path / "cache", ignore_errors=True)
        out = []
        for flags in ([], ["--json"]):
            assert main([*argv, *flags]) == 0
            out.append(capsys.readouterr().out)
        law = deviation._LAW_CACHE[deviation._law_key(load_problem(PROBLEM))]
        runs[run] = (*out, _bits(law))
    assert runs["cold"] == runs["warm"]
    assert "holds" in runs["cold"][0] and json.loads(runs["cold"][1])["holds"] is True
    code = ("import sys\nfrom rfsw_plan.cli.main import main\n"
            f"assert main({argv!r}) == 0\n"
            "print('scipy.optimize' in sys.modules)\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       env={**os.environ, "RFSW_PLAN_CACHE": str(tmp_path / "cache")},
                       cwd=PACKAGE.parent, timeout=300, check=True)
    assert p.stdout.splitlines()[-1] == "False"
