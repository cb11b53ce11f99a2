"""``rfsw-plan validate``: compare the model with measurements and find the missing effect."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from rfsw_plan.cli import measurement_args
from rfsw_plan.cli.numbers import count, number
from rfsw_plan.exceptions import InputError

if TYPE_CHECKING:
    from rfsw_plan.progress import Stages
    from rfsw_plan.validation.engine.scoring import Candidate
    from rfsw_plan.validation.report.validate import ReportFiles
    from rfsw_plan.validation.workbench import ValidationResult

NAME = "validate"
HELP = "compare the model with measurements, diagnose the missing effect, add it and re-identify"

def _epilog() -> str:
    """The --help epilog (lists the effects: imported only when the help is shown)."""
    from rfsw_plan.validation.engine.candidates import addable_effects

    return f"""\
Effects for --add: {", ".join(addable_effects())}; per-joint ones
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
                        help="report directory (default: out/validate/<data file stem>)")
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

    report = _report_folder(args)
    names = _STAGES if report is not None else _STAGES[:-1]
    with Stages(NAME, names) as stages:
        return _run(args, report, stages)


#: The steps the progress bar names (the diagnosis draws its own bar over the candidates).
_STAGES = ("reading the data", "diagnosis", "plots and report")


def _report_folder(args: argparse.Namespace) -> Path | None:
    """The report folder: -o as given; none with --no-report, or with --json and no -o; else
    the default folder, or a new one beside it if it already holds an earlier report."""
    from rfsw_plan.files import prepare_output_dir
    from rfsw_plan.validation.commands import fresh_folder

    if args.no_report or (args.json and not args.output):
        return None
    if args.output:
        return prepare_output_dir(args.output)
    return prepare_output_dir(fresh_folder(str(Path("out") / NAME / Path(args.data).stem)))


def _run(args: argparse.Namespace, report: Path | None, stages: Stages) -> int:
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.files import prepare_output_file
    from rfsw_plan.robot.kinematics import load_robot
    from rfsw_plan.validation.commands import run_validate
    from rfsw_plan.validation.report.validate import result_json

    if args.folds < 2:
        raise InputError("--folds", "", f"{args.folds}", "at least 2")
    save = prepare_output_file(args.save_robot, "--save-robot") if args.save_robot else None
    model = ElastostaticModel(load_robot(args.robot))
    data = measurement_args.load(args, model)
    held, marker = measurement_args.device_options(args)
    run_ = run_validate(
        model, data, held=held, marker=marker,
        noise_m=None if args.noise_mm is None else args.noise_mm * 1e-3,
        add=args.add, folds=args.folds, seed=args.seed, force_noise_n=args.force_noise_n,
        report=report, save_robot=save, name=args.name, argv=getattr(args, "argv", None),
        on_stage=stages.start)
    if args.json:
        print(result_json(run_.result))
        return 0
    _print_summary(run_.result, run_.files, run_.saved)
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


def _floor_lines(result: ValidationResult) -> list[str]:
    """RMS, held-out RMS and the noise floor with its parts."""
    dg = result.diagnosis
    nf = dg.noise

    def mm(v: float | None) -> str:
        return "unknown" if v is None else f"{v * 1e3:.3g} mm"

    if nf.force_noise is not None:
        fnoise = f" (force noise {nf.force_noise:.3g} N, {nf.force_noise_source})"
    elif nf.force_noise_source and nf.force_noise_source != "unknown":
        fnoise = f" (force noise unknown: {nf.force_noise_source})"
    else:
        fnoise = " (force noise unknown)"
    return [
        f"RMS {result.rms * 1e3:.4g} mm (3-D {result.rms_3d * 1e3:.4g} mm), held-out RMS "
        f"{dg.heldout_rms * 1e3:.4g} mm, noise floor {mm(nf.sigma)} ({nf.source})",
        f"  floor parts: measuring device {mm(nf.device_sigma)}, force sensor "
        f"{mm(nf.force_sigma)}{fnoise}",
    ]


def _frame_line(result: ValidationResult) -> list[str]:
    """The device registration used, for device-frame data."""
    if result.device_frame is None or result.setup is None:
        return []
    from rfsw_plan.validation.workbench import device_frame_json

    fr = device_frame_json(result.device_frame, result.setup)
    std = ", ".join(f"{k} {v:.3g}" for k, v in fr["std"].items()) or "held, no fit"
    return [f"device frame ({fr['registration']}): base origin in the device frame "
            f"{', '.join(f'{v:.2f}' for v in fr['base_in_device_xyz_mm'])} mm, rpy "
            f"{', '.join(f'{v:.3f}' for v in fr['base_in_device_rpy_deg'])} deg; marker "
            f"({fr['marker']}) {', '.join(f'{v:.2f}' for v in fr['marker_xyz_mm'])} mm in "
            f"the tool frame; std errors: {std}"]


def _add_lines(result: ValidationResult) -> list[str]:
    """Before/after of --add."""
    if result.add is None:
        return []
    ad = result.add
    out = ["added and re-identified:", f"  {'model':<60} {'held-out RMS':>13} {'RMS':>9}"]
    for cv, rms in ((ad.before, ad.rms_before), (ad.after, ad.rms_after)):
        out.append(f"  {', '.join(cv.labels):<60} {cv.heldout_rms * 1e3:10.4g} mm "
                   f"{rms * 1e3:6.4g} mm")
    out += [f"  not fitted: {s.label}: {s.reason}" for s in ad.not_added]
    return out


def _explains(c: Candidate) -> str:
    """What a candidate does to the held-out error, in words (never 'explains -4.4 %')."""
    if c.explained_fraction <= 0:
        return f"explains nothing (held-out error {-100 * c.explained_fraction:.1f} % worse)"
    return f"explains {100 * c.explained_fraction:5.1f} %"


def _candidate_lines(result: ValidationResult) -> list[str]:
    """The best candidates and the clear parameters of the first."""
    dg = result.diagnosis
    if not dg.candidates:
        return []
    out = ["best candidates (held-out RMS after adding):"]
    for c in dg.candidates[:5]:
        flag = "significant" if c.significant else "not significant"
        if not c.plausible:
            flag += f"; implausible: {c.implausible}"
        out.append(f"  {c.label:<34} {c.rms_after * 1e3:8.4g} mm  {_explains(c)}  ({flag})")
    top = dg.candidates[0]
    robot = result.model.robot
    clear = _clear_params(top, robot.joint_names, list(robot.prismatic))
    if clear:
        out.append(f"  {top.label} parameters beyond 2 standard errors: {clear}")
    return out


def _selection_lines(result: ValidationResult) -> list[str]:
    """The forward selection's steps, one line each."""
    dg = result.diagnosis
    if not dg.chain:
        return []
    sigma = dg.noise.sigma
    out = [f"forward selection ({dg.stop}):"]
    for i, s in enumerate(dg.chain):
        ratio = "" if sigma is None else f", {s.rms_after / sigma:.3g} x floor"
        out.append(f"  {i + 1}. + {s.label:<30} held-out RMS {s.rms_before * 1e3:.4g} -> "
                   f"{s.rms_after * 1e3:.4g} mm, share explained "
                   f"{100 * s.share_explained:.2f} %{ratio}"
                   + (f" (cannot tell it from {', '.join(s.ties)})" if s.ties else ""))
    return out


def _print_summary(
    result: ValidationResult, files: ReportFiles | None, saved: Path | None
) -> None:
    dg = result.diagnosis
    lines = [f"robot {result.robot}, {result.analysis.n_samples} samples ({result.dialect}; "
             f"positions in the {'device' if result.setup else 'base'} frame), effects: "
             f"{', '.join(result.model.labels)}",
             *_floor_lines(result), *_frame_line(result), *_add_lines(result),
             f"verdict: {dg.message}", *_candidate_lines(result)]
    lines += _selection_lines(result)
    lines += [f"unknown state: {x.line()}" for x in dg.indeterminate]
    if dg.skipped:
        lines.append("not identifiable from this data: " + ", ".join(s.label for s in dg.skipped))
    if dg.not_supported:
        lines.append("not supported by this data (fit outside the physical range): "
                     + ", ".join(s.label for s in dg.not_supported))
    lines += [f"next campaign: {a}" for a in dg.advice]
    if files is not None:
        lines.append(f"report: {files.html}  json: {files.json}")
    if saved is not None:
        lines.append(f"wrote robot description {saved}")
    print("\n".join(lines))
