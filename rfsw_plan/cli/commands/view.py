"""``rfsw-plan view PLAN_FOLDER``: build the plan's 3-D page ``plan.html`` again (and open it).

``rfsw-plan plan`` writes ``plan.html`` with the other files of the plan folder; ``view``
rebuilds it from the folder's files (the same bytes for the same plan,
:func:`rfsw_plan.planfiles.page3d.rebuild_plan_page`) and opens it in the system's browser only
when asked (``--open``).
"""

from __future__ import annotations

import argparse

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

    if args.output is not None:  # its folder is created (``-o out/view/plan.html``, issue 39)
        prepare_output_file(args.output, "-o")
    res = rebuild_plan_page(args.plan, args.output)
    state = "written" if res.changed else "up to date (same bytes)"
    print(f"{res.path}: {state}, {res.size / 1e6:.2f} MB; open it in a browser "
          f"(file://, no server needed)")
    if args.open:
        import webbrowser

        webbrowser.open(res.path.resolve().as_uri())
    return 0
