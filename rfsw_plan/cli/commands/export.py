"""``rfsw-plan export PLAN_DIR --format krl,fanuc_tp,rapid,stream``: controller programs.

Also the ``--export`` option of ``rfsw-plan plan`` (:func:`add_export_arguments`,
:func:`export_plan_result`). Programs are written, re-read, taken through the robot model and
checked before they get their names (:mod:`rfsw_plan.export.api`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rfsw_plan.cli.numbers import number
from rfsw_plan.exceptions import InputError

if TYPE_CHECKING:
    from rfsw_plan.export.api import ExportResult
    from rfsw_plan.planning.result import PlanResult

NAME = "export"
HELP = "write KUKA KRL, FANUC TP, ABB RAPID programs and a stream file from a written plan"


def add_export_arguments(parser: argparse.ArgumentParser, flag: str) -> None:
    """The export options shared by ``plan --export`` and ``export --format``."""
    parser.add_argument(flag, default=None if flag == "--export" else "krl,fanuc_tp,rapid",
                        metavar="FORMATS",
                        help="comma-separated: krl (.src/.dat), fanuc_tp (.ls), rapid (.mod), "
                             "stream (CSV at the controller cycle)"
                             + ("" if flag == "--export" else " (default krl,fanuc_tp,rapid)"))
    parser.add_argument("--export-spacing-mm", type=number(0.01, 1e4, "mm"), default=None,
                        help="program point spacing along the seam [mm] (default: the plan's)")
    parser.add_argument("--stream-cycle-ms",
                        type=number(0.1, 1000, "ms", why="a robot controller cycle"), default=4.0,
                        help="controller cycle of the stream file [ms] (default 4, RSI/EGM)")
    parser.add_argument("--path-tol-mm", type=number(1e-4, 10, "mm"), default=0.01,
                        help="largest distance of a verified sample from the programmed path "
                             "[mm] (default 0.01)")


def _checked(args: argparse.Namespace) -> tuple[float | None, float, float]:
    sp = args.export_spacing_mm
    if sp is not None and not 0.01 <= sp <= 1e4:
        raise InputError("--export-spacing-mm", "", f"got {sp:g}", "a number in [0.01, 10000]")
    if not 0.1 <= args.stream_cycle_ms <= 1000:
        raise InputError("--stream-cycle-ms", "", f"got {args.stream_cycle_ms:g}",
                         "a number in [0.1, 1000]")
    if not 1e-4 <= args.path_tol_mm <= 10:
        raise InputError("--path-tol-mm", "", f"got {args.path_tol_mm:g}",
                         "a number in [0.0001, 10]")
    return (None if sp is None else sp * 1e-3, args.stream_cycle_ms * 1e-3,
            args.path_tol_mm * 1e-3)


def check_export_arguments(args: argparse.Namespace) -> None:
    """``plan --export``: refuse bad export options before the planning work (exit 2)."""
    if args.export is not None:
        from rfsw_plan.export.api import parse_formats

        parse_formats(args.export, "--export")
        _checked(args)


def export_plan_result(args: argparse.Namespace, result: PlanResult, out: Path,
                       record: dict[str, Any]) -> ExportResult | None:
    """``plan --export``: programs of a plan just written to ``out`` (before its plan.json).

    The re-read points and the stream rows pass the planner's own check of the samples
    (joint limits and the weld window with the plan's model, task and window).
    """
    if args.export is None:
        return None
    from rfsw_plan.export.api import export_programs, parse_formats

    formats = parse_formats(args.export, "--export")
    spacing, cycle, tol = _checked(args)
    stream = _stream_at_cycle(args, result, cycle) if "stream" in formats else None
    return export_programs(result.model.robot, out / "waypoints.csv", record, formats, out,
                           spacing, cycle, tol, check=_plan_check(result), stream=stream)


def _stream_at_cycle(args: argparse.Namespace, result: PlanResult, cycle: float) -> Any:
    """The verified plan timed again by the planner's time parameterisation at the cycle."""
    import numpy as np

    from rfsw_plan.export.stream import samples_of
    from rfsw_plan.planning.verify import seam_frames_at
    from rfsw_plan.process.problem import load_problem
    from rfsw_plan.timing.trajectory import TimingLimits, time_parameterise

    opts = result.options
    process = load_problem(args.problem).process
    traj = time_parameterise(result.model.robot, result.task, result.q, result.offsets,
                             TimingLimits(clearance=opts.clearance,
                                          approach_speed=opts.approach_speed,
                                          plunge_speed=process.plunge_speed, dt=cycle))
    seam = seam_frames_at(result.task, np.asarray(traj.s))[0]
    return samples_of(traj, seam)


def _plan_check(result: PlanResult) -> Any:
    """The planner's sample check for re-read program points and stream rows."""
    import numpy as np

    from rfsw_plan.exceptions import InfeasibleError
    from rfsw_plan.export.program import Samples
    from rfsw_plan.planning import verify

    model, task, window = result.model, result.task, result.window
    d = model.robot.description

    def check(s: Samples) -> None:
        sv = getattr(verify, "verify_samples", None)
        check.__doc__ = ("planning.verify.verify_samples" if sv is not None
                         else "joint limits only")
        if sv is not None:
            sv(model, task, window, s).raise_if_failed()
            return
        lim = np.minimum(s.q - d.lower, d.upper - s.q)  # before trust's verify_samples lands
        if np.any(lim < -1e-7):
            raise InfeasibleError("exported point outside the joint limits", None,
                                  "joint_limit", float(np.min(lim)))

    return check


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("plan_dir", help="folder written by rfsw-plan plan (plan.json, "
                                         "waypoints.csv)")
    parser.add_argument("-o", "--output", default=None,
                        help="output folder for the programs (default: PLAN_DIR)")
    add_export_arguments(parser, "--format")
    parser.add_argument("--json", action="store_true", help="print the export record")


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.export.api import export_programs, parse_formats
    from rfsw_plan.files import OutputLock, prepare_output_dir, strict_json, write_json
    from rfsw_plan.planfiles.waypoints import check_plan_folder
    from rfsw_plan.robot.kinematics import load_robot

    folder = Path(args.plan_dir)
    if not folder.is_dir():
        raise InputError(folder, "", "not a folder", "a plan folder written by rfsw-plan plan")
    formats = parse_formats(args.format, "--format")
    spacing, cycle, tol = _checked(args)
    rec = check_plan_folder(folder)
    robot = load_robot(rec.get("robot_file") or rec.get("robot") or "")
    out = prepare_output_dir(args.output if args.output else folder)
    with OutputLock(out):
        res = export_programs(robot, folder / "waypoints.csv", rec, formats, out, spacing,
                              cycle, tol)
        record = {"status": "exported", "plan": str(folder), **res.to_dict()}
        write_json(out / "export.json", record)
    if args.json:
        print(strict_json(record), end="")
        return 0
    print(f"{res.header.plan_id}: {res.n_points} points at {res.header.spacing * 1e3:.3g} mm, "
          f"path within {tol * 1e3:.3g} mm of the verified samples")
    for fmt, trip in res.round_trips.items():
        print(f"  {fmt:<9} round trip: {trip.summary()}")
    for f in res.files:
        print(f"  wrote {f}", file=sys.stdout)
    return 0
