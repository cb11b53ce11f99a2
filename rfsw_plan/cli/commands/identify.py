"""``rfsw-plan identify``: joint stiffness (and effect parameters) from a measurement file.

Least squares on measured TCP positions (seed 000 eq. 13-15, seed 001 eq. 8-11): parses the
options, calls :func:`rfsw_plan.validation.identify_robot.identify_robot`, prints.
"""

from __future__ import annotations

import argparse
from typing import Any

from rfsw_plan.cli import measurement_args

NAME = "identify"
HELP = "identify joint stiffness from a measurement CSV and optionally write a new robot file"


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", required=True, metavar="NAME|PATH",
                        help="bundled robot name or robot TOML file (its values are the priors)")
    parser.add_argument("--data", required=True, metavar="FILE",
                        help="measurement CSV (q1_deg.., fx_N.., x_mm..; format: "
                             "docs/formats/measurements.md)")
    parser.add_argument("--method", choices=("ols", "wls"), default="ols",
                        help="ordinary (seed 000 eq. 15) or weighted least squares "
                        "(weights from sigma_mm, else from per-axis residuals)")
    parser.add_argument("--free", default="joint_compliance", metavar="LABEL[,LABEL...]",
                        help="effects to identify (default: joint_compliance; the robot file's "
                        "other effects keep their values); 'all' frees every effect")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--name", metavar="NAME", default=None,
                        help="robot name in the -o file (default: the robot's name + "
                             "'identified' or the added effects)")
    parser.add_argument("-o", "--output", metavar="NEW_ROBOT_FILE",
                        help="write the robot description with the identified values (TOML)")
    measurement_args.register(parser)


def run(args: argparse.Namespace) -> int:
    # The heavy libraries load here, so the parser answers a bad option at once.
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.files import prepare_output_file, strict_json
    from rfsw_plan.robot.kinematics import load_robot
    from rfsw_plan.validation.identify_robot import identify_robot

    if args.output:
        prepare_output_file(args.output, "-o")
    model = ElastostaticModel(load_robot(args.robot))
    data = measurement_args.load(args, model)
    held, marker = measurement_args.device_options(args)
    free = None if args.free.strip() == "all" else [x.strip() for x in args.free.split(",")]
    out = identify_robot(model, data, method=args.method, free=free, held=held, marker=marker,
                         output=args.output or None, name=args.name)
    rep = out.to_json()
    if args.json:
        print(strict_json(rep, indent=None), end="")
        return 0
    _print(rep)
    return 0


def _status(identified: bool, note: str) -> str:
    return ("identified" if identified else "NOT identified") + (f": {note}" if note else "")


def _print(rep: dict[str, Any]) -> None:
    """The text summary of ``identify`` (from its JSON object)."""
    print(f"robot {rep['robot']}: {rep['n_samples']} samples, {rep['n_observations']} measured "
          f"values, method {rep['method']}")
    print(f"{'joint':>5}  {'stiffness [N m/rad]':>20}  {'std error':>10}  status")
    for j in rep["joints"]:
        std = "-" if j["std_error_Nm_per_rad"] is None else f"{j['std_error_Nm_per_rad']:.3e}"
        print(f"{j['joint']:>5}  {j['stiffness_Nm_per_rad']:>20.4e}  {std:>10}  "
              f"{_status(j['identified'], j['note'])}")
    for e in rep["effects"]:
        std = "-" if e["std_error"] is None else f"{e['std_error']:.3e}"
        print(f"  {e['effect']}.{e['param']} = {e['value']:.4e} (std {std}) "
              f"{_status(e['identified'], e['note'])}")
    cond = rep["condition_number"]
    print(f"condition number (column-normalised regressor): "
          f"{'n/a' if cond is None else f'{cond:.4g}'}")
    print(f"RMS position residual: before {rep['rms_before_mm']:.4f} mm, "
          f"after {rep['rms_after_mm']:.4f} mm")
    if rep["output"] is not None:
        print(f"wrote {rep['output']}")
