"""Benchmark of ``plan.html`` (issue 35): what writing the 3-D page costs ``rfsw-plan plan``.

Run: ``.venv/bin/python benchmarks/benchmark_page3d.py [PROBLEM ...]`` (default:
zk500_table6_seam, the problem of the 1.5 s budget).

For each problem, side by side in one process (the CasADi compile cache warm for both, as in
a second run of the CLI):

* **with**: ``rfsw-plan -q plan PROBLEM -o DIR`` as it is (writes ``plan.html``);
* **without**: the same command with the page writer replaced by nothing;
* **page alone**: :func:`rfsw_plan.planfiles.page3d.plan_page` on the written folder (read
  ``waypoints.csv``, Pinocchio link frames, numbers through numfmt, the inline three.js).

It prints the best of ``REPEAT`` wall (and CPU) times of each and the page's size.
Timings depend on the machine and its load.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import rfsw_plan.planfiles.page3d as page3d
from rfsw_plan.cli.main import main
from rfsw_plan.process.problem import load_problem
from rfsw_plan.robot.kinematics import load_robot

#: Runs per variant (the best is reported).
REPEAT = 3


def _plan(problem: str, out: Path) -> tuple[float, float]:
    """Wall and CPU time [s] of one ``rfsw-plan -q plan`` (its output swallowed)."""
    import contextlib
    import io

    t0, c0 = time.perf_counter(), time.process_time()
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["-q", "plan", problem, "-o", str(out)]) == 0
    return time.perf_counter() - t0, time.process_time() - c0


def bench(problem: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "plan"
        _plan(problem, out)  # warm-up: imports, CasADi compile cache
        with_page = min(_plan(problem, out) for _ in range(REPEAT))
        real = page3d.write_plan_page
        page3d.write_plan_page = lambda folder, *a, **k: Path(folder) / "waypoints.csv"
        try:
            without = min(_plan(problem, Path(tmp) / "nopage") for _ in range(REPEAT))
        finally:
            page3d.write_plan_page = real
        pb = load_problem(problem)
        robot = load_robot(pb.robot)
        w = (pb.window.lower * 1e3, pb.window.upper * 1e3)
        alone = []
        for _ in range(REPEAT):
            t0, c0 = time.perf_counter(), time.process_time()
            text = page3d.plan_page(out / "waypoints.csv", robot, pb.seam.frames_at, w, problem)
            alone.append((time.perf_counter() - t0, time.process_time() - c0))
        size = (out / "plan.html").stat().st_size
    print(f"{problem}: rfsw-plan plan with plan.html {with_page[0]:.2f} s wall "
          f"({with_page[1]:.2f} s CPU), without {without[0]:.2f} s ({without[1]:.2f} s CPU); "
          f"page alone {min(alone)[0]:.3f} s wall ({min(alone)[1]:.3f} s CPU); "
          f"plan.html {size / 1e6:.2f} MB ({len(text)} characters)")


if __name__ == "__main__":
    for name in sys.argv[1:] or ["zk500_table6_seam"]:
        bench(name)
