"""``rfsw-plan deviation PROBLEM``: predicted uncompensated pin deviation along the seam."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import TYPE_CHECKING

from rfsw_plan.cli.numbers import number

NAME = "deviation"
HELP = "predict the uncompensated lateral/axial/along-track pin deviation of a problem"

if TYPE_CHECKING:  # the parser answers before the heavy libraries are imported
    from rfsw_plan.progress import Stages

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("problem", metavar="PROBLEM",
                        help="problem file or bundled stem (e.g. zk500_table6_seam)")
    parser.add_argument("-o", "--output", metavar="DIR", default=None,
                        help="output folder (default out/deviation/<problem>)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--dt", type=number(1e-6, 3600, "s", why="at least 1 us; at most the "
                                            "weld's duration, checked with the problem"),
                        default=0.1, metavar="S",
                        help="time step of the load schedule [s] (default 0.1, seed 001)")
    parser.add_argument("--cosim", action="store_true",
                        help="solve the axial force with the penetration law of "
                        "[process.coupling] (seed 001 Fig. 8 co-simulation)")
    parser.add_argument("--forces", metavar="CSV", default=None,
                        help="measured force series (t_s, fx_N, fy_N, fz_N[, m*_Nm][, frame]) "
                        "to fit the process forces to before predicting")
    parser.add_argument("--forces-frame", choices=("base", "seam", "tool"), default=None,
                        help="frame of the force CSV if it has no 'frame' column")
    parser.add_argument("--no-plot", action="store_true", help="do not write the PNG")


def run(args: argparse.Namespace) -> int:
    """Parse, call the job (:class:`~rfsw_plan.process.deviation_job.DeviationRequest`),
    write its folder, print."""
    from rfsw_plan.progress import Stages

    predict = "co-simulation" if args.cosim else "deviation"
    names = ["reading the problem", *(["fitting the force log"] if args.forces else []),
             predict, "files" if args.no_plot else "files and plot"]
    with Stages(NAME, names) as stages:
        return _run(args, stages, names)


def _run(args: argparse.Namespace, stages: Stages, names: list[str]) -> int:
    from rfsw_plan.files import OutputLock, prepare_output_dir, strict_json
    from rfsw_plan.process.deviation_job import DeviationRequest
    from rfsw_plan.process.problem import load_problem

    problem = load_problem(args.problem)
    out = prepare_output_dir(args.output if args.output else Path("out") / NAME / problem.name)
    forces = None
    if args.forces is not None:
        from rfsw_plan.io.force_series import read_force_series

        forces = read_force_series(args.forces, args.forces_frame)
    request = DeviationRequest(problem, dt=args.dt, cosim=args.cosim, forces=forces)
    job = request.run(on_stage=stages.start)
    stages.start(names[-1])
    with OutputLock(out):
        files = job.write(out, plot=not args.no_plot)
    data = {**job.to_dict(), "files": [str(f) for f in files]}
    if args.json:
        print(strict_json(data, indent=None), end="")
        return 0
    res = job.result
    print(job.summary())
    if job.fit_text:
        print(job.fit_text)
    if res.penetration_fit is not None:
        print(res.penetration_fit.summary())
    if res.cosim is not None:
        print(res.cosim.summary())
        print(res.cosim_summary())
    print(f"wrote {', '.join(f.name for f in files)} to {out}")
    return 0
