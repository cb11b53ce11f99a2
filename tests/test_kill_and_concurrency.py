"""Killed and concurrent plans never leave a lie on disk (issue 9 §4-5).

A child process plans into a folder that holds an earlier successful plan. It is killed
(SIGTERM, SIGKILL, SIGINT) at the write of ``waypoints.csv``: in the middle of its rows and
just before the rename. Afterwards the folder never holds a complete-looking truncated file,
and never the old success record beside new (or removed) data. Two writers on one folder: the
second is refused with one line while the first writes.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.planfiles.folder import PlanFolder

ROOT = Path(__file__).resolve().parents[1]
PROBLEM = "zk500_table6_seam"

# The child plans with a hook at the write: ``row`` signals itself after 200 rows of
# waypoints.csv were formatted (mid-write), ``rename`` just before the finished temporary file
# gets the name waypoints.csv, ``pause`` waits there for a flag file (concurrency test).
CHILD = r"""
import os, signal, sys, time
import rfsw_plan.files as files
import rfsw_plan.planfiles.waypoints as wp
from rfsw_plan.cli.main import main

mode, sig, flag = sys.argv[1], int(sys.argv[2]), sys.argv[3]
# A child started from a background job inherits SIGINT ignored (POSIX shells without job
# control); a user's foreground Ctrl-C reaches Python's default handler, so restore it.
signal.signal(signal.SIGINT, signal.default_int_handler)
if mode == "row":  # the header written, the rows being formatted
    orig_table = wp.table_bytes
    def table(*args, **kwargs):
        body = orig_table(*args, **kwargs)
        os.kill(os.getpid(), sig)
        time.sleep(5)
        return body
    wp.table_bytes = table
else:
    orig_commit = files._commit_file
    def commit(src, dst, anonymous):
        if str(dst).endswith("waypoints.csv"):
            if mode == "rename":
                os.kill(os.getpid(), sig)
                time.sleep(5)
            else:
                open(flag, "w").close()
                while os.path.exists(flag):
                    time.sleep(0.05)
        return orig_commit(src, dst, anonymous)
    files._commit_file = commit
sys.exit(main(["-q", "plan", sys.argv[4], "-o", sys.argv[5]]))
"""


def _child(mode: str, sig: int, flag: Path, out: Path, stored: str = ""
           ) -> subprocess.Popen[bytes]:
    """The child plans PROBLEM (``stored``: lines run first, ``child_stored_plan``)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen([sys.executable, "-c", stored + CHILD, mode, str(int(sig)), str(flag),
                             PROBLEM, str(out)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)


def _assert_honest(out: Path) -> None:
    """No complete-looking truncated file; no success record beside other data."""
    rec = json.loads((out / "plan.json").read_text())
    visible = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    if rec["status"] in ("incomplete", "infeasible", "failed"):
        assert visible == ["plan.json"], visible
    else:
        PlanFolder.open(out)  # every file it vouches for is there, byte for byte


@pytest.fixture(scope="module")
def old_plan(tmp_path_factory, plan_folder) -> Path:
    """An earlier successful plan: the session's ``rfsw-plan -q plan PROBLEM -o DIR``."""
    return plan_folder(PROBLEM, tmp_path_factory.mktemp("old") / "plan")


#: (mode, signal) killed in the default run: a hard kill mid-row and a polite one at the rename;
#: the other four pairs under ``-m slow`` (the same assertions).
_DEFAULT_KILLS = {("row", signal.SIGKILL), ("rename", signal.SIGTERM)}


@pytest.mark.parametrize(("mode", "sig"), [
    pytest.param(m, s, marks=[] if (m, s) in _DEFAULT_KILLS else [pytest.mark.slow])
    for m in ("row", "rename") for s in (signal.SIGTERM, signal.SIGKILL, signal.SIGINT)])
@pytest.mark.usefixtures("stored_plans")  # the next run's plan: the session's (conftest)
def test_killed_at_the_write_leaves_no_lie(tmp_path, old_plan, mode, sig,
                                           child_stored_plan) -> None:
    out = tmp_path / "out"
    out.mkdir()
    for p in old_plan.iterdir():  # an earlier successful plan in the folder
        (out / p.name).write_bytes(p.read_bytes())
    assert json.loads((out / "plan.json").read_text())["status"].startswith("optimal")
    proc = _child(mode, sig, tmp_path / "flag", out, child_stored_plan(PROBLEM))
    _, err = proc.communicate(timeout=300)
    assert proc.returncode != 0
    if sig != signal.SIGKILL:
        assert proc.returncode == 130, err.decode()
        assert b"Traceback" not in err
    # No temporary file and no lock file, SIGKILL included (the temporaries have no name
    # until they are complete; the lock is on the folder itself).
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".")) == []
    assert not (out / "waypoints.csv").exists()
    assert json.loads((out / "plan.json").read_text())["status"] == "incomplete"
    _assert_honest(out)
    # The next run into the folder cleans up and writes a whole, vouched plan.
    assert main(["-q", "plan", PROBLEM, "-o", str(out)]) == 0
    PlanFolder.open(out)
    assert not [p for p in out.iterdir() if ".tmp" in p.name]


def test_two_writers_on_one_folder(tmp_path, capsys, child_stored_plan) -> None:
    out = tmp_path / "out"
    flag = tmp_path / "flag"
    first = _child("pause", 0, flag, out, child_stored_plan(PROBLEM))
    t_end = time.monotonic() + 300
    while not flag.exists():  # the first writer is at its write, holding the folder
        assert first.poll() is None, first.communicate()[1].decode()
        assert time.monotonic() < t_end
        time.sleep(0.05)
    code = main(["-q", "plan", "fanuc_butt_1700mm", "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and "another rfsw-plan process" in err
    flag.unlink()
    _, err1 = first.communicate(timeout=300)
    assert first.returncode == 0, err1.decode()
    rec = PlanFolder.open(out).record
    assert rec["problem"] == PROBLEM  # one seam only, never a mix
    text = (out / "waypoints.csv").read_text()
    assert len(text.splitlines()) == rec["samples"]["n"] + 1


def test_a_plan_leaves_no_lock_and_no_temporary(old_plan) -> None:
    """Issue 24: no ``.rfsw-plan.lock`` (the lock is on the folder itself) and no hidden
    temporary in a folder after a run."""
    assert sorted(p.name for p in old_plan.iterdir() if p.name.startswith(".")) == []


def test_interrupted_plan_leaves_the_incomplete_record_alone(tmp_path, old_plan,
                                                            child_stored_plan) -> None:
    """SIGTERM after waypoints.csv has its name (during the programs' export or the commit):
    exit 130, and the data files it wrote are removed: an ``incomplete`` record alone, never a
    complete-looking waypoints.csv that nothing vouches for."""
    out = tmp_path / "out"
    out.mkdir()
    for p in old_plan.iterdir():
        (out / p.name).write_bytes(p.read_bytes())
    # The second commit of plan.json is the one that would vouch for the new waypoints.csv
    # (the first turned the old record into "incomplete"): SIGTERM just before it.
    child = CHILD.replace('if str(dst).endswith("waypoints.csv"):',
                          'seen.append(str(dst))\n        '
                          'if sum(s.endswith("plan.json") for s in seen) == 2:').replace(
        "orig_commit = files._commit_file", "orig_commit = files._commit_file\n    seen = []")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    child = child_stored_plan(PROBLEM) + child
    proc = subprocess.Popen([sys.executable, "-c", child, "rename", str(int(signal.SIGTERM)),
                             str(tmp_path / "flag"), PROBLEM, str(out)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 130, err.decode()
    names = sorted(p.name for p in out.iterdir())
    assert names == ["plan.json"], names
    assert json.loads((out / "plan.json").read_text())["status"] == "incomplete"


@pytest.mark.slow
def test_kill_campaign_sample(tmp_path) -> None:
    """A few moments of the kill campaign (tests/kill_campaign.py runs 20 per signal)."""
    from kill_campaign import campaign

    kills = campaign(2, seed=3, work=tmp_path)
    bad = [k for k in kills if not k.ok]
    assert not bad, bad


def test_a_sigterm_after_the_command_finished_keeps_its_exit_code() -> None:
    """The kill campaign once hit a finished export in the interpreter's shutdown, where the
    default SIGTERM action was back: exit -15 for a complete run. The rfsw-plan script ignores
    SIGTERM once the command has finished (here the signal is sent from an exit hook)."""
    code = ("import atexit, os, signal, sys\n"
            "atexit.register(lambda: os.kill(os.getpid(), signal.SIGTERM))\n"
            "sys.argv = ['rfsw-plan', '--version']\n"
            "from rfsw_plan.cli.main import console\n"
            "console()\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=60, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.returncode == 0, (r.returncode, r.stderr)
    assert "rfsw-plan" in r.stdout and "Traceback" not in r.stderr


def test_an_interrupt_inside_a_callback_is_noted_not_printed() -> None:
    """A SIGTERM that lands in a weakref callback (seen once in the kill campaign) reaches
    Python's unraisable hook: it is noted, so the next writer stops the run (exit 130), and
    no 'Exception ignored ... Traceback' is printed; other unraisable errors pass through."""
    from types import SimpleNamespace

    from rfsw_plan import files
    from rfsw_plan.cli.main import _interrupt_in_a_callback

    passed: list[object] = []
    hook = _interrupt_in_a_callback(passed.append)
    files.clear_interrupt()
    try:
        other = SimpleNamespace(exc_value=ValueError("x"))
        hook(other)
        assert passed == [other]
        files.check_interrupt()  # nothing noted yet
        hook(SimpleNamespace(exc_value=KeyboardInterrupt()))
        assert passed == [other]
        with pytest.raises(KeyboardInterrupt):
            files.check_interrupt()
    finally:
        files.clear_interrupt()


# Ctrl-C in a terminal while IPOPT runs (issue 33, wall 1). CasADi catches the
# KeyboardInterrupt inside IPOPT's callbacks and returns the iterate it had; the run must still
# stop with exit 130 and write nothing. The child announces each solve on stderr; the parent
# types ^C on the pseudo-terminal (the terminal driver sends SIGINT to the foreground process
# group, as a user's Ctrl-C does) shortly after, while IPOPT is inside that solve.
PTY_CHILD = r"""
import sys
import rfsw_plan.planning.nlp as nlp
orig = nlp.single_thread_blas
def announced():
    sys.stderr.write("\nIPOPT-SOLVE-STARTS\n")
    sys.stderr.flush()
    return orig()
nlp.single_thread_blas = announced
from rfsw_plan.cli.main import console
sys.argv = ["rfsw-plan", *sys.argv[1:]]
console()
"""


def _ctrl_c_in_a_terminal(argv: list[str], delay_s: float) -> tuple[int, str]:
    """Run ``rfsw-plan argv`` on a pseudo-terminal, type ^C ``delay_s`` after the first IPOPT
    solve starts; the exit code and what the terminal showed."""
    import pty
    import select

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    pid, fd = pty.fork()
    if pid == 0:  # the child: a new session whose controlling terminal is the pty
        signal.signal(signal.SIGINT, signal.SIG_DFL)  # as in a user's interactive shell
        os.execve(sys.executable, [sys.executable, "-c", PTY_CHILD, *argv], env)
    shown, sent_at, deadline = b"", None, time.monotonic() + 300
    try:
        while time.monotonic() < deadline:
            if sent_at is None and b"IPOPT-SOLVE-STARTS" in shown:
                time.sleep(delay_s)
                os.write(fd, b"\x03")
                sent_at = time.monotonic()
            ready, _, _ = select.select([fd], [], [], 0.05)
            if ready:
                try:
                    chunk = os.read(fd, 4096)
                except OSError:  # the child closed the terminal
                    break
                if not chunk:
                    break
                shown += chunk
    finally:
        _, status = os.waitpid(pid, 0)
        os.close(fd)
    assert sent_at is not None, shown.decode(errors="replace")[-2000:]
    return os.waitstatus_to_exitcode(status), shown.decode(errors="replace")


@pytest.mark.parametrize("command, delay_s", [
    (["plan", "kr600_curved_seam"], 0.3),  # its first solve takes about 1.3 s
    pytest.param(["place", PROBLEM, "--candidates", "2"], 0.02, marks=pytest.mark.slow),
])
def test_ctrl_c_in_a_terminal_stops_with_130_and_writes_nothing(tmp_path, command,
                                                                 delay_s) -> None:
    out = tmp_path / "new" / "folder"
    code, shown = _ctrl_c_in_a_terminal([*command, "-q", "-o", str(out)], delay_s)
    assert code == 130, shown[-2000:]
    assert "rfsw-plan: interrupted" in shown
    assert "wrote" not in shown and "GO" not in shown, shown[-2000:]
    assert not (tmp_path / "new").exists(), sorted(map(str, tmp_path.rglob("*")))
