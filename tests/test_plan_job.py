"""The ``plan`` job (``rfsw_plan.planfiles.job``): a typed request, ``run()``, ``write(folder)``;
the CLI parses, calls it and prints, so Python users write the same folder. Its errors name
parameters, and an interrupted write into a new folder leaves nothing behind (issue 39)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.exceptions import InputError
from rfsw_plan.planfiles.folder import PlanFolder
from rfsw_plan.planfiles.job import PlanRequest

ROOT = Path(__file__).resolve().parents[1]
PROBLEM = "zk500_table6_seam"


def test_the_job_writes_the_folder_the_cli_writes(tmp_path, monkeypatch) -> None:
    """``PlanRequest(...).run().write(folder)`` and ``rfsw-plan plan`` give the same
    ``waypoints.csv`` and a ``plan.json`` that vouches for every file beside it."""
    import pickle

    import rfsw_plan.planning.api as api

    real, made = api.plan, {}

    def once(*args, **kwargs):
        # the same arguments are planned once (planning is deterministic): this is about what
        # the job and the command write, and that the command asks for the job's plan
        key = pickle.dumps((args, kwargs))
        if key not in made:
            made[key] = real(*args, **kwargs)
        return made[key]

    monkeypatch.setattr(api, "plan", once)
    written = PlanRequest(PROBLEM, overrides={"max_iter": 200}).run().write(tmp_path / "job")
    assert written.files[-1] == tmp_path / "job" / "plan.json"
    rec = PlanFolder.open(tmp_path / "job").record
    assert {"waypoints.csv", "plan.html"} <= set(rec["sha256"])
    assert main(["-q", "plan", PROBLEM, "-o", str(tmp_path / "cli"), "--set", "max_iter=200"]) == 0
    assert len(made) == 1  # the command planned what the job planned: the same request
    assert ((tmp_path / "job" / "waypoints.csv").read_bytes()
            == (tmp_path / "cli" / "waypoints.csv").read_bytes())


@pytest.mark.parametrize(("kwargs", "source", "flag"), [
    ({"forces_frame": "base"}, "forces_frame", "--forces-frame"),
    ({"overrides": {"w_stifness": 1}}, "overrides", "--set"),
    ({"spacing": -1.0}, "spacing", "--spacing-mm"),
    ({"force_uncertainty": float("nan")}, "force_uncertainty", "--force-uncertainty"),
])
def test_job_errors_name_the_parameter_and_the_cli_maps_it(kwargs, source, flag) -> None:
    """A bad request is refused before any planning, naming the parameter; the CLI's table
    turns it into the flag (``cli/params.py``)."""
    from rfsw_plan.cli.params import as_flag_error

    with pytest.raises(InputError) as info:
        PlanRequest(PROBLEM, **kwargs).prepare()
    assert info.value.source == source
    assert "--" not in str(info.value)
    assert str(as_flag_error(info.value)).startswith(flag)


# The child plans into a folder that does not exist yet and sends itself SIGTERM while the
# plots are drawn: after plan.json has committed waypoints.csv and plan.html, with a plot
# written, before plan.json is rewritten for the plots.
CHILD = r"""
import os, signal, sys, time
import rfsw_plan.files as files
from rfsw_plan.cli.main import main

orig_commit = files._commit_file
def commit(src, dst, anonymous):
    out = orig_commit(src, dst, anonymous)
    if str(dst).endswith("lateral_error.png"):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(5)
    return out
files._commit_file = commit
sys.exit(main(["-q", "plan", sys.argv[1], "-o", sys.argv[2]]))
"""


def test_sigterm_while_plotting_into_a_new_folder_leaves_nothing(tmp_path,
                                                                 child_stored_plan) -> None:
    """Issue 39: a SIGTERM during ``plan`` into a new folder left waypoints.csv, plan.html and
    a plot without plan.json. Now the run ends with exit 130 and the folder it created is
    gone with everything in it."""
    out = tmp_path / "new" / "plan"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    # the child's plan is the session's (conftest: child_stored_plan): this is about plotting
    proc = subprocess.run([sys.executable, "-c", child_stored_plan(PROBLEM) + CHILD, PROBLEM,
                           str(out)], env=env,
                          capture_output=True, timeout=300)
    assert proc.returncode == 130, proc.stderr.decode()
    assert b"Traceback" not in proc.stderr
    assert not (tmp_path / "new").exists(), sorted(p.name for p in out.iterdir())


def test_sigterm_while_plotting_into_a_kept_folder_keeps_the_committed_plan(
        tmp_path, child_stored_plan) -> None:
    """The same SIGTERM into a folder that held files is the committed plan: plan.json vouches
    for the data files (plots pending), and the folder passes the strict reader."""
    out = tmp_path / "plan"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    # the child's plan is the session's (conftest: child_stored_plan): this is about plotting
    proc = subprocess.run([sys.executable, "-c", child_stored_plan(PROBLEM) + CHILD, PROBLEM,
                           str(out)], env=env,
                          capture_output=True, timeout=300)
    assert proc.returncode == 130, proc.stderr.decode()
    assert (out / "notes.txt").read_text() == "mine\n"
    rec = PlanFolder.open(out).record
    assert rec["plots"] == {"pending": ["lateral_error.png", "lateral_error_time.png",
                                        "tradeoff.png"]}
