"""The README's ```sh blocks run as written, in a fresh folder, with optional ``[...]`` parts
left out. Cheap blocks run in the default suite, the slow ones under ``-m slow``; the blocks
that cannot run here are listed in NOT_RUN with the reason."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def readme_blocks() -> list[str]:
    """The ```sh blocks of README.md, in order."""
    return re.findall(r"^```sh\n(.*?)^```", (ROOT / "README.md").read_text(), re.M | re.S)


def as_written(block: str) -> str:
    """The block with continuation lines joined and optional ``[...]`` groups removed."""
    text = block.replace("\\\n", " ")
    prev = None
    while prev != text:
        prev = text
        text = re.sub(r"\s*\[[^\[\]\n]*\]", "", text)
    return text


def _key(block: str) -> str:
    return block.strip().splitlines()[0].split("#")[0].strip()[:60]


#: Blocks (by their first line) not run here, and why.
NOT_RUN = {
    "make demo": "make creates and reinstalls .venv (checked by CI's `make test`)",
    "make lint": "make targets reinstall the shared .venv",
    "rfsw-plan plan zk500_table6_seam -o plan1": "needs trial_track.csv from a real weld "
    "(examples/trial_weld_loop.py runs the same loop on a virtual weld)",
}
#: Blocks too slow for the default run (tens of seconds each on a loaded machine).
SLOW = ("rfsw-plan validate --robot zk500 --data campaign.csv", "D=../shared/data/figaroh_tiago",
        "rfsw-plan compare zk500_table6_seam")
#: Files a block reads that an earlier block writes: run that block first.
NEEDS = {"rfsw-plan validate --robot zk500 --data campaign.csv":
         "rfsw-plan simulate-campaign --robot zk500 --hidden payload_gravity"}


def _cases() -> list[object]:
    out = []
    for b in readme_blocks():
        k = _key(b)
        if any(k.startswith(n) for n in NOT_RUN):
            continue
        marks = [pytest.mark.slow] if any(k.startswith(x) for x in SLOW) else []
        out.append(pytest.param(b, id=k[:40], marks=marks))
    return out


def _run_block(block: str, cwd: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT),
           "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    script = "set -e\n" + as_written(block)
    p = subprocess.run(["bash", "-c", script], cwd=cwd, env=env, capture_output=True,
                       text=True, timeout=1800)
    assert p.returncode == 0, f"{as_written(block)}\n{p.stderr[-2000:]}"


def test_every_block_is_run_or_listed() -> None:
    keys = [_key(b) for b in readme_blocks()]
    assert len(keys) >= 8
    for n in NOT_RUN:
        assert any(k.startswith(n) for k in keys), f"stale NOT_RUN entry {n!r}"


def test_optional_parts_are_removed() -> None:
    text = as_written("a x [--b 1] [--c NAME[=k:v,...] ...] \\\n    -o y [--json]")
    assert text.split() == ["a", "x", "-o", "y"]


@pytest.mark.parametrize("block", _cases())
def test_readme_block_runs(block: str, tmp_path: Path) -> None:
    work = tmp_path / "repo"
    work.mkdir()
    (work / "examples").symlink_to(ROOT / "examples")
    if (ROOT.parent / "shared").exists():
        (tmp_path / "shared").symlink_to((ROOT.parent / "shared").resolve())
    if "../shared/" in block and not (tmp_path / "shared").exists():
        pytest.skip("../shared (the real measurement data) is not beside the repository")
    need = NEEDS.get(next((k for k in NEEDS if _key(block).startswith(k)), ""))
    if need:
        _run_block(next(b for b in readme_blocks() if b.strip().startswith(need)), work)
    _run_block(block, work)
