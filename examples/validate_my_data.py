"""Validate your own measurement file against a robot model and save the improved robot.

Run with your file (the measurement CSV format: docs/formats/measurements.md)::

    PYTHONPATH=. .venv/bin/python examples/validate_my_data.py MY_DATA.csv [ROBOT] [OUT_DIR]

(default OUT_DIR: ``out/examples/validate_my_data``, under the git-ignored ``out/``)

Without a file it first simulates one: the load campaign of the guide (docs/guide/validate.md)
of the bundled ZK-500 with two hidden effects, a 150 kg spindle's weight and backlash in joint
2 (:func:`rfsw_plan.validation.campaign.simulation.run_campaign`), so you can see the whole
loop: the forward selection names both, in order, and adding them brings the held-out error to the
noise floor. The same steps on the command line::

    rfsw-plan validate --robot zk500 --data MY_DATA.csv
    rfsw-plan validate --robot zk500 --data MY_DATA.csv --add EFFECT1 --add EFFECT2 \
        --save-robot improved.toml
    rfsw-plan plan MY_PROBLEM.toml   # with robot = "improved.toml" in the problem file
"""

from __future__ import annotations

import sys
from pathlib import Path

import rfsw_plan
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.validation.campaign.simulation import run_campaign
from rfsw_plan.validation.workbench import save_extended_robot, validate


def main(data_file: Path | None, robot: str, out: Path) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    if data_file is None:
        # No file given: simulate the guide's campaign (40 poses, 8 loads each, 0.01 mm
        # noise) whose truth has a 150 kg spindle and backlash in joint 2 the model lacks.
        campaign = run_campaign(robot, hidden=["payload_gravity=m:150,m_rz:-37.5",
                                               "joint_backlash:j2"], poses=40,
                                loads_per_pose=8, noise_mm=0.01, seed=1)
        data_file = rfsw_plan.write_measurements(out / "campaign.csv", campaign.data)
        print(f"simulated {len(campaign.data.q)} samples into {data_file}")

    model = ElastostaticModel(rfsw_plan.load_robot(robot))
    data = rfsw_plan.read_measurements(data_file, model.robot.nq)  # strict, one-line errors

    # 1. How good is the model, and what is missing? (forward selection of effects,
    #    cross-validated over pose groups, until the held-out error reaches the noise floor)
    first = validate(model, data)
    d = first.diagnosis
    print(f"model {robot}: RMS {first.rms * 1e3:.4f} mm, verdict {d.verdict}: {d.message}")
    floor = d.noise.sigma
    for i, step in enumerate(d.chain):
        ratio = "" if floor is None else f" ({step.rms_after / floor:.2f} x the noise floor)"
        print(f"  step {i + 1}: + {step.label}: held-out RMS {step.rms_before * 1e3:.4f} -> "
              f"{step.rms_after * 1e3:.4f} mm{ratio}, {100 * step.share_explained:.2f} % "
              "explained")
    if d.verdict != "missing":
        print("nothing to add" if d.verdict == "adequate"
              else "no library effect explains most of the residual: nothing to add")
        return data_file

    # 2. Add the named effects, re-identify every parameter, save the improved robot.
    names = list(d.named)
    second = validate(model, data, add=names)
    print(f"with {' + '.join(names)}: RMS {second.rms * 1e3:.4f} mm, held-out "
          f"{second.diagnosis.heldout_rms * 1e3:.4f} mm, verdict {second.diagnosis.verdict}")
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
