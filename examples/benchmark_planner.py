"""Benchmark of the planner: plan time for 100, 300, 1000 and 4000 waypoints.

Run: ``.venv/bin/python examples/benchmark_planner.py [--sizes 100 300 1000 4000]``

For each size, the bundled ``zk500_table6_seam`` is planned with the waypoint spacing that gives
that many weld waypoints (plus the stationary plunge/dwell waypoints). Printed per size:

* ``plan``: the full :func:`rfsw_plan.planning.api.plan` (branches, baselines, NLP with outer
  loop, independent verification, time parameterisation);
* ``nlp`` / ``verify`` / ``timing``: its parts;
* ``baseline 2``: the mirror fixed-point baseline on the same task, verified and timed the same
  way (taught path + mirror + verification + timing).

The first call compiles the NLP point functions to C (once per robot model, cached on disk);
that one-off time is printed separately. Timings are wall clock on this machine; nothing is
asserted.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.planning.api import options_from_problem, plan
from rfsw_plan.planning.baselines import mirror_compensation, no_compensation
from rfsw_plan.planning.verify import verify_plan
from rfsw_plan.process.problem import load_problem
from rfsw_plan.process.task import task_from_schedule
from rfsw_plan.robot.kinematics import load_robot
from rfsw_plan.timing.trajectory import TimingLimits, time_parameterise


def baseline2(problem, spacing: float) -> float:
    """Wall time of the mirror baseline on the same task, verified and timed."""
    t0 = time.perf_counter()
    opts = options_from_problem(problem)
    model = ElastostaticModel(load_robot(problem.robot))
    frames = problem.seam.frames(spacing)
    task = task_from_schedule(frames, problem.process.schedule(frames, 0.05, approach=False),
                              opts.max_start_waypoints)
    taught = no_compensation(model.robot, task, np.asarray(opts.q_seed), opts.tool_rotation)
    mir = mirror_compensation(model, task, taught.q, opts.tool_rotation)
    verify_plan(model, task, problem.window, mir.q, mir.offsets, opts.force_uncertainty)
    time_parameterise(model.robot, task, mir.q, mir.offsets,
                      TimingLimits(plunge_speed=problem.process.plunge_speed))
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 300, 1000, 4000])
    ap.add_argument("--problem", default="zk500_table6_seam")
    args = ap.parse_args()
    problem = load_problem(args.problem)
    L = problem.seam.length
    t0 = time.perf_counter()
    plan(problem, spacing=L / 299)  # warm-up: compiles (or loads) the C point functions
    print(f"{args.problem}: seam {L * 1e3:.1f} mm; warm-up incl. one-off compile "
          f"{time.perf_counter() - t0:.2f} s")
    print(f"{'weld wps':>8} {'K':>6} {'plan s':>8} {'nlp s':>7} {'verify s':>9} {'timing s':>9} "
          f"{'ipopt it':>8} {'baseline2 s':>11} {'max|e| mm':>9}")
    for n in args.sizes:
        spacing = L / (n - 1)
        r = plan(problem, spacing=spacing)
        tb = baseline2(problem, spacing)
        e = np.max(np.abs(r.e_lat[r.task.weld])) * 1e3
        print(f"{n:>8} {len(r.task):>6} {r.total_time:>8.2f} {r.solve_time:>7.2f} "
              f"{r.verify_time:>9.3f} {r.timing_time:>9.2f} {r.iterations:>8} {tb:>11.2f} "
              f"{e:>9.3f}")


if __name__ == "__main__":
    main()
