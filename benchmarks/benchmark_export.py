"""Benchmark of ``export`` (issue 24: at least 5x faster): before and after, in one run.

Run: ``.venv/bin/python benchmarks/benchmark_export.py [PROBLEM ...]``
(default: zk500_table6_seam kr600_curved_seam; each is planned first into a temporary folder).

For each problem it times, on the same written plan and the same three programs (KRL, TP,
RAPID):

* **before**: the round trip as it was (every re-read point's inverse kinematics started from
  the previous point, with the configuration branches computed for every point before the
  first solve: about 0.2 s per point);
* **after**: the round trip as it is (started from the joint values planned for the point;
  the branches only when that solution has another posture);
* the whole ``export_plan_folder`` (strict reader, program build, path-deviation check, four
  formats written, re-read and round-tripped, record written).

It prints the times and the ratio before/after of the round trip and of the whole export
(before = after's export with the old round trip in place of the new one). Timings depend on
the machine and its load; it reports the best of ``REPEAT`` runs.
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rfsw_plan.cli.main import main
from rfsw_plan.export.api import export_plan_folder
from rfsw_plan.export.config import _turn_variants
from rfsw_plan.export.format import ControllerFormat, ReadProgram, get_format
from rfsw_plan.export.program import Samples, build_program
from rfsw_plan.export.readback import round_trip
from rfsw_plan.planfiles.folder import read_plan_folder
from rfsw_plan.planning.baselines import branch_seeds
from rfsw_plan.robot.ik import solve_ik
from rfsw_plan.robot.kinematics import Robot, load_robot

REPEAT = 2
FORMATS = ("krl", "fanuc_tp", "rapid")


def best(fn: Callable[[], object]) -> float:
    out = math.inf
    for _ in range(REPEAT):
        t0 = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - t0)
    return out


def old_round_trip(robot: Robot, fmt: ControllerFormat, read: ReadProgram,
                   expected: Samples) -> None:
    """The round trip before issue 24: continuation seed, branches computed eagerly."""
    conv = robot.description.convention
    to_model = np.linalg.inv(read.tool) @ np.linalg.inv(conv.flange) @ robot.description.tool
    seed = None
    for p in read.points:
        if p.q is not None:
            seed = p.q
            continue
        T = conv.base @ read.work @ p.pose @ to_model
        base = seed if seed is not None else expected.q[0]
        seeds = ([] if seed is None else [seed]) + [s for _, s in branch_seeds(robot, base)]
        for s in seeds:
            res = solve_ik(robot, T, s, tol_pos=1e-10, tol_rot=1e-10, max_iter=300)
            q = next((v for v in _turn_variants(robot, res.q, s)
                      if fmt.matches(robot, p, v)), None)
            if q is not None:
                seed = q
                break


def run(problem: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / problem
        assert main(["-q", "plan", problem, "-o", str(folder)]) == 0
        rec_robot = read_plan_folder(folder).robot_file
        robot = load_robot(rec_robot)
        d = robot.description
        plan = read_plan_folder(folder, d.convention.column_names(), (d.lower, d.upper))
        from rfsw_plan.export.api import ProgramHeader, plan_spacing

        header = ProgramHeader("rfsw_bench", "bench", problem, robot.name, "", "", "", 0.2,
                               0.2, (-1.25, 0.7), 1e-5, plan_spacing(plan.record))
        program = build_program(robot, plan.samples, header)
        reads = {}
        for f in FORMATS:
            fmt = get_format(f)
            reads[f] = (fmt, fmt.read(fmt.write(program, Path(tmp))[0]), fmt.expected(program))
        t_old = best(lambda: [old_round_trip(robot, *reads[f]) for f in FORMATS])
        t_new = best(lambda: [round_trip(robot, *reads[f]) for f in FORMATS])
        t_export = best(lambda: export_plan_folder(folder, [*FORMATS, "stream"],
                                                    Path(tmp) / "out"))
        n = len(reads["krl"][1].points)
        print(f"{problem}: {n} points x {len(FORMATS)} formats")
        print(f"  round trip   before {t_old:7.2f} s   after {t_new:6.2f} s   "
              f"ratio {t_old / t_new:6.1f}x")
        t_before = t_export - t_new + t_old
        print(f"  whole export before {t_before:7.2f} s   after {t_export:6.2f} s   "
              f"ratio {t_before / t_export:6.1f}x")


if __name__ == "__main__":
    for name in sys.argv[1:] or ["zk500_table6_seam", "kr600_curved_seam"]:
        run(name)
