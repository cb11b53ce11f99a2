"""The numbers the manual's prose quotes are the numbers its quoted outputs show (issue 39).

A quoted output (```text title="output"``` after its ```sh block) is re-measured by
``tests/test_readme_commands.py`` (the slow blocks under ``-m slow``; ``RFSW_REQUOTE=1``
re-quotes it). The prose around it quoted numbers of its own that went stale ("offline
83.0 %" beside its table's 88.2 %, "two plots" where ``plan`` writes three and a page, "within
0.1 %" where ``kr600_curved_seam`` prints 2.91 %): here each prose number is read from the page
and compared with the quoted output it comes from, or with the code that decides it. Every
picture of the manual is marked illustrative and names the test that makes it.
"""

from __future__ import annotations

import re
from pathlib import Path

from test_readme_commands import Block, page_blocks

from rfsw_plan.planfiles.waypoints import PLAN_PLOTS

ROOT = Path(__file__).resolve().parents[1]
GUIDE = ROOT / "docs" / "guide"


def quoted(page: Path, command: str) -> Block:
    """The block of ``page`` whose first command starts with ``command``, with its output."""
    blocks = [b for b in page_blocks(page) if b.key.startswith(command)]
    assert len(blocks) == 1 and blocks[0].output, (page, command)
    return blocks[0]


def prose(page: Path) -> str:
    """The page without its fenced blocks, lines joined (a sentence may wrap)."""
    text = re.sub(r"^```.*?^```\n", "", page.read_text(), flags=re.M | re.S)
    return " ".join(text.split())


def test_deviation_prose_is_its_own_table() -> None:
    page = GUIDE / "deviation.md"
    out = quoted(page, "rfsw-plan compare zk500_table6_seam").output or ""
    section = out.split("hidden_tilting_compliance", 1)[1].split("noise_x3", 1)[0]
    inside = {m[1]: m[2] for m in re.finditer(r"^\s*(\w+)\s+([\d.]+)\s", section, re.M)}
    m = re.search(r"With a hidden tilting compliance the hybrid stays at ([\d.]+) % "
                  r"\(offline ([\d.]+) %\)", prose(page))
    assert m, "deviation.md no longer quotes the hidden-compliance rerun"
    assert (float(m[1]), float(m[2])) == (float(inside["hybrid"]), float(inside["offline"])), (
        m.groups(), inside)


def test_planning_lists_the_files_plan_writes() -> None:
    """The files planning.md says ``plan -o`` writes are the plots the code draws
    (:data:`PLAN_PLOTS`, each checked against a real plan by test_plan_cli.py), the data files
    and the page, and the files the quoted ``plan kr600_curved_seam`` output lists."""
    page = GUIDE / "planning.md"
    m = re.search(r"The plan goes into `-o DIR` \(default `out/<problem>`\): (.*?), described",
                  prose(page))
    assert m, "planning.md no longer says what plan writes"
    named = re.findall(r"`([\w.]+\.\w+)`", m[1])
    count = {"two": 2, "three": 3, "four": 4}[re.search(r"(\w+) plots", m[1])[1]]
    plots = [n for n in named if n.endswith(".png")]
    assert count == len(plots) and sorted(plots) == sorted(PLAN_PLOTS), m[1]
    assert sorted(named) == sorted(["waypoints.csv", "plan.json", "plan.html", *PLAN_PLOTS])
    out = quoted(page, "rfsw-plan plan kr600_curved_seam -o").output or ""
    wrote = re.search(r"wrote (\d+) files in (\S+):\n((?:  \S+\n)+)", out)
    assert wrote, "the quoted kr600 output no longer lists the files"
    listed = [Path(ln.strip()).name for ln in wrote[3].splitlines()]
    assert int(wrote[1]) == len(listed) and sorted(listed) == sorted(named)


def test_planning_pin_speed_is_the_quoted_figure() -> None:
    page = GUIDE / "planning.md"
    m = re.search(r"the commanded speed within the weld envelope's tolerance of ([\d.]+) %, "
                  r"the start ramp included: `plan` prints the figure, ([\d.]+) % on "
                  r"`kr600_curved_seam`",
                  prose(page))
    assert m, "planning.md no longer states the pin speed"
    out = quoted(page, "rfsw-plan plan kr600_curved_seam -o").output or ""
    got = re.search(r"pin speed off the commanded by at most ([\d.]+) % of the weld speed, the "
                    r"acceleration included \(tolerance ([\d.]+) %\)", out)
    assert got, "the quoted kr600 output no longer shows the weld envelope line"
    assert (m[2], m[1]) == (got[1], got[2])
    assert float(got[1]) <= float(got[2])


def test_every_picture_is_marked_illustrative_and_names_its_test() -> None:
    """A screenshot shows the plan of the day it was taken (the manual's plan3d pictures showed
    a worst sample the page no longer shows): each picture is preceded by
    ``<!-- illustrative: ... -->`` naming the test that makes it, and that test writes it."""
    bad = []
    for page in sorted((ROOT / "docs").rglob("*.md")):
        text = page.read_text()
        for m in re.finditer(r"^!\[[^\]]*\]\(([^)]+\.png)\)", text, re.M):
            before = text[:m.start()].rstrip().rsplit("\n", 1)[-1]
            mark = re.fullmatch(r"<!-- illustrative: .*?(tests/test_\w+\.py).* -->", before)
            image = Path(m[1]).name
            if mark is None:
                bad.append(f"{page.relative_to(ROOT)}: {image} not marked illustrative")
                continue
            test = (ROOT / mark[1]).read_text()
            stem = image.removesuffix(".png").replace("zk500_table6_seam", "{PROBLEM}")
            if stem not in test or "RFSW_UPDATE_SCREENSHOT" not in test:
                bad.append(f"{page.relative_to(ROOT)}: {mark[1]} does not write {image}")
    assert not bad, "\n".join(bad)


def test_calibrate_page_warns_of_its_run_time() -> None:
    """``calibrate`` on the FANUC example ran for minutes with no word of it on its page
    (issue 39): the step that runs it says how long it takes, before the command."""
    text = (GUIDE / "calibrate.md").read_text()
    step = text.split("## 4. Calibrate", 1)[1].split("```sh", 1)[0]
    assert re.search(r"takes (about )?[\w\d .,]*\b(s|min|minutes?|seconds?)\b", step), step
