"""``rfsw-plan place PROBLEM -o DIR``: where to put the part so that the plan is most robust."""

from __future__ import annotations

import argparse
import csv
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

from rfsw_plan.cli.commands._placement_args import register_region, request_from_args
from rfsw_plan.cli.numbers import count
from rfsw_plan.exceptions import InputError

NAME = "place"
HELP = ("find the part placement (table-plane position, yaw, height) whose plan tolerates the "
        "most force uncertainty: screen a map, plan the best candidates, write the placed problem")

_CSV = ("rank", "label", "chosen", "x_mm", "y_mm", "z_mm", "yaw_deg", "dx_mm", "dy_mm",
        "robot_base_height_mm", "status", "tolerated_uncertainty", "max_abs_lateral_mm",
        "min_lateral_stiffness_N_per_mm", "sample_window_margin_mm", "plan_time_s",
        "dominant_compliance",
        "screen_tolerated_uncertainty_centred", "message")


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
    from rfsw_plan.files import (
        OutputLock,
        atomic_path,
        prepare_output_dir,
        strict_json,
        write_json,
    )
    from rfsw_plan.placement.files import (
        map_summary,
        write_map_csv,
        write_map_json,
        write_placed_problem,
    )
    from rfsw_plan.placement.optimise import place, results_table
    from rfsw_plan.placement.plots import plot_map, plot_yaw
    from rfsw_plan.placement.session import map_problem
    from rfsw_plan.planning.api import options_from_problem
    from rfsw_plan.process.problem import load_problem

    problem = load_problem(args.problem)
    request = request_from_args(args)
    if args.candidates < 1:
        raise InputError("--candidates", "", f"got {args.candidates}", ">= 1")
    over = {} if args.force_uncertainty is None else {"force_uncertainty": args.force_uncertainty}
    opts = options_from_problem(problem, over)
    out = prepare_output_dir(Path(args.output) if args.output else
                             Path("out") / NAME / problem.name)
    executor, closer, where = make_executor(args.workers, args.dask)
    try:
        with OutputLock(out):
            s = map_problem(problem, request, opts)
            m = s.map
            res = place(problem, m, opts, args.candidates, executor)
            rows = results_table(res, m.anchor)
            chosen = res.chosen
            files = [out / n for n in ("map.csv", "map.json", "map.png", "map_yaw.png",
                                       "candidates.csv", "place.json")]
            write_map_csv(out / "map.csv", m)
            marks = [(c.label, c.placement.x, c.placement.y) for c in res.candidates
                     if c.label != "given"]
            plot_map(out / "map.png", m, marks, requested=opts.force_uncertainty)
            plot_yaw(out / "map_yaw.png", m)
            write_map_json(out / "map.json", m, opts.force_uncertainty)
            with atomic_path(out / "candidates.csv") as tmp, open(tmp, "w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(_CSV)
                for r in rows:
                    w.writerow([_cell(r.get(c)) for c in _CSV])
            summary = _summary(problem, res, rows, m, opts.force_uncertainty, where)
            summary["map"] = {k: v for k, v in map_summary(m, opts.force_uncertainty).items()
                              if k not in ("grid",)}
            if chosen is not None:
                toml = out / f"{problem.name}_placed.toml"
                note = (f"Placed by rfsw-plan place from {problem.name}: seam anchor moved to "
                        f"x {chosen.placement.x * 1e3:.1f}, y {chosen.placement.y * 1e3:.1f}, "
                        f"z {chosen.placement.z * 1e3:.1f} mm, yaw "
                        f"{summary['chosen']['yaw_deg']:+.1f} deg.\nPlanned tolerated force "
                        f"uncertainty {chosen.tolerated_uncertainty * 100:.1f} % (given placement:"
                        f" {summary['given']['tolerated_uncertainty'] * 100:.1f} %), planned "
                        f"for {res.planned_for * 100:.3g} % (requested "
                        f"{opts.force_uncertainty * 100:.3g} % plus headroom for the planner's "
                        f"fine projection).")
                q_seed = chosen.q_start
                write_placed_problem(toml, problem, chosen.placement, m.anchor, q_seed, note,
                                     force_uncertainty=res.planned_for)
                files.insert(0, toml)
            summary["files"] = [str(f) for f in files]
            write_json(out / "place.json", summary)
    finally:
        if closer is not None:
            (closer.close if hasattr(closer, "close") else closer.shutdown)()
    if args.json:
        print(strict_json(summary).rstrip())
        return 0 if chosen is not None else 3
    _print(problem.name, summary, rows, m, s)
    return 0 if chosen is not None else 3


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        from rfsw_plan.numfmt import general

        return "" if v != v or v in (float("inf"), float("-inf")) else general(v, 6)
    return str(v)


def _summary(problem: Any, res: Any, rows: list[dict[str, Any]], m: Any, requested: float,
             where: str) -> dict[str, Any]:
    given = next(r for r in rows if r["label"] == "given")
    chosen = next((r for r in rows if r["chosen"]), None)
    best_u = chosen["tolerated_uncertainty"] if chosen else float("nan")
    reached = bool(chosen is not None and best_u >= requested)
    if chosen is None:
        verdict = "no candidate could be planned: " + "; ".join(
            f"{r['label']}: {r['message']}" for r in rows)
    elif reached:
        verdict = (f"+-{requested * 100:.3g} % holds at the chosen placement (tolerated "
                   f"{best_u * 100:.1f} %); the stiffest such placement was chosen")
    else:
        verdict = (f"+-{requested * 100:.3g} % is reached by no planned candidate in this region; "
                   f"the largest is {best_u * 100:.1f} % (given placement "
                   f"{given['tolerated_uncertainty'] * 100:.1f} %); the worst-case spread there "
                   f"comes mostly from the compliance of {chosen['dominant_compliance']}")
    return {
        "problem": problem.name,
        "requested_uncertainty": requested,
        "planned_for_uncertainty": res.planned_for,
        "requested_reached": reached,
        "verdict": verdict,
        "given": given,
        "chosen": chosen,
        "candidates": rows,
        "executor": where,
        "plans_seconds": res.seconds,
        "map_seconds": m.seconds,
    }


def _print(name: str, summary: dict[str, Any], rows: list[dict[str, Any]], m: Any,
           s: Any) -> None:
    print(f"{name}: map of {len(m.placements)} placements in {m.seconds:.1f} s; "
          f"{len(rows)} plans in {summary['plans_seconds']:.1f} s ({summary['executor']})")
    if s.extent is not None:
        print(f"default region: {s.extent.text()}")
    print(f"{'rank':>4} {'cand':>5} {'x mm':>8} {'y mm':>8} {'z mm':>7} {'yaw':>6} "
          f"{'tolerated':>9} {'max|e| mm':>9} {'k_lat N/mm':>10} {'plan s':>6}  status")
    for r in rows:
        u = r["tolerated_uncertainty"]
        print(f"{r['rank']:>4} {r['label']:>5} {r['x_mm']:>8.0f} {r['y_mm']:>8.0f} "
              f"{r['z_mm']:>7.0f} {r['yaw_deg']:>6.0f} "
              f"{'' if u != u else f'{u * 100:.1f} %':>9} {r['max_abs_lateral_mm']:>9.3f} "
              f"{r['min_lateral_stiffness_N_per_mm']:>10.0f} {r['plan_time_s']:>6.1f}  "
              f"{r['status']}{'  <- chosen' if r['chosen'] else ''}"
              f"{'' if not r['message'] else ': ' + r['message'][:80]}")
    print(summary["verdict"])
    print("files: " + ", ".join(summary["files"]))
