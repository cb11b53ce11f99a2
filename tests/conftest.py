"""Shared fixtures: the bundled problems planned once per session, as typed results
(``planned_result``), as the folder ``rfsw-plan plan`` writes (``plan_folder``) and with every
export format (``plan_with_programs``: the plans ``tests/test_export.py`` and
``tests/test_program_checkers.py`` check). Planning is deterministic, so one plan per problem
stands for every test that only reads it.

``model`` (the ZK-500 elastostatic model) and ``zk500_case`` (a constant-force task on the
seed 001 seam with its taught and mirror baselines) are the set-ups of the planner, row,
verification, baseline and workbench tests; helpers they share live in ``tests/_helpers.py``."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any, NamedTuple

import pytest
from _plan_store import PlanStore, store_root

#: (problem, robot) of the three bundled plans whose programs are checked.
PROGRAM_CASES = [("zk500_table6_seam", "zk500_seed001"), ("fanuc_butt_1700mm", "fanuc_s900ib_400"),
                 ("kr600_curved_seam", "kuka_kr600_r2830")]

_PLANS: dict[str, tuple[Path, dict[str, Any]]] = {}
_RESULTS: dict[str, Any] = {}

#: The longest test files first (by the sum of their ``--durations``, measured on the default
#: run on 2 cores shared with other jobs, 28 Nov 2026, with this order's previous estimate and
#: issue 41's suite-CPU changes). xdist's
#: ``loadfile`` hands out whole files in collection order (``--no-loadscope-reorder`` in
#: pyproject: not by their number of tests), so a long file never starts last and runs alone
#: while the other worker idles. Every other file follows in its usual order. The order
#: changes no result: each file's tests stay together and in their order.
LONGEST_FIRST = (
    "test_export.py", "test_validate_weld.py", "test_examples.py", "test_mission.py",
    "test_readme_commands.py", "test_placement.py", "test_robust_claim.py", "test_check_edits.py",
    "test_plan_property.py", "test_reader_fuzz.py", "test_progress_cli.py", "test_architecture.py",
    "test_program_checkers.py", "test_kill_and_concurrency.py", "test_validate_cli.py",
    "test_samples.py", "test_strict_json.py", "test_compare.py", "test_verdict.py", "test_docs.py",
    "test_realdata.py", "test_plan_job.py", "test_lost_motion_lab.py", "test_plan_cli.py",
    "test_coarse.py", "test_weld_envelope.py", "test_page3d_chromium.py", "test_waypoints.py",
    "test_full_solver.py", "test_page3d.py", "test_plan_forces.py", "test_realdata_ur10.py",
    "test_plan_cache.py", "test_lost_motion.py", "test_numfmt.py", "test_paper_checks.py",
    "test_program_timing.py", "test_programs_physical.py", "test_nlp.py", "test_plan_folder.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Order the files by :data:`LONGEST_FIRST` (a stable sort: the tests of a file keep their
    order)."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


@pytest.fixture(scope="session")
def plan_store(tmp_path_factory: pytest.TempPathFactory) -> PlanStore:
    """The session's :class:`~_plan_store.PlanStore`: each bundled plan made once for all
    xdist workers."""
    return PlanStore(store_root(tmp_path_factory.getbasetemp()))


@pytest.fixture(scope="session")
def planned_result(plan_store: PlanStore):
    """``planned_result(problem)`` -> the :class:`~rfsw_plan.planning.result.PlanResult` of
    ``rfsw_plan.plan(problem)`` with the problem's own options, planned once per session
    (frozen: tests read it, never change it)."""
    from rfsw_plan.planning.api import plan

    def get(problem: str) -> Any:
        if problem not in _RESULTS:
            _RESULTS[problem] = plan_store.result(("plan", problem), lambda: plan(problem))
        return _RESULTS[problem]

    return get


def _stored_plan_function(planned_result: Any) -> Any:
    """The stand-in for :func:`rfsw_plan.planning.api.plan` of :func:`stored_plans`."""
    import pickle

    import rfsw_plan.planning.api as api
    from rfsw_plan.process.problem import bundled_problem_names, load_problem

    real = api.plan
    bundled = set(bundled_problem_names())

    def bundled_as_is(problem: Any) -> str | None:
        if isinstance(problem, str):
            return problem if problem in bundled else None
        name = getattr(problem, "name", None)
        if name not in bundled:
            return None
        try:
            same = pickle.dumps(problem) == pickle.dumps(load_problem(name))
        except (pickle.PicklingError, TypeError, AttributeError):
            same = False
        return name if same else None

    def plan(problem: Any, options: Any = None, spacing: float | None = None,
             model: Any = None, compile_c: bool | None = None) -> Any:
        name = bundled_as_is(problem)
        if (name is not None and spacing is None and model is None and compile_c is None
                and (options is None or options == load_problem(name).planning)):
            return planned_result(name)
        return real(problem, options, spacing=spacing, model=model, compile_c=compile_c)

    return plan


@pytest.fixture
def stored_plans(monkeypatch: pytest.MonkeyPatch, planned_result: Any) -> None:
    """While the test runs, :func:`rfsw_plan.planning.api.plan` of a bundled problem as its
    file has it (by name, or loaded and unchanged), with the problem's own options, spacing and
    model, returns :func:`planned_result` (made once per session) instead of planning again;
    every other call plans. For tests of what a command does with a plan (``rfsw-plan plan``
    run in this process, ``compare``), not of the planner's work: planning is deterministic,
    and ``tests/test_plan_cache.py`` checks that the stored plan writes a fresh plan's bytes."""
    import rfsw_plan.planning.api as api

    monkeypatch.setattr(api, "plan", _stored_plan_function(planned_result))


@pytest.fixture
def child_stored_plan(planned_result: Any, tmp_path: Path):
    """``child_stored_plan(problem)`` -> Python lines for a child process to run before
    ``main``: there :func:`rfsw_plan.planning.api.plan` of ``problem`` with its own options
    returns the session's :func:`planned_result` (pickled into ``tmp_path``), as
    :func:`stored_plans` does in this process. For children that are about what ``plan`` does
    after planning (a kill at the write, a signal while plotting)."""
    import pickle

    def code(problem: str) -> str:
        path = tmp_path / f"{problem}.plan.pickle"
        if not path.exists():
            path.write_bytes(pickle.dumps(planned_result(problem)))
        return (
            "import pickle as _pickle\n"
            "import rfsw_plan.planning.api as _api\n"
            f"_STORED, _real_plan = _pickle.loads(open({str(path)!r}, 'rb').read()), _api.plan\n"
            "from rfsw_plan.process.problem import load_problem as _load\n"
            "def _stored_plan(problem, options=None, **kw):\n"
            f"    as_is = _load({problem!r})  # the bundled problem as its file has it\n"
            "    if (not any(kw.values()) and options in (None, as_is.planning) and (\n"
            f"            problem == {problem!r}\n"
            "            or _pickle.dumps(problem) == _pickle.dumps(as_is))):\n"
            "        return _STORED\n"
            "    return _real_plan(problem, options, **kw)\n"
            "_api.plan = _stored_plan\n")

    return code


@pytest.fixture(scope="session")
def plan_folder(plan_store: PlanStore, planned_result: Any):
    """``plan_folder(problem, folder)`` -> ``folder``, holding what ``rfsw-plan -q plan PROBLEM
    -o folder`` writes, planned once per session (a plan folder is the same bytes wherever it
    is written: ``tests/test_plan_cache.py``). ``folder`` must not exist; it is the caller's
    copy, to read or change. For tests that need a plan folder, not the ``plan`` command.

    The folder is written by the ``plan`` job (``PlanRequest(problem)``, what the command
    runs) from the session's :func:`planned_result`, so the problem is planned once for both
    (``tests/test_plan_cache.py`` checks that it is the bytes of a fresh plan's folder)."""
    from rfsw_plan.planfiles.job import PlanRequest, PlanRun

    def make(folder: Path, problem: str) -> None:
        PlanRun(PlanRequest(problem).prepare(), planned_result(problem)).write(folder / "plan")

    def get(problem: str, folder: Path) -> Path:
        stored = plan_store.folder(("plan -o", problem), lambda f: make(f, problem))
        shutil.copytree(stored / "plan", folder)
        return folder

    return get


@pytest.fixture(scope="session")
def plan_with_programs(tmp_path_factory: pytest.TempPathFactory, plan_store: PlanStore,
                       planned_result: Any):
    """``plan_with_programs(problem)`` -> (folder, plan.json) of ``rfsw-plan plan PROBLEM
    --export`` with every registered format, run once per session on the session's plan
    (:func:`planned_result`, as :func:`stored_plans` gives it; the folder is this worker's copy
    of the store's)."""
    import rfsw_plan.planning.api as api
    from rfsw_plan.cli.main import main
    from rfsw_plan.export.format import format_names

    formats = ",".join(format_names())

    def make(folder: Path, problem: str) -> None:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(api, "plan", _stored_plan_function(planned_result))
            assert main(["-q", "plan", problem, "-o", str(folder / "plan"), "--export",
                         formats]) == 0

    def get(problem: str) -> tuple[Path, dict[str, Any]]:
        if problem not in _PLANS:
            stored = plan_store.folder(("plan --export", problem, formats),
                                       lambda f: make(f, problem))
            out = tmp_path_factory.mktemp(problem)
            shutil.copytree(stored / "plan", out, dirs_exist_ok=True)
            _PLANS[problem] = (out, json.loads((out / "plan.json").read_text()))
        return _PLANS[problem]

    return get


@pytest.fixture(scope="session")
def validate_my_data_example(plan_store: PlanStore, tmp_path_factory: pytest.TempPathFactory):
    """``python examples/validate_my_data.py "" zk500 DIR`` (a simulated campaign validated
    and the improved robot saved), run once per session for every worker, as written (its own
    process, from the repository's root): ``(stdout, DIR)``, DIR this worker's copy (for
    ``tests/test_examples.py`` and ``tests/test_selection.py``, which read the same run)."""
    import os
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]

    def make(folder: Path) -> None:
        env = {**os.environ, "PYTHONPATH": str(root)}
        proc = subprocess.run([sys.executable, str(root / "examples" / "validate_my_data.py"),
                               "", "zk500", str(folder / "out")], capture_output=True,
                              text=True, env=env, cwd=root, timeout=600)
        assert proc.returncode == 0, proc.stderr[-2000:]
        (folder / "stdout.txt").write_text(proc.stdout)

    stored = plan_store.folder(("examples/validate_my_data.py", "", "zk500"), make)
    out = tmp_path_factory.mktemp("validate_my_data") / "out"
    shutil.copytree(stored / "out", out)
    return (stored / "stdout.txt").read_text(), out


@pytest.fixture(scope="module")
def model() -> Any:
    """The ZK-500 elastostatic model (seed 001 stiffness), one per test module (a module may
    change it)."""
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.robot.kinematics import load_robot

    return ElastostaticModel(load_robot("zk500"))


class Zk500Case(NamedTuple):
    """A constant-force task on the seed 001 seam and its baselines."""

    model: Any
    task: Any
    taught: Any
    mirror: Any


@pytest.fixture(scope="module")
def zk500_case(model: Any):
    """``zk500_case(k)`` -> :class:`Zk500Case` on ``k`` waypoints of the seed 001 seam under
    its steady force at 3 mm/s: the model, the task, the taught path (no compensation) and the
    mirror fake targets, built once per module and ``k``."""
    from _helpers import F_SEAM, Q_SEED, zk500_frames

    from rfsw_plan.planning.baselines import mirror_compensation, no_compensation
    from rfsw_plan.process.task import task_constant_force

    cases: dict[int, Zk500Case] = {}

    def get(k: int) -> Zk500Case:
        if k not in cases:
            task = task_constant_force(zk500_frames(k), F_SEAM, 3e-3)
            taught = no_compensation(model.robot, task, Q_SEED)
            cases[k] = Zk500Case(model, task, taught,
                                 mirror_compensation(model, task, taught.q))
        return cases[k]

    return get
