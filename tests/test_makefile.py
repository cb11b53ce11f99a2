"""``make demo`` installs the runtime only, ``make test`` and ``make lint`` add the dev extras
(issue 24: the demo installed 61 packages, a 1.2 GB venv). Checked with ``make -n`` in a clean
folder holding the Makefile and pyproject.toml, so nothing is installed. ``.ci/run`` is run
with its installers and make replaced by recorders."""

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


def _fake_bin(folder: Path, tools: dict[str, str]) -> Path:
    folder.mkdir()
    for name, body in tools.items():
        (folder / name).write_text(f"#!/bin/bash\n{body}\n")
        (folder / name).chmod(0o755)
    for real in ("dirname", "bash"):
        (folder / real).symlink_to(shutil.which(real) or f"/usr/bin/{real}")
    return folder


@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash")
@pytest.mark.parametrize(("present", "installed"), [
    ((), ["chromium", "default-jre-headless"]),
    (("chromium",), ["default-jre-headless"]),
    (("chromium", "java"), None)])
def test_ci_installs_java_and_chromium_where_missing(tmp_path: Path, present: tuple[str, ...],
                                                     installed: list[str] | None) -> None:
    """``.ci/run`` on a clean machine installs what the browser tests (Chromium) and the ANTLR
    grammar test (Java) need from Debian's packages, so they run instead of skipping (issue
    41); then lint, docs and the tests. Run here with apt-get, id and make replaced by
    recorders, on a PATH that holds only them (and the tools named in ``present``)."""
    (tmp_path / ".ci").mkdir()
    shutil.copy(ROOT / ".ci" / "run", tmp_path / ".ci" / "run")
    log = tmp_path / "log"
    tools = {"apt-get": f'echo "apt-get $*" >> {log}', "id": "echo 0",
             "make": f'echo "make $*" >> {log}',
             **{name: "true" for name in present}}
    path = _fake_bin(tmp_path / "bin", tools)
    subprocess.run([str(path / "bash"), str(tmp_path / ".ci" / "run")], cwd=tmp_path,
                   env={"PATH": str(path)}, check=True, capture_output=True, text=True)
    lines = log.read_text().splitlines()
    installs = [ln.split()[4:] for ln in lines if ln.startswith("apt-get install")]
    assert installs == ([] if installed is None else [installed]), lines
    assert lines[-3:] == ["make lint", "make docs", "make test"]


def test_dask_is_a_dev_extra() -> None:
    """The ``place --dask`` test (tests/test_placement.py) imports dask.distributed: it is in
    the dev extras, so ``make test`` runs it instead of skipping (issue 41)."""
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"]
    assert any(d.split(">")[0].split("=")[0] == "distributed" for d in extras["dev"])


@pytest.mark.skipif(shutil.which("make") is None, reason="no make")
def test_bench_times_every_command(tmp_path: Path) -> None:
    """``make bench`` runs the command benchmark (issue 41) beside the others; the benchmark
    itself is never run in the tests (timings are not asserted)."""
    out = dry_run(tmp_path, "bench")
    assert "benchmarks/benchmark_commands.py" in out
    assert (ROOT / "benchmarks" / "benchmark_commands.py").is_file()
