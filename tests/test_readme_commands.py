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

A block that plans a bundled problem it names, as its file has it, gets the session's plan of
it (``stored_plans_for``; planning is deterministic) instead of planning it again in each
block's fresh process: the command runs as written, from its parsing to what it writes and
prints.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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
    "rfsw-plan validate --robot robots/zk500.toml --data",
    "rfsw-plan deviation problems/zk500_table6_seam.toml --cosim",
)
#: Blocks that read what another block writes: that one (key prefix), and a file it writes.
NEEDS = {
    "rfsw-plan check out/plan/zk500/rfsw_zk500_table6_seam.src":
        ("rfsw-plan plan zk500_table6_seam -o out/plan/zk500 --export",
         "out/plan/zk500/rfsw_zk500_table6_seam.src"),
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


def _norm(s: str) -> str:
    return " ".join(s.split())


def _same(q: str, line: str) -> bool:
    if "..." not in q:
        return q == line
    return re.fullmatch(".*".join(re.escape(p) for p in q.split("...")), line) is not None


def output_matches(quoted: str, actual: str) -> str | None:
    """None if the quoted lines are the output, in order and adjacent, else the first quoted
    line not found. The quote is the whole output: it starts at the first line and ends at the
    last, unless it starts or ends with a line ``...``. A line ``...`` stands for any number of
    lines, ``...`` inside a line for any text (a time, a path); runs of blanks are collapsed,
    blank lines and trailing blanks ignored."""
    lines = [_norm(ln) for ln in actual.splitlines() if ln.strip()]
    quotes = [q for q in (_norm(x) for x in quoted.splitlines()) if q]
    pos = 0
    gap = False  # the first quoted line is the first line, unless the quote starts with ...
    for q in quotes:
        if q == "...":
            gap = True
            continue
        found = next((i for i in range(pos, len(lines) if gap else min(pos + 1, len(lines)))
                      if _same(q, lines[i])), None)
        if found is None:
            return q
        pos, gap = found + 1, False
    if quotes and not gap and pos < len(lines):
        return (f"(end of the quote, but the output goes on with {lines[pos]!r}; end the "
                "quote with a line ... if that is meant)")
    return None


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?"


def _elide_times(line: str) -> str:
    """A wall-clock time in an output line put into a quote becomes ``...`` (it changes)."""
    return re.sub(r"\d+(?:\.\d+)? s\b", "... s", line)


def requote(quoted: str, actual: str, max_inserted: int = 8) -> str:
    """The quote re-measured from ``actual``: each quoted line is looked for, in order, among the
    output lines with its numbers free (a line with ``...`` keeps its elisions and takes the new
    numbers; a line without takes the output line as it is); output lines the quote skipped
    without a ``...`` are put in (up to ``max_inserted``, else a ``...``), and so are the
    output's last lines if the quote did not end with ``...``. A quoted line whose shape is no
    longer in the output is kept as it is, for a person to look at (the test still fails)."""
    lines = [ln.rstrip() for ln in actual.splitlines() if ln.strip()]
    out: list[str] = []
    pos, gap = 0, False
    for q in (x.rstrip() for x in quoted.splitlines()):
        if not q.strip():
            continue
        if q.strip() == "...":
            out.append("...")
            gap = True
            continue
        parts = re.split(rf"(\.\.\.|{_NUMBER})", _norm(q))
        pattern = "".join("(.*)" if p == "..." else f"({_NUMBER})" if re.fullmatch(_NUMBER, p)
                          else re.escape(p) for p in parts)
        found = next((i for i in range(pos, len(lines))
                      if re.fullmatch(pattern, _norm(lines[i]))), None)
        if found is None:
            out.append(q)
            continue
        skipped = lines[pos:found]
        if skipped and not gap:
            out += [_elide_times(x) for x in skipped] if len(skipped) <= max_inserted else [
                "..."]
        if "..." in q:
            m = re.fullmatch(pattern, _norm(lines[found]))
            assert m is not None
            vals = iter(m.groups())
            rebuilt = []
            for p in parts:
                if p == "...":
                    next(vals)
                    rebuilt.append("...")
                elif re.fullmatch(_NUMBER, p):
                    rebuilt.append(next(vals))
                else:
                    rebuilt.append(p)
            out.append("".join(rebuilt))
        else:
            out.append(lines[found])
        pos, gap = found + 1, False
    rest = lines[pos:]
    if rest and not gap:  # the quote stopped early: a few plain lines are put in (a robot
        # added to a list); times, paths of written files or a long tail are left to "..."
        volatile = any(re.search(r"\btime\b|^\s+\S+/", ln) for ln in rest)
        out += [_elide_times(x) for x in rest] if len(rest) <= 4 and not volatile else ["..."]
    return "\n".join(out) + "\n"


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


#: The child-side hook that answers ``plan`` of a bundled problem with the session's plan.
CHILD_SITE = Path(__file__).resolve().parent / "_child_site"


@pytest.fixture(scope="module")
def stored_plans_for(tmp_path_factory: pytest.TempPathFactory, planned_result: Any):
    """``stored_plans_for(block)`` -> the environment under which the block's commands plan
    each bundled problem it names with the session's plan (``planned_result``, conftest),
    not again in each block: ``tests/_child_site/sitecustomize.py``. The command still runs
    as written, from its parsing to the files it writes and what it prints."""
    import pickle

    from rfsw_plan.process.problem import bundled_problem_names

    folder = tmp_path_factory.mktemp("stored_plans")
    names = bundled_problem_names()

    def get(block: Block) -> dict[str, str]:
        for name in names:
            path = folder / f"{name}.plan.pickle"
            if re.search(rf"\b{re.escape(name)}\b", block.code) and not path.exists():
                path.write_bytes(pickle.dumps(planned_result(name)))
        return {"RFSW_TEST_STORED_PLANS": str(folder)}

    return get


def _run(block: Block, cwd: Path, stored: dict[str, str] | None = None) -> str:
    """Run one block in ``cwd``; its stdout and stderr, merged. ``stored``: the environment
    of :func:`stored_plans_for` (the session's plans), or None (every command plans)."""
    env = {**os.environ, "PYTHONPATH": str(cwd),
           "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    if stored is not None:
        env.update(stored, PYTHONPATH=f"{CHILD_SITE}{os.pathsep}{cwd}")
    if block.lang == "python":
        cmd = [sys.executable, "-c", block.code]
    else:
        cmd = ["bash", "-c", "set -e\nexec 2>&1\n" + as_written(block.code)]
    p = subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, text=True, timeout=1800)
    assert p.returncode == 0, f"{block.page}: {as_written(block.code)}\n{p.stdout[-3000:]}"
    return p.stdout


def _requote_pages(block: Block, out: str) -> int:
    """Write ``requote(block.output, out)`` into every page that quotes this block (the tour is
    on two pages); the number of pages changed."""
    fence = f"```{block.lang}\n{block.code}```\n\n```text title=\"output\"\n"
    old, new = fence + f"{block.output}```", fence + f"{requote(block.output or '', out)}```"
    changed = 0
    for page in PAGES:
        text = page.read_text()
        if old in text:
            page.write_text(text.replace(old, new))
            changed += 1
    return changed


#: Fenced blocks that are code, not output: file contents (toml, csv, json) and the manual's
#: Python fragments. Every other block is a command (``sh``: run), a quoted output
#: (``text title="output"`` right after its ``sh`` block: compared), or marked illustrative.
_CODE = ("toml", "python", "csv", "json")
_FENCE = re.compile(r"^```([^\n]*)\n(.*?)^```\n", re.M | re.S)
_ILLUSTRATIVE = re.compile(r"<!-- illustrative: (\S[^\n]*?) -->\n*$")


def test_every_quoted_block_is_compared_or_marked_illustrative() -> None:
    """A block that shows what a command prints, or a command that is not run, is either
    compared with the real output (``text title="output"`` after its ``sh`` block, run by
    ``test_block_runs``) or preceded by ``<!-- illustrative: REASON -->`` saying why it
    cannot be (issue 33, wall 4)."""
    unmarked = []
    for page in PAGES:
        text = page.read_text()
        compared = {b.output for b in page_blocks(page) if b.output is not None}
        for m in _FENCE.finditer(text):
            info = m[1].strip()
            if info == "sh" or info in _CODE:
                continue
            if info == 'text title="output"' and m[2] in compared:
                continue
            if _ILLUSTRATIVE.search(text[:m.start()]) is None:
                line = text[:m.start()].count("\n") + 1
                unmarked.append(f"{page.relative_to(ROOT)}:{line}: ```{info} {m[2][:50]!r}")
    assert not unmarked, ("quoted blocks neither compared nor marked <!-- illustrative: "
                          "REASON -->:\n" + "\n".join(unmarked))


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
    assert output_matches("...\nA: 1\n...\ntable 1 2\n...", actual) is None
    assert output_matches("...\nA: 1\ntable 1 2\n...", actual) == "table 1 2"  # adjacent
    assert output_matches("...\ntable  1  2\n...\nA: 1", actual) == "A: 1"  # order kept
    assert output_matches("...\nA: 2\n...", actual) == "A: 2"
    assert output_matches("...\ntable 1 2\n\nlast", actual) is None  # blank lines do not count
    assert output_matches("...\nrobot from ...\ntable 1 ...\n...", actual) is None  # elided
    assert output_matches("...\nrobot ... /y\n...", actual) == "robot ... /y"


def test_a_quote_is_the_whole_output_unless_it_says_so() -> None:
    """A quote that leaves out the output's first or last lines says so with a line ``...``:
    ``robots`` quoted without its last robot passed (issue 33, wall 4)."""
    actual = "warning: w\nA: 1\nB: 2\n"
    assert output_matches("warning: w\nA: 1\nB: 2", actual) is None
    assert output_matches("A: 1\nB: 2", actual) == "A: 1"  # the first line is missing
    assert output_matches("warning: w\nA: 1", actual) is not None  # the last line is missing
    assert output_matches("...\nA: 1\n...", actual) is None


def test_requote_takes_the_new_numbers_and_keeps_the_elisions() -> None:
    actual = ("setup\nnone  3.430  2.1\noffline  0.517  0.3\nplan time 4.14 s\n"
              "zk500_seed001   new robot\n")
    quoted = "...\nnone  2.046  2.1\noffline  0.148  0.3\nplan time ... s\n"
    new = requote(quoted, actual)
    assert new == ("...\nnone  3.430  2.1\noffline  0.517  0.3\nplan time ... s\n"
                   "zk500_seed001   new robot\n")
    assert output_matches(new, actual) is None
    # A line whose shape is gone is kept for a person to look at.
    assert "gone 1" in requote("...\ngone 1\n...", actual)


def test_readme_stays_short_and_lists_every_folder() -> None:
    """README.md is the front door (<= 250 lines), and its layout names every package folder."""
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 250
    layout = text.split("## Layout", 1)[1]
    for d in sorted(p.name for p in (ROOT / "rfsw_plan").iterdir()
                    if p.is_dir() and (p / "__init__.py").exists()):
        assert f"  {d}/" in layout, f"README layout does not list rfsw_plan/{d}/"


@pytest.mark.parametrize("block", _cases())
def test_block_runs(block: Block, fresh_copy: Path, stored_plans_for: Any) -> None:
    if "../shared/" in block.code and not (fresh_copy.parent / "shared").exists():
        pytest.skip("../shared (the real measurement data) is not beside the repository")
    need = next((v for k, v in NEEDS.items() if block.key.startswith(k)), None)
    if need and not (fresh_copy / need[1]).exists():
        first = next(b for b in all_blocks() if b.code.startswith(need[0]))
        _run(first, fresh_copy, stored_plans_for(first))
    out = _run(block, fresh_copy, stored_plans_for(block))
    if block.output is not None:
        missing = output_matches(block.output, out)
        if missing is not None and os.environ.get("RFSW_REQUOTE"):
            pytest.fail(f"{block.page}: re-quoted `{block.key}` in {_requote_pages(block, out)} "
                        "page(s) from its real output; review the diff (git diff docs README.md)"
                        " and run again")
        assert missing is None, (f"{block.page}: the quoted output line {missing!r} is not "
                                 f"what `{block.key}` prints:\n{out[-3000:]}")
    status = subprocess.run(["git", "status", "--porcelain"], cwd=fresh_copy,
                            capture_output=True, text=True, check=True).stdout
    assert status == "", f"{block.page}: `{block.key}` left files outside out/:\n{status}"


#: Options of rfsw-plan that name a file or folder it writes.
_WRITE_OPTIONS = re.compile(r"(?:^|\s)(?:-o|--output|--save-robot|--save-truth)[ =](\S+)")
#: Example scripts whose positional arguments name the folder they write (after the inputs).
_EXAMPLE_OUT = re.compile(r"examples/(?:plan_my_seam|python_api|trial_weld_loop)\.py\s+(\S+)"
                          r"|examples/virtual_trial_weld\.py\s+\S+\s+(\S+)")


def _written_paths(text: str) -> list[str]:
    found = [m[1] for m in _WRITE_OPTIONS.finditer(text)]
    found += [a or b for a, b in _EXAMPLE_OUT.findall(text)]
    return [p.strip("`'\"") for p in found]


def test_documented_commands_write_only_under_out() -> None:
    """Every command a page shows, run or not (any code block and any inline command), writes
    under ``out/``, or names a placeholder the reader fills in (``DIR``, ``NEW.toml``,
    ``OUT_DIR``: upper case): never the repository's ``robots/`` or the folder it runs in
    (issue 33, wall 5)."""
    bad = []
    for page in PAGES:
        text = page.read_text().replace("\\\n", " ")
        for path in _written_paths(text):
            placeholder = re.search(r"[A-Z]{2,}", path.split(".")[0]) is not None
            if not (path.startswith("out/") or placeholder or path in ('""', "")):
                bad.append(f"{page.relative_to(ROOT)}: {path}")
    assert not bad, "documented outputs outside out/:\n" + "\n".join(bad)
