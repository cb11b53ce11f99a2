"""Compare offline planning with real-time compensation for your weld.

Every strategy welds the same virtual seam on a truth robot that differs from the model (here
joints 10 % softer), with the same noisy force sensor and slowly drifting process forces::

    PYTHONPATH=. .venv/bin/python examples/compare_my_weld.py [PROBLEM]

PROBLEM is a bundled problem name or your problem file (see examples/plan_my_seam.py); the
default is the 60 mm seam that example writes. The command-line version is
``rfsw-plan compare PROBLEM``; it also runs the sensitivity scenarios and writes the plots.
Strategies: ``none`` (no compensation), ``offline`` (rfsw-plan's plan, open loop),
``realtime_seed000`` and ``realtime_seed002`` (force-sensor feedback of the two papers), and
``hybrid`` (the plan plus a real-time residual correction).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import rfsw_plan


def main(problem_path: str | None) -> None:
    # imported here, not at the top: ``--help`` answers without loading the simulator
    from rfsw_plan.realtime.compare import CompareOptions, compare, format_table

    if problem_path is None:
        import plan_my_seam  # the example beside this one writes a small problem file

        out = Path("out") / "examples" / "compare_my_weld"  # under the gitignored out/
        out.mkdir(parents=True, exist_ok=True)
        plan_my_seam.write_problem(out)
        problem_path = str(out / "my_weld.toml")
    problem = rfsw_plan.load_problem(problem_path)
    options = CompareOptions(
        strategies=("none", "offline", "realtime_seed000", "realtime_seed002", "hybrid"),
        truth_stiffness_scale=0.9,   # the real robot is 10 % softer than its model
        sensitivity=False,           # True adds the stiffness / hidden effect / noise reruns
    )
    result = compare(problem, options)
    print(format_table(result))      # share of the weld inside the window, max |e|, RMS, ...


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("problem", nargs="?", default=None,
                    help="bundled problem name or problem file (default: plan_my_seam's 60 mm "
                         "seam, written under out/examples/compare_my_weld)")
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    try:
        main(args.problem)
    except rfsw_plan.RfswError as exc:  # a wrong name or file: one line, as the CLI says it
        print(f"compare_my_weld: error: {exc}", file=sys.stderr)
        sys.exit(getattr(exc, "exit_code", 2))
