"""The Python API end to end: problem, model, plan, inspect, write, read back.

::

    PYTHONPATH=. .venv/bin/python examples/python_api.py [OUT_DIR]

(default OUT_DIR: ``out/examples/python_api``, under the git-ignored ``out/``)

Everything the CLI does is a function call; the CLI is a thin layer over these. Units: SI in
the objects (m, rad, N, s), mm and degrees in the files.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

import rfsw_plan
from rfsw_plan.planfiles.folder import PlanFolder


def main(out: Path) -> None:
    # 1. A problem: a bundled name or a problem file (strictly checked, one-line errors).
    problem = rfsw_plan.load_problem("zk500_table6_seam")
    print(f"{problem.name}: robot {problem.robot.name} from {problem.robot.path}")

    # 2. The robot and its elastostatic model: the TCP deflection under a wrench.
    robot = rfsw_plan.load_robot(problem.robot)
    model = rfsw_plan.ElastostaticModel(robot)
    q = problem.q_seed()                                   # the problem's seed pose [rad]
    wrench = np.array([0.0, 0.0, 5000.0, 0.0, 0.0, 0.0])  # 5 kN pushing up at the TCP, base frame
    dx = model.deflection(q, wrench)
    print(f"deflection under 5 kN up: {np.round(dx[:3] * 1e3, 3)} mm (base frame)")

    # 3. Plan with other options (the same keys as [planning] / --set, in SI).
    options = replace(problem.planning, force_uncertainty=0.1)
    result = rfsw_plan.plan(problem, options)
    s = result.summary()
    print(f"{result.status}: max |e| while travelling {s['max_abs_lateral_weld_mm']:.3f} mm, "
          f"in the material (plunge and dwell too) {s['samples']['max_abs_lateral_mm']:.3f} mm, "
          "tolerated force "
          f"uncertainty +-{result.tolerated_force_uncertainty * 100:.3g} %, "
          f"{len(result.task)} waypoints, {result.trajectory.t[-1]:.1f} s")
    for b in result.baselines:  # none, mirror and nlp on the same waypoints (in the material)
        print(f"  {b.name:<7} max |e| {b.to_dict()['max_abs_lateral_mm']:.3f} mm")

    # 4. Write the plan folder exactly as `rfsw-plan plan -o DIR` does (atomic files, plan.json
    #    last with the SHA-256 of every file), then read it back
    #    through the one strict reader (PlanFolder: the record, the samples, rebuild()).
    plan_json = rfsw_plan.write_plan(out, result, robot_file=problem.robot.path)
    folder = PlanFolder.open(plan_json.parent)  # raises if a file is missing or changed
    record, samples = folder.record, folder.samples
    print(f"wrote {plan_json.parent}: status {record.status}, files "
          f"{sorted(record.sha256)}, {len(samples.t)} samples")


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out_dir", nargs="?", type=Path,
                    default=Path("out") / "examples" / "python_api",
                    help="plan folder to write (default: out/examples/python_api)")
    args = ap.parse_args()
    try:
        main(args.out_dir)
    except rfsw_plan.RfswError as exc:
        print(f"python_api: error: {exc}", file=sys.stderr)
        sys.exit(getattr(exc, "exit_code", 2))
