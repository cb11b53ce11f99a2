"""Benchmark of the virtual weld and the compensation comparison (prints figures, asserts none).

1. Seed 001's co-simulated weld: 2 s plunge + 10 s weld at 3 mm/s on the ZK-500 Table 6 seam
   (seed 001 §2.3: 8.5 h of FEA). Time of the virtual weld per strategy at a 4 ms cycle.
2. ``compare`` on zk500_table6_seam and fanuc_butt_1700mm: the tables and timings.

Run: ``.venv/bin/python benchmarks/benchmark_compare.py [--no-plan]``.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import RfswError
from rfsw_plan.process.problem import Problem, load_problem
from rfsw_plan.process.taught import taught_path
from rfsw_plan.realtime.compare import (
    STRATEGIES,
    CompareOptions,
    compare,
    default_planner,
    format_table,
    planned_path,
)
from rfsw_plan.realtime.simulator import SimConfig, VirtualWeld
from rfsw_plan.robot.kinematics import load_robot


def seed001_12s_problem() -> Problem:
    """zk500_table6_seam cut to 30 mm (10 s at 3 mm/s) with a 2 s plunge and no dwell."""
    p = load_problem("zk500_table6_seam")
    a, b = p.seam.points[0], p.seam.points[-1]
    end = a + (b - a) / np.linalg.norm(b - a) * 0.030
    seam = replace(p.seam, points=np.stack([a, end]))
    proc = replace(p.process, dwell_time=0.0, plunge_speed=p.process.plunge_depth / 2.0)
    return replace(p, seam=seam, process=proc, name="seed001_12s")


def bench_12s(with_plan: bool) -> None:
    problem = seed001_12s_problem()
    robot = load_robot(problem.robot)
    model = ElastostaticModel(robot)
    frames = problem.frames()
    q = taught_path(robot, frames, problem.q_seed(), problem.planning.tool_rotation)
    opts = CompareOptions()
    tic = time.perf_counter()
    schedule = problem.process.schedule(frames, opts.cycle_s)
    vw = VirtualWeld(schedule, model, None, SimConfig())
    paths = {"taught": vw.path_from_waypoints(frames.s - frames.s[0], q)}
    setup = time.perf_counter() - tic
    names = [s for s in STRATEGIES if s not in ("offline", "hybrid")]
    if with_plan:
        try:
            wp = default_planner(problem)
            paths["plan"] = planned_path(vw, wp)
            names = list(STRATEGIES)
            print(f"  plan (offline, once): {wp.solve_time_s:.2f} s")
        except (RfswError, ImportError) as exc:
            print(f"  no offline plan: {exc}")
    n = int(np.sum(vw.weld_mask))
    phases = ", ".join(
        f"{ph} {np.sum(vw.phase == ph) * opts.cycle_s:.1f} s"
        for ph in ("plunge", "dwell", "weld", "retract") if np.any(vw.phase == ph))
    print(f"seed 001 weld: {vw.t[-1] - vw.t[0]:.1f} s process ({phases}), {len(vw.t)} cycles "
          f"of 4 ms ({n} welding); setup (schedule, sensor, paths) {setup * 1e3:.1f} ms")
    total = setup
    for s in names:
        key = "plan" if s in ("offline", "hybrid") else "taught"
        tic = time.perf_counter()
        run = vw.run(opts.make_strategy(s), paths[key], label=s)
        dt = time.perf_counter() - tic
        total += dt
        e = np.abs(run.lateral_error[run.weld]).max() * 1e3
        print(f"  {s:<18} {dt * 1e3:7.1f} ms   max |e| {e:5.2f} mm")
    print(f"  all strategies incl. setup: {total:.3f} s (seed 001 FEA: 8.5 h)")


def bench_compare(name: str, with_plan: bool) -> None:
    problem = load_problem(name)
    strategies = STRATEGIES if with_plan else ("none", "realtime_seed000", "realtime_seed002")
    tic = time.perf_counter()
    try:
        res = compare(problem, CompareOptions(strategies=tuple(strategies)))
    except (RfswError, ImportError) as exc:
        print(f"{name}: compare failed: {exc}")
        return
    print(format_table(res))
    print(f"  wall time {time.perf_counter() - tic:.2f} s\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-plan", action="store_true", help="real-time strategies only")
    args = ap.parse_args()
    bench_12s(not args.no_plan)
    print()
    for name in ("zk500_table6_seam", "fanuc_butt_1700mm"):
        bench_compare(name, not args.no_plan)


if __name__ == "__main__":
    main()
