"""``rfsw-plan simulate-campaign``: a synthetic load campaign with hidden effects."""

from __future__ import annotations

import argparse

from rfsw_plan.cli.numbers import count, number

NAME = "simulate-campaign"
HELP = "write a measurement CSV of a simulated load campaign with hidden effects"


def _epilog() -> str:
    """The --help epilog (lists the effects: imported only when the help is shown)."""
    from rfsw_plan.validation.campaign.simulation import THERMAL_DRIFT
    from rfsw_plan.validation.engine.candidates import addable_effects

    return f"""\
--hidden EFFECT[:jN][=name:value,...] (repeatable). Effects: {", ".join(
    addable_effects())}, and {THERMAL_DRIFT} (not in the library:
a TCP drift with time, parameters rate_mm_per_h, dir_x, dir_y, dir_z; it also makes the
temperature_C column rise). Values are SI (rad, m, kg, N, N m, kg m), missing ones take the
effect's prior; without '=' the values are random and plausible, scaled up if needed to at
least 10x the noise. Examples: --hidden payload_gravity=m:150,m_rz:-37.5
--hidden joint_backlash:j2=b:3e-4 --hidden tilting_compliance:j3 --hidden {THERMAL_DRIFT}
"""


def register(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _epilog  # type: ignore[assignment]  # computed by format_help
    parser.add_argument("--robot", required=True, help="bundled robot name or robot TOML file")
    parser.add_argument("--hidden", action="append", default=[], metavar="EFFECT[:jN][=PARAMS]",
                        help="hidden effect of the truth model (repeatable)")
    parser.add_argument("--poses", type=count(1, 10_000), default=40,
                        help="number of poses (default 40)")
    parser.add_argument("--loads-per-pose", type=count(1, 100), default=8,
                        help="samples per pose: zero load, +-wrench pairs, zero load (default 8)")
    parser.add_argument("--noise-mm", type=number(0, 100, "mm", why="0 = noise-free"),
                        default=0.01,
                        help="1-sigma position noise per axis [mm] (default 0.01)")
    parser.add_argument("--seed", type=count(0, 2**32 - 1), default=0,
                        help="random seed (default 0)")
    parser.add_argument("-o", "--output", required=True, metavar="FILE.csv",
                        help="measurement CSV to write")
    parser.add_argument("--save-truth", metavar="FILE.toml",
                        help="also write the truth robot description (with the hidden effects)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.files import prepare_output_file, strict_json
    from rfsw_plan.io.measurements import write_measurements
    from rfsw_plan.robot.description import save_robot_description
    from rfsw_plan.robot.kinematics import load_robot
    from rfsw_plan.validation.campaign.simulation import parse_hidden, run_campaign

    prepare_output_file(args.output, "-o")
    if args.save_truth:
        prepare_output_file(args.save_truth, "--save-truth")
    robot = load_robot(args.robot)
    hidden = [parse_hidden(h, robot.nq) for h in args.hidden]
    result = run_campaign(robot, hidden, args.poses, args.loads_per_pose, args.noise_mm,
                          args.seed)
    path = write_measurements(args.output, result.data)
    truth_path = None
    if args.save_truth:
        desc = result.truth.to_description("simulate-campaign truth (joint stiffness unchanged)")
        truth_path = save_robot_description(desc, args.save_truth)
    summary = {
        "file": str(path),
        "robot": robot.name,
        "samples": len(result.data),
        "poses": args.poses,
        "noise_mm": args.noise_mm,
        "hidden": [
            {"effect": lab, "params": p, "contribution_rms_mm": result.contribution_rms_mm[lab]}
            for lab, p in result.hidden.items()
        ],
        "truth_file": None if truth_path is None else str(truth_path),
    }
    if args.json:
        print(strict_json(summary), end="")
        return 0
    print(f"wrote {path}: {len(result.data)} samples, {args.poses} poses, robot {robot.name}, "
          f"noise {args.noise_mm:g} mm")
    for lab, p in result.hidden.items():
        vals = ", ".join(f"{k}={v:.6g}" for k, v in p.items())
        print(f"  hidden {lab}: {vals} ({result.contribution_rms_mm[lab]:.4g} mm RMS)")
    if not result.hidden:
        print("  nothing hidden: the truth is the robot file's model")
    if truth_path is not None:
        print(f"truth model written to {truth_path}")
    return 0
