"""``rfsw-plan map PROBLEM -o DIR``: stiffness and robustness maps over part placements."""

from __future__ import annotations

import argparse
from pathlib import Path

from rfsw_plan.cli.commands._placement_args import register_region, request_from_args

NAME = "map"
HELP = ("map lateral stiffness, deviation, tolerated force uncertainty, kappa_f and nu_p over "
        "placements of the part (table-plane position, yaw, height)")


def register(parser: argparse.ArgumentParser) -> None:
    register_region(parser, "25,25,8")


def run(args: argparse.Namespace) -> int:
    """Parse, call the job (:class:`~rfsw_plan.placement.job.PlacementMapRequest`), write its
    folder, print."""
    from rfsw_plan.files import OutputLock, prepare_output_dir, strict_json
    from rfsw_plan.placement.job import PlacementMapRequest
    from rfsw_plan.process.problem import load_problem

    problem = load_problem(args.problem)
    request = PlacementMapRequest(problem, request_from_args(args), args.force_uncertainty)
    out = prepare_output_dir(Path(args.output) if args.output else
                             Path("out") / NAME / problem.name)
    with OutputLock(out):
        job = request.run()
        job.write(out)
    s = job.session
    m = s.map
    u = job.options.force_uncertainty
    summary = job.to_dict(out)
    if args.json:
        print(strict_json(summary).rstrip())
        return 0
    g = summary["given"]
    print(f"{problem.name}: {summary['placements']} placements in {m.seconds:.1f} s "
          f"({m.rate:.0f} placements/s, {len(s.input.task)} waypoints each); "
          + ", ".join(f"{v} {k}" for k, v in summary["status_counts"].items()))
    if s.extent is not None:
        print(f"default region: {s.extent.text()}")
    print(f"given placement: tolerated uncertainty {_pct(g.get('tolerated_uncertainty_mirror'))} "
          f"(mirror offsets), {_pct(g.get('tolerated_uncertainty_centred'))} (centred), "
          f"min lateral stiffness {g.get('min_lateral_stiffness_N_per_mm', float('nan')):.0f} "
          "N/mm")
    print(f"best placement (rank 1 below): tolerated uncertainty "
          f"{_pct(summary['best_tolerated_uncertainty_mirror'])} (mirror), "
          f"{_pct(summary['best_tolerated_uncertainty_centred'])} (centred); requested "
          f"+-{u * 100:.3g} % "
          f"{'reached' if summary['requested_reached_somewhere'] else 'NOT reached'} in this "
          "region (centred estimate)")
    print(f"{'rank':>4} {'x mm':>8} {'y mm':>8} {'z mm':>7} {'yaw deg':>8} {'u mirror':>9} "
          f"{'u centred':>9} {'k_lat N/mm':>10} {'max|e| mm':>9}")
    for i, r in enumerate(summary["top"], 1):
        print(f"{i:>4} {r['x_mm']:>8.0f} {r['y_mm']:>8.0f} {r['z_mm']:>7.0f} {r['yaw_deg']:>8.1f} "
              f"{_pct(r['tolerated_uncertainty_mirror']):>9} "
              f"{_pct(r['tolerated_uncertainty_centred']):>9} "
              f"{r['min_lateral_stiffness_N_per_mm']:>10.0f} "
              f"{r['max_abs_uncompensated_lateral_mm']:>9.2f}")
    print(f"files in {out}")
    return 0


def _pct(v: object) -> str:
    try:
        f = float(v)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return "n/a"
    return "n/a" if f != f else f"{f * 100:.1f} %"
