"""``make demo`` installs the runtime only, ``make test`` and ``make lint`` add the dev extras
(issue 24: the demo installed 61 packages, a 1.2 GB venv). Checked with ``make -n`` in a clean
folder holding the Makefile and pyproject.toml, so nothing is installed."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def dry_run(tmp: Path, target: str) -> str:
    for f in ("Makefile", "pyproject.toml"):
        shutil.copy(ROOT / f, tmp / f)
    # --no-print-directory: under `make test` (CI) this make is a sub-make and would print
    # "make[1]: Entering/Leaving directory" lines around the commands
    proc = subprocess.run(["make", "--no-print-directory", "-n", target], cwd=tmp,
                          capture_output=True, text=True, check=True)
    return proc.stdout


@pytest.mark.skipif(shutil.which("make") is None, reason="no make")
def test_demo_installs_the_runtime_only_and_test_adds_dev(tmp_path: Path) -> None:
    demo = dry_run(tmp_path, "demo")
    assert "pip install -q -e . >>" in demo and "[dev]" not in demo
    assert "rfsw-plan plan" in demo
    for target in ("test", "lint"):
        out = dry_run(tmp_path, target)
        assert "-e '.[dev]'" in out, target
        assert out.index("-e . >>") < out.index("-e '.[dev]'")


@pytest.mark.skipif(shutil.which("make") is None, reason="no make")
def test_first_demo_shows_the_verdict_not_pip(tmp_path: Path) -> None:
    """``make demo``'s first run printed pip's progress bars and hundreds of lines before the
    plan's verdict (issue 33, wall 10): every install is quiet, into .venv/install.log (shown
    when it fails), and the plan is the last command, so its verdict is the output."""
    demo = dry_run(tmp_path, "demo")
    commands = [ln for ln in demo.splitlines() if ln.strip() and not ln.startswith("echo")]
    pips = [ln for ln in commands if "pip install" in ln]
    assert len(pips) >= 2
    for ln in pips:
        assert " -q " in ln and "install.log 2>&1" in ln and "--progress-bar on" not in ln, ln
        assert "tail -n 40 .venv/install.log" in ln, ln  # a failed install shows its log
    assert "rfsw-plan plan" in commands[-1]


@pytest.mark.skipif(shutil.which("make") is None, reason="no make")
def test_docs_after_demo_adds_the_dev_extras(tmp_path: Path) -> None:
    """``make docs`` after ``make demo`` failed with ``.venv/bin/mkdocs: not found`` (issue 39):
    docs depended on the runtime stamp only, and mkdocs is a dev extra. With the runtime
    stamp in place (as ``make demo`` leaves it), ``make docs`` first installs the dev extras,
    then builds."""
    for f in ("Makefile", "pyproject.toml"):
        shutil.copy(ROOT / f, tmp_path / f)
    (tmp_path / ".venv").mkdir()
    (tmp_path / ".venv" / ".installed").touch()  # newer than pyproject.toml: demo is done
    out = subprocess.run(["make", "--no-print-directory", "-n", "docs"], cwd=tmp_path,
                         capture_output=True, text=True, check=True).stdout
    assert "python3 -m venv" not in out  # the runtime is not installed again
    assert "-e '.[dev]'" in out
    assert out.index("-e '.[dev]'") < out.index("mkdocs build")
