"""``rfsw-plan view PLAN_FOLDER``: build the plan's 3-D page ``plan.html`` again (and open it).

``rfsw-plan plan`` writes ``plan.html`` with the other files of the plan folder; ``view``
rebuilds it from the folder's files (the same bytes for the same plan,
:func:`rfsw_plan.planfiles.page3d.rebuild_plan_page`) and opens it in the system's browser only
when asked (``--open``).
"""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

NAME = "view"
HELP = "build a plan folder's 3-D page plan.html again (--open: show it in a browser)"


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("plan", metavar="PLAN_FOLDER", help="a folder written by rfsw-plan plan")
    parser.add_argument("-o", "--output", default=None, metavar="FILE",
                        help="write the page here instead of PLAN_FOLDER/plan.html")
    parser.add_argument("--open", action="store_true",
                        help="open the page in the system's web browser afterwards")


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.files import prepare_output_file
    from rfsw_plan.planfiles.page3d import rebuild_plan_page

    created: list[Path] = []
    if args.output is not None:  # its folder is created (``-o out/view/plan.html``, issue 39)
        created = _missing_folders(Path(args.output).parent)
        prepare_output_file(args.output, "-o")
    try:
        res = rebuild_plan_page(args.plan, args.output)
    except BaseException:  # a damaged plan writes nothing: the folders made for -o go again
        for folder in created:  # deepest first; one that got an entry meanwhile stays
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    state = "written" if res.changed else "up to date (same bytes)"
    print(f"{res.path}: {state}, {res.size / 1e6:.2f} MB; open it in a browser "
          f"(file://, no server needed)")
    if args.open:
        import webbrowser

        webbrowser.open(res.path.resolve().as_uri())
    return 0


def _missing_folders(folder: Path) -> list[Path]:
    """The folders of ``folder``'s path that do not exist yet, deepest first."""
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    return missing
