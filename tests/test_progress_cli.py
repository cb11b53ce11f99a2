"""Progress bars: on stderr only when it is a terminal and without --quiet; --json stdout
stays one clean JSON object."""

from __future__ import annotations

import fcntl
import json
import os
import pickle
import pty
import select
import struct
import subprocess
import sys
import tempfile
import termios
from pathlib import Path
from typing import Any

import pytest

from rfsw_plan.io.measurements import write_measurements
from rfsw_plan.validation.campaign.simulation import run_campaign

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    c = run_campaign("zk500", hidden=["payload_gravity=m:150"], poses=12, loads_per_pose=4,
                     noise_mm=0.01, seed=1)
    return write_measurements(tmp_path_factory.mktemp("c") / "campaign.csv", c.data)


def _run(args: list[str], tty: bool, stored: Path | None = None) -> tuple[int, str, str]:
    """Run the CLI with stdout a pipe and stderr a pseudo-terminal (``tty``) or a pipe.
    ``stored``: a folder of ``PROBLEM.plan.pickle`` files, the session's plans, which the child
    returns instead of planning a bundled problem again (``tests/_child_site/sitecustomize.py``)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if stored is not None:
        env.update(RFSW_TEST_STORED_PLANS=str(stored),
                   PYTHONPATH=f"{Path(__file__).parent / '_child_site'}{os.pathsep}{ROOT}")
    cmd = [sys.executable, "-m", "rfsw_plan.cli.main", *args]
    if not tty:
        p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
        return p.returncode, p.stdout, p.stderr
    master, slave = pty.openpty()
    # A terminal 100 columns wide (a fresh pty is 0 x 0, and tqdm draws nothing in 0 columns).
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    with tempfile.TemporaryFile() as out_file:  # a file, not a pipe: never blocks the child
        proc = subprocess.Popen(cmd, stdout=out_file, stderr=slave, env=env)
        os.close(slave)
        err = _drain(master, proc)
        proc.wait(timeout=600)
        os.close(master)
        out_file.seek(0)
        out = out_file.read()
    return proc.returncode, out.decode(), err.decode(errors="replace")


def _drain(master: int, proc: subprocess.Popen[bytes]) -> bytes:
    """Everything the child writes to the terminal until it exits."""
    err = b""
    while True:
        r, _, _ = select.select([master], [], [], 1.0)
        if r:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # the child closed the terminal
                break
            if not chunk:
                break
            err += chunk
        elif proc.poll() is not None:
            break
    return err


def _validate(campaign: Path, tmp_path: Path, *flags: str) -> list[str]:
    return [*flags, "validate", "--robot", "zk500", "--data", str(campaign), "--json",
            "--no-report", "--folds", "3"]


def test_validate_bar_on_a_terminal_and_json_stays_clean(campaign: Path,
                                                         tmp_path: Path) -> None:
    rc, out, err = _run(_validate(campaign, tmp_path), tty=True)
    assert rc == 0, err
    assert "diagnosis: candidates" in err        # the bar was drawn, on stderr
    assert json.loads(out)["verdict"] == "missing"  # stdout is exactly one JSON object


def test_no_bar_with_quiet_or_without_a_terminal(campaign: Path, tmp_path: Path) -> None:
    rc, out, err = _run(_validate(campaign, tmp_path, "-q"), tty=True)
    assert rc == 0 and "candidates" not in err
    json.loads(out)
    # -q after the subcommand works the same as before it
    rc, out, err = _run([*_validate(campaign, tmp_path), "-q"], tty=True)
    assert rc == 0 and "candidates" not in err, err
    json.loads(out)
    rc, out, err = _run(_validate(campaign, tmp_path), tty=False)
    assert rc == 0 and "candidates" not in err and "it/s" not in err
    json.loads(out)


def test_compare_bar_counts_welds(tmp_path: Path) -> None:
    sys.path.insert(0, str(ROOT / "examples"))
    try:
        import plan_my_seam
    finally:
        sys.path.pop(0)
    problem = plan_my_seam.write_problem(tmp_path)
    rc, out, err = _run(["compare", str(problem), "--strategies", "none", "realtime_seed000",
                         "--json", "--no-plot", "-o", str(tmp_path / "cmp")], tty=True)
    assert rc == 0, err
    assert "compare" in err and "weld" in err
    assert json.loads(out)["problem"] == "my_weld"


def test_plan_stage_bar_and_quiet_after_the_subcommand(tmp_path: Path,
                                                      planned_result: Any) -> None:
    problem = str(ROOT / "problems" / "zk500_table6_seam.toml")
    rc, out, err = _run(["plan", problem, "-o", str(tmp_path / "a"), "--json"], tty=True)
    assert rc == 0, err
    assert "plan: branches" in err and "plan: NLP" in err  # the stage bar, on stderr
    assert "plan: plots" in err  # writing and plotting after the planner has its own bar
    json.loads(out)
    # -q after the subcommand: no bar at all, the writing's and plotting's included (drawn
    # above without -q). The plan is the session's (the planner's stages ran above; -q is the
    # same switch for every bar): the child does not plan the problem again.
    stored = tmp_path / "stored"
    stored.mkdir()
    (stored / "zk500_table6_seam.plan.pickle").write_bytes(
        pickle.dumps(planned_result("zk500_table6_seam")))
    rc, out, err = _run(["plan", problem, "-o", str(tmp_path / "b"), "--json", "-q"], tty=True,
                        stored=stored)
    assert rc == 0 and "plan: NLP" not in err and "plan: branches" not in err
    assert "plan: files" not in err and "plan: plots" not in err, err
    assert json.loads(out)["problem"] == "zk500_table6_seam"


def test_validate_stages_from_the_first_step_to_the_report(campaign: Path,
                                                          tmp_path: Path) -> None:
    rc, out, err = _run(["validate", "--robot", "zk500", "--data", str(campaign), "--folds", "3",
                         "-o", str(tmp_path / "v")], tty=True)
    assert rc == 0, err
    for stage in ("validate: reading the data", "validate: diagnosis",
                  "validate: plots and report"):
        assert stage in err, stage
    assert "verdict: missing" in out and "validate:" not in out


def test_deviation_stages(tmp_path: Path) -> None:
    rc, out, err = _run(["deviation", "zk500_table6_seam", "--cosim", "-o", str(tmp_path / "d"),
                         "--json"], tty=True)
    assert rc == 0, err
    assert "deviation: co-simulation" in err and "deviation: files and plot" in err
    json.loads(out)


def test_stages_are_named_in_order() -> None:
    from rfsw_plan import progress

    with progress.Stages("cmd", ("a", "b", "c")) as st:
        st.start("c")  # a stage may be skipped
        with pytest.raises(ValueError):
            st.start("b")  # but never gone back to
        with pytest.raises(ValueError):
            st.start("nope")
    with pytest.raises(ValueError):
        progress.Stages("cmd", ())
