"""Shared fixtures: the bundled problems planned once per session, as typed results
(``planned_result``) and with every export format (``plan_with_programs``: the plans
``tests/test_export.py`` and ``tests/test_program_checkers.py`` check). Planning is
deterministic, so one plan per problem stands for every test that only reads it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

#: (problem, robot) of the three bundled plans whose programs are checked.
PROGRAM_CASES = [("zk500_table6_seam", "zk500_seed001"), ("fanuc_butt_1700mm", "fanuc_s900ib_400"),
                 ("kr600_curved_seam", "kuka_kr600_r2830")]

_PLANS: dict[str, tuple[Path, dict[str, Any]]] = {}
_RESULTS: dict[str, Any] = {}


@pytest.fixture(scope="session")
def planned_result():
    """``planned_result(problem)`` -> the :class:`~rfsw_plan.planning.result.PlanResult` of
    ``rfsw_plan.plan(problem)`` with the problem's own options, planned once per session
    (frozen: tests read it, never change it)."""
    from rfsw_plan.planning.api import plan

    def get(problem: str) -> Any:
        if problem not in _RESULTS:
            _RESULTS[problem] = plan(problem)
        return _RESULTS[problem]

    return get


@pytest.fixture(scope="session")
def plan_with_programs(tmp_path_factory: pytest.TempPathFactory):
    """``plan_with_programs(problem)`` -> (folder, plan.json) of ``rfsw-plan plan PROBLEM
    --export`` with every registered format, planned once per session."""
    from rfsw_plan.cli.main import main
    from rfsw_plan.export.format import format_names

    def get(problem: str) -> tuple[Path, dict[str, Any]]:
        if problem not in _PLANS:
            out = tmp_path_factory.mktemp(problem)
            code = main(["-q", "plan", problem, "-o", str(out), "--export",
                         ",".join(format_names())])
            assert code == 0
            _PLANS[problem] = (out, json.loads((out / "plan.json").read_text()))
        return _PLANS[problem]

    return get
