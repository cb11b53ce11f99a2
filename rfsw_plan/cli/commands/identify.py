"""``rfsw-plan identify``: joint stiffness (and effect parameters) from a measurement file.

Least squares on measured TCP positions (seed 000 eq. 13-15, seed 001 eq. 8-11); see
:func:`rfsw_plan.elastostatics.identification.identify`.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rfsw_plan.cli import measurement_args
from rfsw_plan.exceptions import IdentificationError, UnknownNameError

if TYPE_CHECKING:  # the parser answers before the heavy libraries are imported
    from rfsw_plan.elastostatics.identification import IdentificationResult

NAME = "identify"
HELP = "identify joint stiffness from a measurement CSV and optionally write a new robot file"


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", required=True, metavar="NAME|PATH",
                        help="bundled robot name or robot TOML file (its values are the priors)")
    parser.add_argument("--data", required=True, metavar="FILE",
                        help="measurement CSV (q1_deg.., fx_N.., x_mm..; see the README)")
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


def _num(x: float) -> float | None:
    return None if not math.isfinite(x) else float(x)


def _report(res: IdentificationResult, robot_name: str, output: Path | None) -> dict[str, Any]:
    jc = [e for e in res.estimates if e.effect == "joint_compliance"]
    joints = []
    for j in range(res.stiffness.size):
        note = next((e.note for e in jc if e.name == f"c{j + 1}"), "not free in this fit")
        joints.append({
            "joint": j + 1,
            "stiffness_Nm_per_rad": float(res.stiffness[j]),
            "std_error_Nm_per_rad": _num(float(res.stiffness_std[j])),
            "identified": bool(res.joint_identified[j]),
            "note": note,
        })
    others = [
        {"effect": e.effect, "param": e.name, "value": e.value, "prior": e.prior,
         "std_error": _num(e.std_error), "identified": e.identified, "note": e.note}
        for e in res.estimates if e.effect != "joint_compliance"
    ]
    return {
        "robot": robot_name,
        "method": res.method,
        "joints": joints,
        "effects": others,
        "condition_number": _num(res.condition_number),
        "rms_before_mm": res.rms_before * 1e3,
        "rms_after_mm": res.rms_after * 1e3,
        "sigma_mm": res.sigma * 1e3,
        "n_samples": res.n_samples,
        "n_observations": res.n_observations,
        "converged": res.converged,
        "output": None if output is None else str(output),
    }


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.elastostatics.identification import identify
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.files import prepare_output_file, strict_json
    from rfsw_plan.robot.description import derived_description, save_robot_description
    from rfsw_plan.robot.kinematics import load_robot
    from rfsw_plan.validation.sanity import check_data, check_registered

    if args.output:
        prepare_output_file(args.output, "-o")
    robot = load_robot(args.robot)
    model = ElastostaticModel(robot)
    data = measurement_args.load(args, model)
    free = None if args.free.strip() == "all" else [x.strip() for x in args.free.split(",")]
    unknown = [x for x in free or [] if not model.has(x)]
    if unknown:
        raise UnknownNameError("effect in the model", unknown[0], model.labels)
    check_data(model, data)
    setup = measurement_args.device_setup(args, model, data)
    fit_model, fit_data = model, data
    if setup is not None:
        fit_model, fit_data = setup.model(model), setup.data(data)
        check_registered(fit_model, fit_data)
        if free is not None:
            free = [*free, *setup.effect_labels]
    res = identify(fit_model, fit_data, method=args.method, free=free)
    if not (math.isfinite(res.rms_after) and all(math.isfinite(e.value)
                                                 for e in res.estimates)):
        raise IdentificationError(f"{args.data}: the fit gave non-finite values; nothing "
                                  "written")
    output = None
    if args.output:
        note = (f"identified by rfsw-plan identify ({res.method}, {res.n_samples} samples) "
                f"from {Path(args.data).name}; prior: "
                f"{robot.description.sources.get('stiffness', 'not stated')}")
        if setup is None:
            desc = res.model.to_description(note)
        else:
            base_model, frame = setup.fold(res.model, res.estimates)
            desc = replace(base_model.to_description(note), device_frame=frame)
        before = {e.name for e in robot.description.effects}
        added = tuple(e.label for e in res.model.effects[1:]
                      if not e.setup and e.label not in before)
        desc = derived_description(desc, name=args.name, parent=robot.description.path,
                                   data=args.data, command="rfsw-plan identify", added=added)
        output = save_robot_description(desc, args.output)
    rep = _report(res, robot.name, output)
    if args.json:
        print(strict_json(rep, indent=None), end="")
        return 0
    print(f"robot {robot.name}: {res.n_samples} samples, {res.n_observations} measured values, "
          f"method {res.method}")
    print(f"{'joint':>5}  {'stiffness [N m/rad]':>20}  {'std error':>10}  status")
    for j in rep["joints"]:
        std = "-" if j["std_error_Nm_per_rad"] is None else f"{j['std_error_Nm_per_rad']:.3e}"
        status = "identified" if j["identified"] else "NOT identified"
        if j["note"]:
            status += f": {j['note']}"
        print(f"{j['joint']:>5}  {j['stiffness_Nm_per_rad']:>20.4e}  {std:>10}  {status}")
    for e in rep["effects"]:
        std = "-" if e["std_error"] is None else f"{e['std_error']:.3e}"
        status = "identified" if e["identified"] else "NOT identified"
        if e["note"]:
            status += f": {e['note']}"
        print(f"  {e['effect']}.{e['param']} = {e['value']:.4e} (std {std}) {status}")
    cond = rep["condition_number"]
    print(f"condition number (column-normalised regressor): "
          f"{'n/a' if cond is None else f'{cond:.4g}'}")
    print(f"RMS position residual: before {rep['rms_before_mm']:.4f} mm, "
          f"after {rep['rms_after_mm']:.4f} mm")
    if output is not None:
        print(f"wrote {output}")
    return 0
