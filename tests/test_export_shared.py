"""What ``export`` and ``check`` compute once and share (issue 41): the judge of a program takes
the joint values its round trip solved, the plan's plate surface, the hooks' spindle clearance
and the first Newton step of the controller run are computed once per plan. Each shared result
is the one computed alone: the same files, the same judgement."""

from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import rfsw_plan.export.api as api
import rfsw_plan.export.check as check
import rfsw_plan.export.config as config
import rfsw_plan.export.program as program
from rfsw_plan import parallel
from rfsw_plan.export.api import export_plan_folder
from rfsw_plan.planfiles.folder import PlanFolder


def _export(plan: Path, out: Path, monkeypatch: pytest.MonkeyPatch, shared: bool,
            ) -> tuple[dict[str, Any], int, int]:
    """Export the plan's KRL, TP and RAPID programs; per format its judgement, how many
    points the IK solved from a seed (round trips and judges together) and how many path
    bounds of the vendor-neutral blend model were computed."""
    judged: dict[str, Any] = {}
    solved = [0]
    bounds = [0]
    seeded = config.seeded_on_branch
    judge = check.judge_program
    bound = program.path_deviation

    def counting_bounds(*a: Any, **k: Any) -> Any:
        bounds[0] += 1
        return bound(*a, **k)

    def counting(robot: Any, targets: Any, *a: Any, **k: Any) -> Any:
        solved[0] += len(targets)
        return seeded(robot, targets, *a, **k)

    def judging(path: Path, folder: Path, read: Any, basis: Any, edited: Any = (),
                solved: Any = None) -> Any:
        if not shared:  # alone: nothing remembered, nothing handed over
            check._START.clear()
            basis, solved = replace(basis, memo={}), None
        res = judge(path, folder, read, basis, edited, solved)
        judged[path.suffix] = res
        return res

    with monkeypatch.context() as mp:
        mp.setattr(config, "seeded_on_branch", counting)
        mp.setattr(api, "judge_program", judging)
        mp.setattr(program, "path_deviation", counting_bounds)
        mp.setattr(parallel, "cores", lambda: 1)  # counted here: no judge in a worker
        check._START.clear()
        export_plan_folder(plan, ["krl", "fanuc_tp", "rapid"], out)
    return judged, solved[0], bounds[0]


def test_a_shared_judgement_is_the_one_made_alone(plan_folder, tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    plan = plan_folder("zk500_table6_seam", tmp_path / "plan")
    alone, n_alone, _ = _export(plan, tmp_path / "alone", monkeypatch, shared=False)
    shared, n_shared, n_bounds = _export(plan, tmp_path / "shared", monkeypatch, shared=True)
    assert sorted(shared) == sorted(alone) == [".ls", ".mod", ".src"]
    assert n_bounds == 1  # KRL and RAPID: one program of one cycle, its bound once
    for suffix, res in shared.items():  # every field, the floats bit for bit
        a = alone[suffix].to_dict()
        b = res.to_dict()
        for d in (a, b):  # the staging folders differ
            d.pop("plan"), d.pop("program")
        assert b == a, suffix
    # the judges took the round trips' solutions: about half the seeded solves
    assert n_shared < 0.6 * n_alone, (n_shared, n_alone)
    for f in (tmp_path / "alone").iterdir():
        assert (tmp_path / "shared" / f.name).read_bytes() == f.read_bytes(), f.name


def test_the_newton_start_remembered_gives_the_same_joint_values(plan_folder,
                                                                 tmp_path: Path) -> None:
    plan, robot = PlanFolder.open_with_robot(plan_folder("zk500_table6_seam", tmp_path / "p"))
    q0 = plan.samples.q
    T = check.sample_fk(robot, q0).copy()
    T[:, :3, 3] += np.array([1e-4, -2e-4, 5e-5])  # a tent of 0.2 mm
    check._START.clear()
    fresh = check._batch_ik(robot, T, q0)
    assert len(check._START) == 1
    again = check._batch_ik(robot, T, q0.copy())  # equal values: the remembered start
    assert len(check._START) == 1
    np.testing.assert_array_equal(again, fresh)
    other = q0.copy()
    other[0, 0] += 1e-9  # other values: not the remembered one
    check._batch_ik(robot, T, other)
    assert len(check._START) == 2


def test_check_of_a_program_is_the_judgement_export_made(plan_with_programs, tmp_path: Path,
                                                         ) -> None:
    """``check`` (its own basis, nothing handed over) finds what the export's shared judge
    found: the level held as run, in ``plan.json``."""
    out, record = plan_with_programs("zk500_table6_seam")
    dst = tmp_path / "plan"
    shutil.copytree(out, dst)
    held = record["export"]["held_as_run"]
    for name, suffix in (("krl", ".src"), ("fanuc_tp", ".ls"), ("rapid", ".mod")):
        res = check.check_program(next(p for p in dst.iterdir() if p.suffix == suffix))
        assert res.holds, res.line()
        assert 100 * res.held[0] == held[name]["tolerated_pct"]
        assert res.held[1] == held[name]["limited_by"]


def test_judgements_shared_with_a_worker_write_the_same_files(plan_folder, tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch
                                                             ) -> None:
    """The export's judgements run in a forked worker and here (two cores) or all here (one):
    the same programs byte for byte and the same levels as run in the record."""
    plan = plan_folder("zk500_table6_seam", tmp_path / "plan")
    out = {}
    for n in (1, 2):
        with monkeypatch.context() as mp:
            mp.setattr(parallel, "cores", lambda n=n: n)
            res = export_plan_folder(plan, ["krl", "fanuc_tp", "rapid", "stream"],
                                     tmp_path / f"cores{n}")
        out[n] = res
    assert out[1].held_as_run == out[2].held_as_run and len(out[1].held_as_run) == 4
    for f in (tmp_path / "cores1").iterdir():
        assert (tmp_path / "cores2" / f.name).read_bytes() == f.read_bytes(), f.name
