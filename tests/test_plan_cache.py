"""The planner's CasADi caches change nothing but the time (issue 41).

The point functions run compiled to C: with the compiler's optimisation from 200 waypoints on
or wherever that library is already compiled, else without while that library is built in the
background (``nlp.compile_level``); the slow tests compile afresh and compare with the disk
cache, and every level with CasADi's virtual machine.

The point functions, the NLP evaluation, the IPOPT solvers and the mapped functions are built
once per problem structure and kept in memory (``planning/nlp.py``); the point functions are
compiled to C once and kept on disk (``planning/casadi_.py``, ``$RFSW_PLAN_CACHE``). A plan
made with every cache warm and one made after emptying them are the same bytes. So is a plan
the tests read from their plan store (``tests/_plan_store.py``) and a fresh one."""

from __future__ import annotations

import os
import subprocess
import sys
from collections import OrderedDict
from pathlib import Path

import pytest

from rfsw_plan.planfiles.job import PlanRequest, PlanRun
from rfsw_plan.planfiles.waypoints import write_waypoints_csv
from rfsw_plan.planning import api
from rfsw_plan.planning import nlp as nlp_module

ROOT = Path(__file__).resolve().parents[1]
PROBLEM = "zk500_table6_seam"
CACHES = ("_POINT_CACHE", "_SOLVER_CACHE", "_EVAL_CACHE", "_INFO_MAPS")


def _csv(tmp: Path, name: str) -> bytes:
    return write_waypoints_csv(tmp / f"{name}.csv", api.plan(PROBLEM)).read_bytes()


def test_a_plan_with_warm_caches_is_the_plan_with_empty_ones(tmp_path, monkeypatch) -> None:
    """Warm caches (a second plan in one process) give the bytes of a plan after every
    in-memory cache was emptied (the functions and solvers rebuilt)."""
    warm = _csv(tmp_path, "first")  # fills the caches if they were empty
    assert all(len(getattr(nlp_module, c)) for c in CACHES)
    again = _csv(tmp_path, "warm")
    for cache in CACHES:
        monkeypatch.setattr(nlp_module, cache, OrderedDict())
    cold = _csv(tmp_path, "cold")
    assert all(len(getattr(nlp_module, c)) for c in CACHES)  # rebuilt by the cold plan
    assert warm == again == cold


@pytest.fixture(scope="module")
def cold_run() -> PlanRun:
    """``PlanRequest(PROBLEM).run()`` made after every in-memory cache was emptied (the
    functions and solvers rebuilt; the caches are put back afterwards): the fresh plan the
    session's stored plan and folder are compared with."""
    with pytest.MonkeyPatch.context() as mp:
        for cache in CACHES:
            mp.setattr(nlp_module, cache, OrderedDict())
        return PlanRequest(PROBLEM).run()


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def test_the_same_problem_writes_the_same_bytes_in_another_folder(tmp_path, cold_run,
                                                                  plan_folder) -> None:
    """Every file of the plan folder (``plan.json`` with its file list and provenance, the
    CSV, the page and the plots) is the same bytes when the same problem is planned again into
    another folder with the in-memory caches emptied: nothing in it depends on where or when it
    was written (no wall times, no absolute paths of the folder or of a bundled file). The
    first folder is the session's (``plan_folder``: written in the test store, by whichever
    worker planned first, and copied here), so the tests' stored folder is a fresh plan's."""
    first = _files(plan_folder(PROBLEM, tmp_path / "a"))
    cold_run.write(tmp_path / "elsewhere" / "b")
    second = _files(tmp_path / "elsewhere" / "b")
    assert "plan.json" in first and "waypoints.csv" in first
    assert sorted(first) == sorted(second)
    assert [n for n in first if first[n] != second[n]] == []
    assert str(tmp_path) not in first["plan.json"].decode()


@pytest.mark.slow
def test_a_plan_compiled_afresh_is_the_plan_from_the_disk_cache(tmp_path) -> None:
    """At 1000 weld waypoints the point functions run as compiled C: a process with an empty
    compile cache (``$RFSW_PLAN_CACHE``: the C code generated and compiled again) writes the
    bytes of one that loads the compiled library from disk."""
    code = ("import sys\nfrom rfsw_plan.planning import api\n"
            "from rfsw_plan.process.problem import load_problem\n"
            "from rfsw_plan.planfiles.waypoints import write_waypoints_csv\n"
            f"p = load_problem({PROBLEM!r})\n"  # 1000 weld waypoints: compiled (K >= 200)
            "write_waypoints_csv(sys.argv[1], api.plan(p, spacing=p.seam.length / 999))\n")
    out = {}
    for name, cache in (("fresh", tmp_path / "cache"), ("disk", None)):
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        if cache is not None:
            env["RFSW_PLAN_CACHE"] = str(cache)
        subprocess.run([sys.executable, "-c", code, str(tmp_path / f"{name}.csv")], env=env,
                       check=True, timeout=900)
        out[name] = (tmp_path / f"{name}.csv").read_bytes()
    assert list((tmp_path / "cache").glob("rfsw_point_*.so"))  # it did compile
    assert out["fresh"] == out["disk"]


def test_the_tests_stored_plan_writes_the_bytes_of_a_fresh_plan(planned_result, cold_run,
                                                                tmp_path) -> None:
    """The test session's plan store (``tests/_plan_store.py``: each bundled plan made once for
    every xdist worker, pickled and read back) stands for a fresh plan: its data files are the
    fresh plan's bytes."""
    from rfsw_plan.planfiles.waypoints import write_plan_data

    for name in ("stored", "fresh"):
        (tmp_path / name).mkdir()
    stored = write_plan_data(tmp_path / "stored", planned_result(PROBLEM))
    fresh = write_plan_data(tmp_path / "fresh", cold_run.result)
    assert [p.name for p in stored] == [p.name for p in fresh] == ["waypoints.csv", "plan.html"]
    for s, f in zip(stored, fresh, strict=True):
        assert s.read_bytes() == f.read_bytes(), s.name


def _wait_for(path: Path, there: bool = True, timeout_s: float = 300.0) -> bool:
    """Whether ``path`` exists (``there``) or is gone within ``timeout_s``: a background
    build's library renamed into place, its build folder removed."""
    import time

    end = time.monotonic() + timeout_s
    while path.exists() != there and time.monotonic() < end:
        time.sleep(0.05)
    return path.exists() == there


def test_a_small_problem_runs_at_O0_while_its_optimised_library_is_built(tmp_path, monkeypatch
                                                                         ) -> None:
    """Below 200 waypoints a plan without the optimised library on disk runs its point
    functions compiled without optimisation (a quick compile) and leaves the optimised one
    building in the background: once it is on disk, the next plan of this process runs it.
    Other functions (the coupled law's) have a library of their own; one that another process
    is building (its build folder) is not started again."""
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.planning.casadi_ import library_path
    from rfsw_plan.process.problem import load_problem
    from rfsw_plan.robot.kinematics import load_robot

    monkeypatch.setenv("RFSW_PLAN_CACHE", str(tmp_path))
    monkeypatch.setattr(nlp_module, "_OPTIMISED", {})
    monkeypatch.setattr(nlp_module, "_POINT_CACHE", OrderedDict())
    model = ElastostaticModel(load_robot(load_problem("fanuc_butt_1700mm").robot)).physical()
    optimised = nlp_module.COMPILE_LEVELS["O1"][0]
    coupled = library_path(nlp_module.point_functions(model, "", True).library, optimised)
    coupled.with_name(coupled.name + ".building").mkdir()  # "another process builds it"
    assert nlp_module.compile_level(model, 78, True) == "O0"
    big = nlp_module.COMPILE_MIN_WAYPOINTS
    assert nlp_module.compile_level(model, big, False) == "O1"  # waited for, not yet built
    lib = library_path(nlp_module.point_functions(model, "", False).library, optimised)
    assert lib.parent == tmp_path and not lib.exists()
    assert nlp_module.compile_level(model, 78, False) == "O0"
    assert _wait_for(lib), sorted(p.name for p in tmp_path.iterdir())
    assert _wait_for(lib.with_name(lib.name + ".building"), there=False)  # its build folder removed
    assert nlp_module.compile_level(model, 78, False) == "O1"
    assert nlp_module.compile_level(model, 78, True) == "O0"  # not started: never built
    assert sorted(p.name for p in tmp_path.glob("rfsw_point_*.so")) == [lib.name]


def test_a_background_build_gives_the_library_of_the_foreground_one(tmp_path, monkeypatch
                                                                    ) -> None:
    """``compile_in_background`` builds the library ``compile_functions`` would, at its path:
    its functions give the virtual machine's numbers. Nothing is started where the library is
    there; a build folder left by a stopped build (older than ``BUILD_STALE_S``) does not stop
    a new build. A build the compiler refuses leaves a ``.failed`` mark, and no build of that
    library is started again while the mark is recent."""
    import os
    import time

    import casadi as ca
    import numpy as np

    from rfsw_plan.planning import casadi_

    monkeypatch.setenv("RFSW_PLAN_CACHE", str(tmp_path))
    x = ca.SX.sym("x", 3)
    fns = [ca.Function("rfsw_test_f", [x], [ca.sin(x) * ca.sumsqr(x) + 1 / (2 + x)])]
    so = casadi_.library_path(fns, "rfsw_test")
    build = so.with_name(so.name + ".building")
    build.mkdir()
    old = time.time() - casadi_.BUILD_STALE_S - 60
    os.utime(build, (old, old))  # a build stopped long ago
    assert casadi_.compile_in_background(fns, "rfsw_test", "-O1")
    assert _wait_for(so)
    assert _wait_for(build, there=False)
    assert not casadi_.compile_in_background(fns, "rfsw_test", "-O1")  # on disk already
    loaded = casadi_.compile_functions(fns, "rfsw_test", optimise="-O1")
    assert loaded is not None
    v = np.array([0.3, -1.2, 7.0])
    assert np.array_equal(np.asarray(loaded[0](v)), np.asarray(fns[0](v)))

    assert casadi_.compile_in_background(fns, "rfsw_bad", "--no-such-flag")
    bad = casadi_.library_path(fns, "rfsw_bad")
    assert _wait_for(bad.with_name(bad.name + ".failed"))
    assert _wait_for(bad.with_name(bad.name + ".building"), there=False)
    assert not bad.exists()
    assert not casadi_.compile_in_background(fns, "rfsw_bad", "--no-such-flag")


@pytest.mark.slow
def test_the_compiled_functions_plan_the_bytes_of_the_virtual_machine(tmp_path, monkeypatch
                                                                      ) -> None:
    """A small problem planned with its point functions compiled to C, without and with the
    compiler's optimisation, writes the bytes of the plan in CasADi's virtual machine."""
    monkeypatch.setenv("RFSW_PLAN_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(nlp_module, "_OPTIMISED", {})
    out = {}
    for name, level in (("vm", ""), ("O0", "O0"), ("O1", "O1")):
        for cache in CACHES:
            monkeypatch.setattr(nlp_module, cache, OrderedDict())
        monkeypatch.setattr(nlp_module, "compile_level", lambda *a, lv=level: lv)
        result = api.plan("fanuc_butt_1700mm", compile_c=bool(level))
        out[name] = write_waypoints_csv(tmp_path / f"{name}.csv", result).read_bytes()
    libs = sorted(p.name.split("_")[2] for p in (tmp_path / "cache").glob("rfsw_point_*.so"))
    assert len(libs) == 2 and "O0" in libs  # both compiled
    assert out["vm"] == out["O0"] == out["O1"]
