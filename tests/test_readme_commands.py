"""Every command the README and the manual show runs as written.

The ```sh blocks of README.md and of every page under docs/ (and README.md's ```python
blocks) run in order, with optional ``[...]`` parts left out, in one fresh copy of the
repository (its tracked files, committed into a new git repository), from its root, as a user
who follows the pages would. After each block ``git status --porcelain`` of that copy must list
nothing: the commands write only under ``out/`` (ignored), never into the tree.

A block followed by a ```text title="output"``` block quotes its real output: every line of it
(blanks collapsed) must appear in the block's stdout and stderr, in that order and adjacent,
where a line ``...`` stands for any number of lines and ``...`` inside a line for any text (a
time, a machine's path). So a number quoted in the pages is a number the command
prints today.

Cheap blocks run in the default suite, the slow ones under ``-m slow`` (SLOW, and every block
that reads the real measurement data in ``../shared/``); blocks that
cannot run here are in NOT_RUN with the reason; a block that reads what another block writes
names it in NEEDS, which runs first when its output is not there yet. Keys are the first
command line of a block (up to 60 characters, comments removed).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Pages whose commands run: the README and every Markdown page of the manual.
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")))

#: Blocks (by their first line) not run here, and why.
NOT_RUN = {
    "make demo": "make creates and reinstalls .venv (checked by CI's `make test`)",
    "make lint": "make targets reinstall the shared .venv (CI runs them)",
}
#: Blocks too slow for the default run (tens of seconds or more each on a loaded machine).
SLOW = (
    "rfsw-plan validate --robot zk500 --data out/campaign.csv",
    "rfsw-plan compare zk500_table6_seam",
    "rfsw-plan map",
    "python examples/paper_checks.py",
    "python examples/trial_weld_loop.py",
    "rfsw-plan plan zk500_table6_seam -o out/plan1",
    "rfsw-plan place",
    "rfsw-plan plan kr600_curved_seam",
)
#: Blocks that read what another block writes: that one (key prefix), and a file it writes.
NEEDS = {
    "rfsw-plan validate --robot zk500 --data out/campaign.csv":
        ("rfsw-plan simulate-campaign --robot zk500 --hidden payload_gravity", "out/campaign.csv"),
    "rfsw-plan validate --robot out/fanuc_fitted.toml":
        ("rfsw-plan calibrate --robot fanuc_r2000ic_165f", "out/fanuc_fitted.toml"),
}

_BLOCK = re.compile(r"^```(sh|python)\n(.*?)^```\n(?:\n```text title=\"output\"\n(.*?)^```)?",
                    re.M | re.S)


@dataclass(frozen=True)
class Block:
    """One runnable block of a page."""

    page: str  #: path relative to the repository root
    lang: str  #: "sh" or "python"
    code: str
    output: str | None  #: the quoted output, if the page quotes it

    @property
    def key(self) -> str:
        return _key(self.code)


def _key(code: str) -> str:
    first = next((ln for ln in code.splitlines() if ln.strip() and not ln.startswith("#")), "")
    return first.split("#")[0].strip()[:60]


def page_blocks(path: Path) -> list[Block]:
    """The runnable blocks of one page, in order (``python`` blocks of README.md only: the
    manual's Python snippets may be fragments)."""
    rel = path.relative_to(ROOT).as_posix()
    return [Block(rel, m[1], m[2], m[3]) for m in _BLOCK.finditer(path.read_text())
            if m[1] == "sh" or rel == "README.md"]


def all_blocks() -> list[Block]:
    return [b for p in PAGES for b in page_blocks(p)]


def as_written(block: str) -> str:
    """The block with continuation lines joined and optional ``[...]`` groups removed."""
    text = block.replace("\\\n", " ")
    prev = None
    while prev != text:
        prev = text
        text = re.sub(r"\s*\[[^\[\]\n]*\]", "", text)
    return text


def output_matches(quoted: str, actual: str) -> str | None:
    """None if every quoted line appears in ``actual`` in order, else the first quoted line not
    found. A line ``...`` stands for any lines, ``...`` inside a line for any text (a time, a
    path); runs of blanks are collapsed, blank lines and trailing blanks ignored."""
    def norm(s: str) -> str:
        return " ".join(s.split())

    def same(q: str, line: str) -> bool:
        if "..." not in q:
            return q == line
        return re.fullmatch(".*".join(re.escape(p) for p in q.split("...")), line) is not None

    lines = [norm(ln) for ln in actual.splitlines() if ln.strip()]
    pos = 0
    gap = True  # the first quoted line may come after any lines
    for q in (norm(x) for x in quoted.splitlines()):
        if q == "...":
            gap = True
            continue
        if not q:
            continue
        found = next((i for i in range(pos, len(lines) if gap else min(pos + 1, len(lines)))
                      if same(q, lines[i])), None)
        if found is None:
            return q
        pos, gap = found + 1, False
    return None


def _listed(key: str, names: object) -> bool:
    return any(key.startswith(n) for n in names)  # type: ignore[attr-defined]


def _cases() -> list[object]:
    """One test per block; a block that runs the same commands as another (the tour is on the
    README and on the manual's home page) runs once, with every output quoted for it."""
    out: list[object] = []
    seen: set[tuple[str, str | None]] = set()
    blocks = all_blocks()
    for b in blocks:
        same = [o for o in blocks if as_written(o.code) == as_written(b.code)]
        if (as_written(b.code), b.output) in seen or (
                b.output is None and any(o.output is not None for o in same)):
            continue
        seen.add((as_written(b.code), b.output))
        if _listed(b.key, NOT_RUN):
            continue
        slow = _listed(b.key, SLOW) or "../shared/" in b.code  # real data: large files
        marks = [pytest.mark.slow] if slow else []
        out.append(pytest.param(b, id=f"{b.page}:{b.key[:40]}", marks=marks))
    return out


@pytest.fixture(scope="module")
def fresh_copy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The repository's tracked files (as they are in the work tree) committed into a new git
    repository, with ../shared beside it when it is beside this one."""
    base = tmp_path_factory.mktemp("clone")
    work = base / "repo"
    files = subprocess.run(["git", "ls-files", "-z", "--cached", "--others",
                            "--exclude-standard"], cwd=ROOT, capture_output=True, check=True,
                           text=True).stdout.split("\0")
    for f in filter(None, files):
        src = ROOT / f
        if src.is_file():
            (work / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, work / f)
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false"]
    subprocess.run([*git, "init", "-q"], cwd=work, check=True)
    subprocess.run([*git, "add", "-A"], cwd=work, check=True)
    subprocess.run([*git, "commit", "-q", "-m", "fresh copy"], cwd=work, check=True)
    if (ROOT.parent / "shared").exists():
        (base / "shared").symlink_to((ROOT.parent / "shared").resolve())
    return work


def _run(block: Block, cwd: Path) -> str:
    """Run one block in ``cwd``; its stdout and stderr, merged."""
    env = {**os.environ, "PYTHONPATH": str(cwd),
           "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    if block.lang == "python":
        cmd = [sys.executable, "-c", block.code]
    else:
        cmd = ["bash", "-c", "set -e\nexec 2>&1\n" + as_written(block.code)]
    p = subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, text=True, timeout=1800)
    assert p.returncode == 0, f"{block.page}: {as_written(block.code)}\n{p.stdout[-3000:]}"
    return p.stdout


def test_every_block_is_run_or_listed() -> None:
    keys = [b.key for b in all_blocks()]
    assert len(keys) >= 8
    for table in (NOT_RUN, SLOW, NEEDS):
        for n in table:
            assert any(k.startswith(n) for k in keys), f"stale entry {n!r}"
    for need, _ in NEEDS.values():
        assert any(b.code.startswith(need) for b in all_blocks()), f"NEEDS names no block {need!r}"


def test_optional_parts_are_removed() -> None:
    text = as_written("a x [--b 1] [--c NAME[=k:v,...] ...] \\\n    -o y [--json]")
    assert text.split() == ["a", "x", "-o", "y"]


def test_output_is_matched_in_order() -> None:
    actual = "warning: w\nA: 1\nrobot from /x\ntable  1  2\n\nlast\n"
    assert output_matches("A: 1\n...\ntable 1 2", actual) is None
    assert output_matches("A: 1\ntable 1 2", actual) == "table 1 2"  # no ... : adjacent
    assert output_matches("table  1  2\n...\nA: 1", actual) == "A: 1"  # order kept
    assert output_matches("A: 2", actual) == "A: 2"
    assert output_matches("table 1 2\n\nlast", actual) is None  # blank lines do not count
    assert output_matches("robot from ...\ntable 1 ...", actual) is None  # text elided
    assert output_matches("robot ... /y", actual) == "robot ... /y"


def test_readme_stays_short_and_lists_every_folder() -> None:
    """README.md is the front door (<= 250 lines), and its layout names every package folder."""
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 250
    layout = text.split("## Layout", 1)[1]
    for d in sorted(p.name for p in (ROOT / "rfsw_plan").iterdir()
                    if p.is_dir() and (p / "__init__.py").exists()):
        assert f"  {d}/" in layout, f"README layout does not list rfsw_plan/{d}/"


@pytest.mark.parametrize("block", _cases())
def test_block_runs(block: Block, fresh_copy: Path) -> None:
    if "../shared/" in block.code and not (fresh_copy.parent / "shared").exists():
        pytest.skip("../shared (the real measurement data) is not beside the repository")
    need = next((v for k, v in NEEDS.items() if block.key.startswith(k)), None)
    if need and not (fresh_copy / need[1]).exists():
        _run(next(b for b in all_blocks() if b.code.startswith(need[0])), fresh_copy)
    out = _run(block, fresh_copy)
    if block.output is not None:
        missing = output_matches(block.output, out)
        assert missing is None, (f"{block.page}: the quoted output line {missing!r} is not "
                                 f"what `{block.key}` prints:\n{out[-3000:]}")
    status = subprocess.run(["git", "status", "--porcelain"], cwd=fresh_copy,
                            capture_output=True, text=True, check=True).stdout
    assert status == "", f"{block.page}: `{block.key}` left files outside out/:\n{status}"
