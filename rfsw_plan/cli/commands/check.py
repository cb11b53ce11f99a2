"""``rfsw-plan check PROGRAM [--plan PLAN_DIR]``: re-verify a controller program against its plan.

Reads a KRL (``.src``), FANUC TP (``.ls``) or RAPID (``.mod``) file, including one a programmer
touched up on the pendant, or a stream file (``_stream.csv``, its rows run one per cycle),
re-times it as the controller runs it and runs the planner's
sample-by-sample verification with the plan's model and forces
(:func:`rfsw_plan.export.check.check_program`). Prints "holds" (and which files were edited
against the export), or the first failure with the point, its line in the file and the
quantity: the weld window or any other row of the sample check, a segment's timing, a posture
or turn change, or a program of another plan (exit 3).
"""

from __future__ import annotations

import argparse

NAME = "check"
HELP = ("re-verify a KRL/TP/RAPID program (also one edited on the pendant) or a stream file "
        "against its plan")


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("program", help="program file: .src (with its .dat), .ls or .mod, or a "
                        "stream _stream.csv")
    parser.add_argument("--plan", default=None, metavar="PLAN_DIR",
                        help="the plan folder it was exported from (default: the program's "
                             "folder)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.export.check import check_program
    from rfsw_plan.files import strict_json

    res = check_program(args.program, args.plan)
    if args.json:
        print(strict_json(res.to_dict()), end="")
    else:
        print(res.line())
    return 0 if res.holds else 3
