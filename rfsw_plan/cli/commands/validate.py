"""``rfsw-plan validate``: compare the model with measurements and find the missing effect."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from rfsw_plan.cli import measurement_args
from rfsw_plan.cli.numbers import count, number
from rfsw_plan.exceptions import InputError

if TYPE_CHECKING:
    from rfsw_plan.progress import Stages
    from rfsw_plan.validation.diagnosis import Candidate
    from rfsw_plan.validation.report import ReportFiles
    from rfsw_plan.validation.workbench import ValidationResult

NAME = "validate"
HELP = "compare the model with measurements, diagnose the missing effect, add it and re-identify"

def _epilog() -> str:
    """The --help epilog (lists the effects: imported only when the help is shown)."""
    from rfsw_plan.elastostatics.effects import EFFECTS

    return f"""\
Effects for --add: {", ".join(n for n, c in EFFECTS.items()
    if n != "joint_compliance" and not c.setup)}; per-joint ones
take :jN (1-based), e.g. --add tilting_compliance:j2 --add payload_gravity.
Verdicts: adequate (held-out residual at the noise floor), missing (names the effect and
joint), undetermined (no noise floor: no repeats, no --noise-mm, and nothing significant
left; a model is never called adequate on significance alone), unexplained (no library
effect reaches the noise floor; see what the residual
correlates with). The loop: validate -> validate --add EFFECT --save-robot NEW.toml ->
validate --robot NEW.toml ... until adequate.
"""


def register(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _epilog  # type: ignore[assignment]  # computed by format_help
    parser.add_argument("--robot", required=True, help="bundled robot name or robot TOML file")
    parser.add_argument("--data", required=True, metavar="FILE.csv", help="measurement CSV")
    parser.add_argument("-o", "--output", metavar="DIR",
                        help="report directory (default: validate_<data file stem>)")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object on stdout instead of the text summary")
    parser.add_argument("--noise-mm", metavar="S",
                        type=number(1e-4, 100, "mm", why="a position noise a device can have"),
                        help="1-sigma position noise [mm] (default: from repeated samples)")
    parser.add_argument("--force-noise-N", dest="force_noise_n",
                        type=number(1e-3, 1e4, "N", why="a force sensor's noise"), metavar="S",
                        help="1-sigma force sensor noise [N] (default: from the spread of "
                        "zero-load readings); propagated through the compliance into the floor")
    parser.add_argument("--add", action="append", default=[], metavar="EFFECT[:jN]",
                        help="add an effect and re-identify all parameters (repeatable)")
    parser.add_argument("--save-robot", metavar="NEW_FILE.toml",
                        help="write the re-identified (extended) robot description")
    parser.add_argument("--name", metavar="NAME", default=None,
                        help="robot name in the --save-robot file (default: the robot's name "
                             "plus the added effects, e.g. zk500+payload_gravity)")
    parser.add_argument("--folds", type=count(2, 1000), default=5,
                        help="cross-validation folds (default 5)")
    parser.add_argument("--seed", type=count(0, 2**32 - 1), default=0,
                        help="seed of the fold split (default 0)")
    parser.add_argument("--no-report", action="store_true",
                        help="do not write report.html, PNGs and validate.json")
    measurement_args.register(parser)


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.progress import Stages

    names = _STAGES if not args.no_report else _STAGES[:-1]
    with Stages(NAME, names) as stages:
        return _run(args, stages)


#: The steps the progress bar names (the diagnosis draws its own bar over the candidates).
_STAGES = ("reading the data", "diagnosis", "plots and report")


def _run(args: argparse.Namespace, stages: Stages) -> int:
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.robot.kinematics import load_robot
    from rfsw_plan.validation.report import result_json, write_report
    from rfsw_plan.validation.workbench import save_extended_robot, validate

    if args.noise_mm is not None and not args.noise_mm > 0:
        raise InputError("--noise-mm", "", f"{args.noise_mm:g}", "a positive noise in mm")
    if args.folds < 2:
        raise InputError("--folds", "", f"{args.folds}", "at least 2")
    from rfsw_plan.files import OutputLock, prepare_output_dir, prepare_output_file
    from rfsw_plan.validation.sanity import check_data, check_registered

    out = None
    if not args.no_report:
        out = prepare_output_dir(args.output if args.output
                                 else Path(f"validate_{Path(args.data).stem}"))
    if args.save_robot:
        prepare_output_file(args.save_robot, "--save-robot")
    robot = load_robot(args.robot)
    model = ElastostaticModel(robot)
    data = measurement_args.load(args, model)
    check_data(model, data)
    setup = measurement_args.device_setup(args, model, data)
    if setup is not None:
        check_registered(setup.model(model), setup.data(data))
    stages.start("diagnosis")
    result = validate(
        model, data,
        noise_m=None if args.noise_mm is None else args.noise_mm * 1e-3,
        add=args.add, folds=args.folds, seed=args.seed, setup=setup,
        force_noise_n=args.force_noise_n,
    )
    files = None
    if out is not None:
        stages.start("plots and report")
        with OutputLock(out):
            files = write_report(result, out, argv=getattr(args, "argv", None),
                                 started=getattr(args, "started", None))
    saved = (save_extended_robot(result, args.save_robot, name=args.name) if args.save_robot
             else None)
    if args.json:
        print(result_json(result))
        return 0
    _print_summary(result, files, saved)
    return 0


def _clear_params(cand: Candidate, joint_names: list[str], prismatic: list[bool]) -> str:
    """The candidate's parameters beyond 2 standard errors, joint offsets by joint name."""
    parts = []
    for name, value in cand.params.items():
        std = cand.std.get(name, float("nan"))
        if not (abs(value) > 2 * std):
            continue
        if name.startswith("dq") and name[2:].isdigit():
            j = int(name[2:]) - 1
            label = joint_names[j] if j < len(joint_names) else name
            unit = "mm" if j < len(prismatic) and prismatic[j] else "mrad"
            parts.append(f"{label} offset {value * 1e3:.3g} +- {std * 1e3:.2g} {unit}")
        else:
            parts.append(f"{name} {value:.4g} +- {std:.2g}")
    return ", ".join(parts)


def _print_summary(
    result: ValidationResult, files: ReportFiles | None, saved: Path | None
) -> None:
    dg = result.diagnosis
    out = sys.stdout
    noise = "unknown" if dg.noise.sigma is None else f"{dg.noise.sigma * 1e3:.4g} mm"
    print(f"robot {result.robot}, {result.analysis.n_samples} samples ({result.dialect}; "
          f"positions in the {'device' if result.setup else 'base'} frame), effects: "
          f"{', '.join(result.model.labels)}", file=out)
    print(f"RMS {result.rms * 1e3:.4g} mm (3-D {result.rms_3d * 1e3:.4g} mm), held-out RMS "
          f"{dg.heldout_rms * 1e3:.4g} mm, noise floor {noise} ({dg.noise.source})", file=out)
    nf = dg.noise

    def _mm(v: float | None) -> str:
        return "unknown" if v is None else f"{v * 1e3:.3g} mm"

    fnoise = "unknown" if nf.force_noise is None else f"{nf.force_noise:.3g} N"
    print(f"  floor parts: measuring device {_mm(nf.device_sigma)}, force sensor "
          f"{_mm(nf.force_sigma)} (force noise {fnoise}, {nf.force_noise_source})", file=out)
    if result.device_frame is not None and result.setup is not None:
        from rfsw_plan.validation.workbench import device_frame_json

        fr = device_frame_json(result.device_frame, result.setup)
        std = ", ".join(f"{k} {v:.3g}" for k, v in fr["std"].items()) or "held, no fit"
        print(f"device frame ({fr['registration']}): base origin in the device frame "
              f"{', '.join(f'{v:.2f}' for v in fr['base_in_device_xyz_mm'])} mm, rpy "
              f"{', '.join(f'{v:.3f}' for v in fr['base_in_device_rpy_deg'])} deg; marker "
              f"({fr['marker']}) {', '.join(f'{v:.2f}' for v in fr['marker_xyz_mm'])} mm in "
              f"the tool frame; std errors: {std}", file=out)
    if result.add is not None:
        ad = result.add
        print("added and re-identified:", file=out)
        print(f"  {'model':<60} {'held-out RMS':>13} {'RMS':>9}", file=out)
        for cv, rms in ((ad.before, ad.rms_before), (ad.after, ad.rms_after)):
            print(f"  {', '.join(cv.labels):<60} {cv.heldout_rms * 1e3:10.4g} mm "
                  f"{rms * 1e3:6.4g} mm", file=out)
        for s in ad.not_added:
            print(f"  not fitted: {s.label}: {s.reason}", file=out)
    print(f"verdict: {dg.message}", file=out)
    if dg.candidates:
        print("best candidates (held-out RMS after adding):", file=out)
        for c in dg.candidates[:5]:
            flag = "significant" if c.significant else "not significant"
            print(f"  {c.label:<34} {c.rms_after * 1e3:8.4g} mm  explains "
                  f"{100 * c.explained_fraction:5.1f} %  ({flag})", file=out)
        top = dg.candidates[0]
        robot = result.model.robot
        clear = _clear_params(top, robot.joint_names, list(robot.prismatic))
        if clear:
            print(f"  {top.label} parameters beyond 2 standard errors: {clear}", file=out)
    if dg.skipped:
        print("not identifiable from this data: "
              + ", ".join(s.label for s in dg.skipped), file=out)
    if files is not None:
        print(f"report: {files.html}  json: {files.json}", file=out)
    if saved is not None:
        print(f"wrote robot description {saved}", file=out)
