"""Validate your own measurement file against a robot model and save the improved robot.

Run with your file (the measurement CSV format: docs/formats/measurements.md)::

    PYTHONPATH=. .venv/bin/python examples/validate_my_data.py MY_DATA.csv [ROBOT] [OUT_DIR]

(default OUT_DIR: ``out/examples/validate_my_data``, under the git-ignored ``out/``)

Without a file it first simulates one: a small load campaign of the bundled ZK-500 with a
hidden payload gravity effect (:func:`rfsw_plan.validation.campaign.run_campaign`), so you
can see the whole loop. The same steps on the command line::

    rfsw-plan validate --robot zk500 --data MY_DATA.csv
    rfsw-plan validate --robot zk500 --data MY_DATA.csv --add EFFECT --save-robot improved.toml
    rfsw-plan plan MY_PROBLEM.toml   # with robot = "improved.toml" in the problem file
"""

from __future__ import annotations

import sys
from pathlib import Path

import rfsw_plan
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.validation.campaign import run_campaign
from rfsw_plan.validation.workbench import save_extended_robot, validate


def main(data_file: Path | None, robot: str, out: Path) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    if data_file is None:
        # No file given: simulate a small campaign (12 poses, 4 loads each, 0.01 mm noise)
        # whose truth has a 150 kg payload the model does not know about.
        campaign = run_campaign(robot, hidden=["payload_gravity=m:150"], poses=12,
                                loads_per_pose=4, noise_mm=0.01, seed=1)
        data_file = rfsw_plan.write_measurements(out / "campaign.csv", campaign.data)
        print(f"simulated {len(campaign.data.q)} samples into {data_file}")

    model = ElastostaticModel(rfsw_plan.load_robot(robot))
    data = rfsw_plan.read_measurements(data_file, model.robot.nq)  # strict, one-line errors

    # 1. How good is the model, and what is missing? (cross-validated over poses)
    first = validate(model, data, folds=3)
    d = first.diagnosis
    print(f"model {robot}: RMS {first.rms * 1e3:.4f} mm, verdict {d.verdict}: {d.message}")
    if d.verdict != "missing":
        print("nothing to add")
        return data_file

    # 2. Add the best candidate, re-identify every parameter, save the improved robot.
    best = d.candidates[0].label
    second = validate(model, data, add=[best], folds=3)
    print(f"with {best}: RMS {second.rms * 1e3:.4f} mm, verdict {second.diagnosis.verdict}")
    saved = save_extended_robot(second, out / "improved_robot.toml")
    print(f"saved {saved}: plan with robot = \"{saved}\" in your problem file")
    return saved


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", nargs="?", default="",
                    help="your measurement CSV ('' or left out: simulate one first)")
    ap.add_argument("robot", nargs="?", default="zk500",
                    help="bundled robot name or robot file (default zk500)")
    ap.add_argument("out_dir", nargs="?", type=Path,
                    default=Path("out") / "examples" / "validate_my_data",
                    help="output folder (default: out/examples/validate_my_data)")
    args = ap.parse_args()
    try:
        main(Path(args.data) if args.data else None, args.robot, args.out_dir)
    except rfsw_plan.RfswError as exc:
        print(f"validate_my_data: error: {exc}", file=sys.stderr)
        sys.exit(getattr(exc, "exit_code", 2))
