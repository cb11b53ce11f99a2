"""``rfsw-plan place PROBLEM -o DIR``: where to put the part so that the plan is most robust."""

from __future__ import annotations

import argparse
from concurrent.futures import Executor
from dataclasses import replace
from pathlib import Path
from typing import Any

from rfsw_plan.cli.commands._placement_args import register_region, request_from_args
from rfsw_plan.cli.numbers import count
from rfsw_plan.exceptions import InputError

NAME = "place"
HELP = ("find the part placement (table-plane position, yaw, height) whose plan tolerates the "
        "most force uncertainty: screen a map, plan the best candidates, write the placed problem")

def register(parser: argparse.ArgumentParser) -> None:
    register_region(parser, "15,15,8")
    parser.add_argument("--candidates", type=count(0, 100), default=4,
                        help="screened placements planned in full, besides the given one "
                        "(default 4)")
    parser.add_argument("--workers", type=count(1, 256), default=1,
                        help="local worker processes for the candidate plans (default 1: in "
                        "this process)")
    parser.add_argument("--dask", default=None, metavar="ADDRESS",
                        help="plan the candidates on a Dask distributed scheduler (e.g. "
                        "tcp://10.0.0.5:8786); needs the extra rfsw_plan[dask]")


def make_executor(workers: int, dask: str | None) -> tuple[Executor | None, Any, str]:
    """The executor for the candidate plans, the object to close afterwards, and a label.

    Raises:
        InputError: Bad worker count, both options, Dask missing or unreachable.
    """
    if workers < 1:
        raise InputError("--workers", "", f"got {workers}", ">= 1")
    if dask is not None:
        if workers != 1:
            raise InputError("--dask", "", "given together with --workers",
                             "either local --workers or a --dask scheduler")
        try:
            from dask.distributed import Client
        except ImportError:
            raise InputError("--dask", dask, "dask.distributed is not installed",
                             "pip install 'rfsw_plan[dask]'") from None
        try:
            client = Client(dask, timeout=10)
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError("--dask", dask, f"cannot connect to the scheduler ({exc})",
                             "the address of a running dask scheduler") from None
        return client.get_executor(), client, f"dask {dask}"
    if workers == 1:
        return None, None, "in process"
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    ex = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))
    return ex, ex, f"{workers} local processes"


def run(args: argparse.Namespace) -> int:
    """Parse, call the job (:class:`~rfsw_plan.placement.job.PlaceRequest`), write its
    folder, print."""
    from rfsw_plan.files import OutputLock, prepare_output_dir, strict_json
    from rfsw_plan.placement.job import PlaceRequest
    from rfsw_plan.process.problem import load_problem

    problem = load_problem(args.problem)
    request = PlaceRequest(problem, request_from_args(args), args.candidates,
                           args.force_uncertainty)
    request.check()
    out = prepare_output_dir(Path(args.output) if args.output else
                             Path("out") / NAME / problem.name)
    executor, closer, where = make_executor(args.workers, args.dask)
    try:
        with OutputLock(out):
            job = replace(request, executor=executor, executor_label=where).run()
            job.write(out)
    finally:
        if closer is not None:
            (closer.close if hasattr(closer, "close") else closer.shutdown)()
    summary = job.to_dict(out)
    code = 0 if job.chosen is not None else 3
    if args.json:
        print(strict_json(summary).rstrip())
        return code
    _print(problem.name, summary, job.rows, job.result, job.session)
    return code


def _print(name: str, summary: dict[str, Any], rows: list[dict[str, Any]], res: Any,
           s: Any) -> None:
    """The table, with the wall times the files leave out (the map's, each plan's)."""
    m = s.map
    seconds = {c.label: c.plan_time for c in res.results}
    print(f"{name}: map of {len(m.placements)} placements in {m.seconds:.1f} s; "
          f"{len(rows)} plans in {res.seconds:.1f} s ({summary['executor']})")
    if s.extent is not None:
        print(f"default region: {s.extent.text()}")
    print(f"{'rank':>4} {'cand':>5} {'x mm':>8} {'y mm':>8} {'z mm':>7} {'yaw':>6} "
          f"{'tolerated':>9} {'max|e| mm':>9} {'k_lat N/mm':>10} {'plan s':>6}  status")
    for r in rows:
        u = r["tolerated_uncertainty"]
        print(f"{r['rank']:>4} {r['label']:>5} {r['x_mm']:>8.0f} {r['y_mm']:>8.0f} "
              f"{r['z_mm']:>7.0f} {r['yaw_deg']:>6.0f} "
              f"{'' if u != u else f'{u * 100:.1f} %':>9} {r['max_abs_lateral_mm']:>9.3f} "
              f"{r['min_lateral_stiffness_N_per_mm']:>10.0f} {seconds[r['label']]:>6.1f}  "
              f"{r['status']}{'  <- chosen' if r['chosen'] else ''}"
              f"{'' if not r['message'] else ': ' + r['message'][:80]}")
    print(summary["verdict"])
    print("files: " + ", ".join(summary["files"]))
