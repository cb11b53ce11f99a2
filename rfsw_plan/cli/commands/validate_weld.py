"""``rfsw-plan validate-weld PLAN_DIR --track TRACK.csv``: the plan against the measured weld."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from rfsw_plan.cli.numbers import count

if TYPE_CHECKING:
    from rfsw_plan.progress import Stages

NAME = "validate-weld"
HELP = ("compare a trial weld's measured track with the plan's predicted pin path, diagnose "
        "what the model misses, re-identify and save the robot")

_EPILOG = """\
TRACK.csv: s_mm, e_lat_mm[, e_norm_mm] (offset of the weld from the joint line along the
seam, advancing side +) or x_mm, y_mm, z_mm (weld centreline in the robot base frame,
projected onto the seam); empty cells are gaps.
Candidates: joint_compliance:jN (the stiffness of joint N) and every library effect the robot
file lacks (e.g. tilting_compliance:j2). The loop: plan -> weld -> validate-weld ->
validate-weld --add BEST --save-robot NEW.toml -> plan PROBLEM --forces LOG --robot NEW.toml.
"""


def register(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG
    parser.add_argument("plan_dir", metavar="PLAN_DIR", help="output folder of rfsw-plan plan")
    parser.add_argument("--track", required=True, metavar="TRACK.csv",
                        help="measured weld track (see below)")
    parser.add_argument("--forces", metavar="LOG.csv", default=None,
                        help="force log of the weld (default: the planned forces)")
    parser.add_argument("--forces-frame", choices=("base", "seam", "tool"), default=None,
                        help="frame of the force log if it has no 'frame' column")
    parser.add_argument("--problem", default=None,
                        help="problem file (default: the one plan.json names)")
    parser.add_argument("--robot", default=None,
                        help="current robot model (default: the one the plan was made with)")
    parser.add_argument("-o", "--output", metavar="DIR", default=None,
                        help="report folder (default: PLAN_DIR/validate_weld)")
    parser.add_argument("--json", action="store_true",
                        help="print validate_weld.json (without the samples) on stdout")
    parser.add_argument("--add", action="append", default=[], metavar="EFFECT[:jN]",
                        help="add a candidate and re-identify it from the weld (repeatable)")
    parser.add_argument("--save-robot", metavar="NEW.toml", default=None,
                        help="write the re-identified robot (needs --add)")
    parser.add_argument("--name", metavar="NAME", default=None,
                        help="robot name in the --save-robot file (default: the robot's name "
                             "plus the added labels, e.g. zk500+joint_compliance:j1)")
    parser.add_argument("--blocks", type=count(2, 1000), default=5,
                        help="blocks of s for the cross-validation (default 5)")


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.progress import Stages

    with Stages(NAME, _STAGES) as stages:
        return _run(args, stages)


#: The steps the progress bar names (the diagnosis draws its own bar over the candidates).
_STAGES = ("reading the plan, track and forces", "diagnosis", "plots and report")


def _run(args: argparse.Namespace, stages: Stages) -> int:
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.exceptions import InputError
    from rfsw_plan.files import OutputLock, prepare_output_dir, prepare_output_file
    from rfsw_plan.io.force_series import read_force_series
    from rfsw_plan.io.weld_track import read_weld_track
    from rfsw_plan.robot.description import derived_description, save_robot_description
    from rfsw_plan.robot.kinematics import load_robot
    from rfsw_plan.validation.weld import next_command, read_plan_dir, validate_weld
    from rfsw_plan.validation.weld_report import write_weld_report

    if args.save_robot and not args.add:
        raise InputError("--save-robot", args.save_robot, "given without --add",
                         "--add EFFECT --save-robot NEW.toml (the weld re-identifies only what "
                         "you add)")
    if args.blocks < 2:
        raise InputError("--blocks", "", f"{args.blocks}", "at least 2")
    out = prepare_output_dir(args.output or Path(args.plan_dir) / "validate_weld")
    if args.name is not None and not args.save_robot:
        raise InputError("--name", args.name, "given without --save-robot",
                         "--save-robot NEW.toml --name NAME")
    save = prepare_output_file(args.save_robot, "--save-robot") if args.save_robot else None
    record = read_plan_dir(args.plan_dir, args.problem)
    track = read_weld_track(args.track)
    series = read_force_series(args.forces, args.forces_frame) if args.forces else None
    if args.forces_frame and not args.forces:
        raise InputError("--forces-frame", "", "given without --forces", "--forces LOG.csv")
    model = ElastostaticModel(load_robot(args.robot or record.problem.robot))
    with OutputLock(out):
        stages.start("diagnosis")
        result = validate_weld(record, track, series, model, add=args.add, blocks=args.blocks)
        saved = None
        if save is not None and result.add is not None:
            a = result.add
            note = (f"re-identified by rfsw-plan validate-weld from {args.track} (plan "
                    f"{args.plan_dir}): {', '.join(a.labels)}; lateral RMS "
                    f"{a.rms_before * 1e3:.4g} -> {a.rms_after * 1e3:.4g} mm")
            # The same compact, provenance-carrying writer as validate --save-robot.
            desc = derived_description(
                a.model.to_description(note), name=args.name,
                parent=model.robot.description.path, data=args.track,
                command="rfsw-plan validate-weld", added=tuple(a.labels), forces=args.forces)
            saved = save_robot_description(desc, save)
        nxt = next_command(result, args.plan_dir, args.track, args.forces, saved)
        stages.start("plots and report")
        files = write_weld_report(result, out, nxt, {"saved_robot": str(saved) if saved else None})
    if args.json:
        data = json.loads(files.json.read_text())
        data.pop("samples", None)
        print(json.dumps(data, indent=2))
        return 0
    _print(result, files.html, saved, nxt)
    return 0


def _print(result: object, html: Path, saved: Path | None, nxt: str) -> None:
    from rfsw_plan.validation.weld import WeldValidation

    assert isinstance(result, WeldValidation)
    r = result
    dg = r.diagnosis
    js = r.to_json()
    out = sys.stdout
    print(f"{r.plan.problem.name}: track {r.track.s.size} points over s = "
          f"{r.track.overlap[0] * 1e3:.1f}..{r.track.overlap[1] * 1e3:.1f} mm of "
          f"{r.track.seam_length * 1e3:.1f} mm ({r.track.gaps} gaps), forces: "
          f"{r.forces_source}", file=out)
    rl = js["residual_lat"]
    print(f"measured inside the window {100 * js['measured_inside_window_fraction']:.1f} % "
          f"(predicted {100 * js['predicted_inside_window_fraction']:.1f} %); lateral "
          f"residual RMS {rl['rms_mm']:.4f} mm, max {rl['max_abs_mm']:.4f} mm, noise floor "
          f"{dg.sigma * 1e3:.4f} mm", file=out)
    print(f"verdict: {dg.message}", file=out)
    print(dg.identifiability.text(), file=out)
    if dg.candidates:
        print("best candidates (held-out RMS over blocks of s):", file=out)
        for c in dg.candidates[:6]:
            k = c.stiffness_scale
            extra = f" stiffness x{k:.3f}" if k is not None else ""
            print(f"  {c.label:<32} {c.heldout_rms * 1e3:8.4f} mm  "
                  f"{'significant' if c.significant else 'not significant'}"
                  f"{'' if c.identifiable else ', not identifiable alone'}{extra}", file=out)
    if r.add is not None:
        a = r.add
        print(f"added {', '.join(a.labels)}: lateral+normal RMS {a.rms_before * 1e3:.4f} -> "
              f"{a.rms_after * 1e3:.4f} mm (held-out {a.heldout_after * 1e3:.4f} mm)", file=out)
    for n in r.notes:
        print(f"note: {n}", file=out)
    if saved is not None:
        print(f"wrote robot {saved}", file=out)
    print(f"report: {html}", file=out)
    print(f"next: {nxt}", file=out)
