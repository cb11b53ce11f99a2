"""``rfsw-plan validate-weld PLAN_DIR --track TRACK.csv``: the plan against the measured weld."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

from rfsw_plan.cli.numbers import count

if TYPE_CHECKING:
    from rfsw_plan.progress import Stages
    from rfsw_plan.validation.engine.scoring import Candidate
    from rfsw_plan.validation.weld.workbench import WeldValidation

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
    from rfsw_plan.exceptions import InputError
    from rfsw_plan.files import prepare_output_dir, prepare_output_file, strict_json
    from rfsw_plan.validation.commands import run_validate_weld

    if args.blocks < 2:
        raise InputError("--blocks", "", f"{args.blocks}", "at least 2")
    if args.name is not None and not args.save_robot:
        raise InputError("--name", args.name, "given without --save-robot",
                         "--save-robot NEW.toml --name NAME")
    out = prepare_output_dir(args.output or Path(args.plan_dir) / "validate_weld")
    save = prepare_output_file(args.save_robot, "--save-robot") if args.save_robot else None
    run_ = run_validate_weld(
        args.plan_dir, args.track, out, forces=args.forces, forces_frame=args.forces_frame,
        problem=args.problem, robot=args.robot, add=args.add, save_robot=save, name=args.name,
        blocks=args.blocks, on_stage=stages.start)
    if args.json:  # validate_weld.json without the samples
        data = json.loads(run_.files.json.read_text())
        data.pop("samples", None)
        print(strict_json(data), end="")
        return 0
    _print(run_.result, run_.files.html, run_.saved, run_.next)
    return 0


def _candidate_line(c: Candidate, best: Candidate | None) -> str:
    k = c.stiffness_scale
    return (f"  {c.label:<32} {c.rms_after * 1e3:8.4f} mm  "
            f"{'significant' if c.significant else 'not significant'}"
            f"{'' if c.identifiable else ', not identifiable alone'}"
            f"{'' if k is None else f' stiffness x{k:.3f}'}"
            f"{'' if c.plausible else f', IMPLAUSIBLE ({c.implausible})'}"
            f"{'  <- named' if best is not None and c.label == best.label else ''}")


def _print(r: WeldValidation, html: Path, saved: Path | None, nxt: str) -> None:
    dg = r.diagnosis
    js = r.to_json()
    rl = js["residual_lat"]
    lines = [
        f"{r.plan.problem.name}: track {r.track.s.size} points over s = "
        f"{r.track.overlap[0] * 1e3:.1f}..{r.track.overlap[1] * 1e3:.1f} mm of "
        f"{r.track.seam_length * 1e3:.1f} mm ({r.track.gaps} gaps), forces: {r.forces_source}",
        f"measured inside the window {100 * js['measured_inside_window_fraction']:.1f} % "
        f"(predicted {100 * js['predicted_inside_window_fraction']:.1f} %); lateral "
        f"residual RMS {rl['rms_mm']:.4f} mm, max {rl['max_abs_mm']:.4f} mm, noise floor "
        f"{dg.sigma * 1e3:.4f} mm",
        f"verdict: {dg.message}",
        dg.identifiability.text(),
    ]
    if dg.candidates:
        lines.append("best candidates (held-out RMS over blocks of s, lowest first):")
        lines += [_candidate_line(c, dg.best) for c in dg.candidates[:6]]
    if r.add is not None:
        a = r.add
        lines.append(f"added {', '.join(a.labels)}: lateral+normal RMS "
                     f"{a.rms_before * 1e3:.4f} -> {a.rms_after * 1e3:.4f} mm (held-out "
                     f"{a.heldout_after * 1e3:.4f} mm)")
    lines += [f"note: {n}" for n in r.notes]
    if saved is not None:
        lines.append(f"wrote robot {saved}")
    lines += [f"report: {html}", f"next: {nxt}"]
    print("\n".join(lines))
