"""A program holds what its header claims as its controller runs it (issue 41's review).

The export builds each program once per controller interpolation cycle (KUKA 12 ms, FANUC
8 ms, ABB 12 ms ASSUMED), so a program's speed steps are coarser than the plan's 10 ms samples.
On the FANUC plans the KRL and RAPID programs, run as their controllers run them, hold less
force uncertainty than the plan: the export judges every program it writes the way
``rfsw-plan check`` does, writes that lower level into the program's header and says so first;
a program that would break a GO (the requested uncertainty the plan holds) is refused."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from rfsw_plan.cli.main import main

FANUC = "fanuc_butt_1700mm"


def _file(folder: Path, suffix: str) -> Path:
    return next(p for p in folder.iterdir() if p.name.endswith(suffix))


def _stated(path: Path) -> str:
    """The header's level, the TP's wrapped remark lines joined."""
    text = " ".join(re.sub(r"^\s*(?:\d+:)?\s*[;!]?\s*|\s*;\s*$", "", line)
                    for line in path.read_text().splitlines()[:80])
    m = re.search(r"verified tolerated force uncertainty: \+-([0-9.]+) %", text)
    assert m is not None, path
    return m.group(1)


def test_each_program_states_the_level_it_holds_as_run(plan_with_programs, tmp_path: Path,
                                                        capsys) -> None:
    """On the FANUC plan: KRL and RAPID state their own level and the plan's, TP the plan's;
    check (which recomputes the run) finds each holding what it states; the export's first
    lines say which programs hold less than the plan."""
    folder, rec = plan_with_programs(FANUC)
    plan = 100 * rec["tolerated_force_uncertainty"]
    held = rec["export"]["held_as_run"]
    for fmt, suffix in (("krl", ".src"), ("fanuc_tp", ".ls"), ("rapid", ".mod")):
        path = _file(folder, suffix)
        u = held[fmt]["tolerated_pct"]
        below = u < 0.99 * plan
        assert _stated(path) == f"{u if below else plan:.3g}", (fmt, u, plan)
        capsys.readouterr()
        assert main(["check", "--json", str(path)]) == 0, fmt
        res = json.loads(capsys.readouterr().out)
        assert res["holds"] and res["held_pct"] == pytest.approx(u, rel=1e-9), fmt
        assert res["plan_claimed_pct"] == pytest.approx(plan, rel=1e-12)
    assert held["krl"]["tolerated_pct"] < 0.99 * plan  # the case this file is about
    assert held["fanuc_tp"]["tolerated_pct"] >= 0.99 * plan
    capsys.readouterr()
    assert main(["export", str(folder), "--format", "krl,fanuc_tp", "-o",
                 str(tmp_path / "x")]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith("krl: as its controller runs it the program holds +-"), first
    assert f"below the plan's +-{plan:.2f} %" in first, first


def test_check_holds_a_program_to_its_header(plan_with_programs, tmp_path: Path,
                                             capsys) -> None:
    """The KRL's header edited back to the plan's level: check finds the program as run
    below it and says so (exit 3, failure claim), so the header is what it is held to."""
    folder, rec = plan_with_programs(FANUC)
    dst = tmp_path / "plan"
    shutil.copytree(folder, dst)
    src = _file(dst, ".src")
    plan = 100 * rec["tolerated_force_uncertainty"]
    text = src.read_text()
    line = re.search(r"verified tolerated force uncertainty: .*", text)
    assert line is not None and "as this program runs" in line.group(0)
    src.write_text(text.replace(line.group(0),
                                f"verified tolerated force uncertainty: +-{plan:.3g} %"))
    capsys.readouterr()
    assert main(["check", "--json", str(src)]) == 3
    res = json.loads(capsys.readouterr().out)
    assert res["failure"] == "claim" and res["below_claim"]
    assert f"below the plan's +-{plan:.2f} %" in res["line"], res["line"]


def test_a_program_that_breaks_the_go_is_refused(tmp_path: Path, capsys) -> None:
    """Planned for +-2.8 %, the FANUC plan holds +-2.83 % (GO); its KRL as run holds less
    than +-2.8 %: plan --export refuses it (exit 3, one line naming the format, both levels
    and what to do) and writes no program. The folder records the refusal as a planner's
    (verdict NO, saying the plan holds and its program does not), not an unfinished plan, and
    the command prints that verdict first."""
    out = tmp_path / "go"
    code = main(["plan", FANUC, "--force-uncertainty", "2.8%", "--export", "krl",
                 "-o", str(out)])
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert code == 3, err
    assert len(err) == 1 and err[0].startswith("rfsw-plan plan: error: krl program as its "
                                               "controller runs it (12 ms"), err
    assert "the requested +-2.8 % the plan holds (GO)" in err[0], err
    assert not list(out.glob("*.src"))
    rec = json.loads((out / "plan.json").read_text())
    assert rec["status"] == "infeasible" and rec["verdict"] == "NO", rec
    assert rec["verdict_text"] == ("NO: the plan holds, but a program written from it does not "
                                   "as its controller runs it: " + rec["message"])
    assert err[0].endswith(rec["message"])
    assert captured.out.splitlines() == [rec["verdict_text"]]
    assert sorted(p.name for p in out.iterdir()) == ["plan.json"]
    page = (Path(__file__).parents[1] / "docs" / "guide" / "programs.md").read_text()
    quoted = page.split("tests/test_export_claim.py runs it", 1)[1].split("```")[1]
    assert quoted.strip() == err[0]  # the manual shows what the command prints
