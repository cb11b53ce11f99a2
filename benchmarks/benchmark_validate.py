"""Benchmark: time of a full ``validate`` (all candidate effects, k-fold) on 10^4 samples.

Simulates a zk500 load campaign (2500 poses x 4 loads = 10^4 samples) with a hidden effect,
then times the steps of ``rfsw-plan validate``: reading is skipped (in memory), the
validation itself (noise floor, cross-validation of the model, residual analysis, diagnosis of
every candidate effect on every joint) and the report (plots, HTML, JSON). Prints the figures;
asserts nothing (the issue's goal is <= 30 s for the validation on this machine).

Run: ``.venv/bin/python benchmarks/benchmark_validate.py [--samples N] [--folds K]``
"""

from __future__ import annotations

import argparse
import tempfile
import time

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.robot.kinematics import load_robot
from rfsw_plan.validation.campaign import run_campaign
from rfsw_plan.validation.report import write_report
from rfsw_plan.validation.workbench import validate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=10_000, help="number of samples")
    parser.add_argument("--folds", type=int, default=5, help="cross-validation folds")
    parser.add_argument("--robot", default="zk500")
    args = parser.parse_args()

    robot = load_robot(args.robot)
    model = ElastostaticModel(robot)
    loads = 4
    poses = max(args.samples // loads, args.folds)
    cases = [
        ("one hidden effect", ["tilting_compliance:j2"], []),
        ("two hidden effects (greedy chain)", ["payload_gravity", "joint_backlash:j3"], []),
        ("one hidden effect, --add it", ["tilting_compliance:j2"], ["tilting_compliance:j2"]),
    ]
    print(f"robot {robot.name}, {poses * loads} samples ({poses} poses x {loads} loads), "
          f"{args.folds} folds")
    for title, hidden, add in cases:
        t0 = time.perf_counter()
        camp = run_campaign(robot, hidden, poses=poses, loads_per_pose=loads, noise_mm=0.01,
                            seed=1)
        t1 = time.perf_counter()
        result = validate(model, camp.data, add=add, folds=args.folds)
        t2 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            write_report(result, tmp)
        t3 = time.perf_counter()
        dg = result.diagnosis
        n_cand = len(dg.candidates) + len(dg.skipped)
        print(f"\n{title}: hidden {', '.join(hidden)}" + (f"; --add {', '.join(add)}" if add
                                                         else ""))
        print(f"  simulate campaign      {t1 - t0:7.2f} s")
        print(f"  validate (diagnosis)   {t2 - t1:7.2f} s   ({n_cand} candidates, "
              f"{len(dg.chain)} greedy step(s), diagnosis alone {dg.seconds:.2f} s)")
        print(f"  report (plots, HTML)   {t3 - t2:7.2f} s")
        print(f"  total validate+report  {t3 - t1:7.2f} s")
        print(f"  verdict: {dg.message}")


if __name__ == "__main__":
    main()
