"""Benchmark of the placement map and of ``place`` on the bundled problems.

Run: ``.venv/bin/python benchmarks/benchmark_placement.py [--grid 50,50,8] [--workers 2]``

Printed:

* ``map``: placements per second of :func:`rfsw_plan.placement.map.compute_map` on a 50-waypoint
  seam (the problem's stationary plunge/dwell waypoints plus 50 weld waypoints) over a
  ``--grid`` of placements around the given one (+-400 mm, the full turn of yaw), with the share
  of placements the robot reaches; the goal of issue 14 is 1e4 placements/s;
* ``place``: wall time of the whole ``rfsw-plan place`` pipeline (default region scan, a
  15 x 15 x 8 screening map, the plans of 4 candidates and the given placement on
  ``--workers`` local processes, the files); the goal is 60 s on 2 cores.

Timings are wall clock on this machine; nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np

from rfsw_plan.placement.geometry import PlacementGrid
from rfsw_plan.placement.map import compute_map, map_input
from rfsw_plan.process.problem import bundled_problem_names, load_problem

#: The problems of issue 14's proof.
PROBLEMS = ("zk500_table6_seam", "fanuc_butt_1700mm", "kr600_curved_seam")


def bench_map(name: str, shape: tuple[int, int, int]) -> None:
    mi = map_input(load_problem(name), max_weld=50)
    a = mi.anchor
    grid = PlacementGrid(a[0] + np.linspace(-0.4, 0.4, shape[0]),
                         a[1] + np.linspace(-0.4, 0.4, shape[1]),
                         np.deg2rad(np.linspace(-180.0, 180.0, shape[2], endpoint=False)),
                         np.array([a[2]]))
    t0 = time.perf_counter()
    m = compute_map(mi, grid, progress_desc=None)
    dt = time.perf_counter() - t0
    reach = float(np.mean(m.status != "unreachable"))
    print(f"map   {name:<20} {grid.size:>6} placements x {len(mi.task):>3} waypoints: "
          f"{dt:6.2f} s, {grid.size / dt:8.0f} placements/s, {m.evaluated_poses / dt:9.0f} "
          f"poses/s, {reach * 100:.0f} % reachable")


def bench_place(name: str, workers: int) -> None:
    from rfsw_plan.cli.main import main

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        code = main(["-q", "place", name, "-o", os.path.join(tmp, "o"), "--workers",
                     str(workers)])
        dt = time.perf_counter() - t0
    print(f"place {name:<20} {dt:6.1f} s (exit {code}, {workers} worker(s))")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grid", default="50,50,8", help="nx,ny,nyaw of the map benchmark")
    ap.add_argument("--workers", type=int, default=2, help="local processes for place")
    ap.add_argument("--problems", nargs="*", default=list(PROBLEMS),
                    help=f"bundled problems (any of {', '.join(bundled_problem_names())})")
    ap.add_argument("--skip-place", action="store_true")
    args = ap.parse_args()
    shape = tuple(int(v) for v in args.grid.split(","))
    for name in args.problems:
        bench_map(name, shape)  # type: ignore[arg-type]
    if not args.skip_place:
        for name in args.problems:
            bench_place(name, args.workers)


if __name__ == "__main__":
    main()
