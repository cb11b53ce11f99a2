"""``rfsw-plan export PLAN_DIR [--format krl,rapid]``: controller programs (default: every format).

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
    parser.add_argument(flag, default=None, metavar="FORMATS",
                        help="comma-separated formats: krl (.src/.dat), fanuc_tp (.ls), rapid "
                             "(.mod), stream (CSV), or any registered format"
                             + ("" if flag == "--export" else
                                " (default: every registered format)"))
    parser.add_argument("--export-spacing-mm", type=number(0.01, 1e4, "mm"), default=None,
                        help="program point spacing along the seam [mm] (default: the plan's)")
    parser.add_argument("--stream-cycle-ms",
                        type=number(0.1, 1000, "ms", why="a robot controller cycle"), default=None,
                        help="controller cycle of the stream file [ms]; plan --export times the "
                             "plan at it (default 4, RSI/EGM); export writes the plan's own "
                             "samples, so it must be the plan's sample time (the default)")
    parser.add_argument("--path-tol-mm", type=number(1e-4, 10, "mm"), default=0.01,
                        help="largest distance of a verified sample from the path the "
                             "controller runs, blending included [mm] (default 0.01)")
    parser.add_argument("--tool-number", type=int, default=1,
                        help="tool number: FANUC UTOOL n (and with --cell-data KUKA "
                             "TOOL_DATA/LOAD_DATA[n], FANUC PAYLOAD[n]) (default 1)")
    parser.add_argument("--base-number", type=int, default=1,
                        help="base number: FANUC UFRAME n (and with --cell-data KUKA "
                             "BASE_DATA[n]) (default 1)")
    parser.add_argument("--cell-data", action="store_true",
                        help="write the tool, base and payload into the controller's numbered "
                             "data (KUKA TOOL_DATA/BASE_DATA/LOAD_DATA, FANUC UFRAME/UTOOL "
                             "through PR[91]/PR[92] and PAYLOAD), replacing what the cell had "
                             "there; default: leave them alone (KRL sets $TOOL/$BASE/$LOAD, "
                             "FANUC lists the values to enter)")
    parser.add_argument("--hooks", metavar="FILE.toml", default=None,
                        help="process hook lines per format (home_start, spindle_start, "
                             "force_on, force_off, spindle_stop, home_end); default: comments "
                             "saying what belongs there")


def _checked(args: argparse.Namespace) -> tuple[float | None, float | None, float]:
    sp = args.export_spacing_mm
    if sp is not None and not 0.01 <= sp <= 1e4:
        raise InputError("--export-spacing-mm", "", f"got {sp:g}", "a number in [0.01, 10000]")
    cyc = args.stream_cycle_ms
    if cyc is not None and not 0.1 <= cyc <= 1000:
        raise InputError("--stream-cycle-ms", "", f"got {cyc:g}", "a number in [0.1, 1000]")
    if not 1e-4 <= args.path_tol_mm <= 10:
        raise InputError("--path-tol-mm", "", f"got {args.path_tol_mm:g}",
                         "a number in [0.0001, 10]")
    for opt, v in (("--tool-number", args.tool_number), ("--base-number", args.base_number)):
        if not 1 <= v <= 32:
            raise InputError(opt, "", f"got {v}", "a number in 1..32")
    return (None if sp is None else sp * 1e-3, None if cyc is None else cyc * 1e-3,
            args.path_tol_mm * 1e-3)


def _options(args: argparse.Namespace) -> Any:
    from rfsw_plan.export.program import Hooks, ProgramOptions, read_hooks

    hooks = read_hooks(args.hooks) if args.hooks else Hooks()
    return ProgramOptions(args.tool_number, args.base_number, hooks,
                          cell_data=bool(getattr(args, "cell_data", False)))


def check_export_arguments(args: argparse.Namespace) -> None:
    """``plan --export``: refuse bad export options before the planning work (exit 2)."""
    if args.export is not None:
        from rfsw_plan.export.format import parse_formats

        parse_formats(args.export, "--export")
        _checked(args)
        _options(args)


def export_plan_result(args: argparse.Namespace, result: PlanResult, out: Path,
                       record: dict[str, Any]) -> ExportResult | None:
    """``plan --export``: programs of a plan just written to ``out`` (before its plan.json).

    The re-read points and the stream rows pass the planner's own check of the samples
    (joint limits and the weld window with the plan's model, task and window).
    """
    if args.export is None:
        return None
    from rfsw_plan.export.api import export_programs, plate_surface
    from rfsw_plan.export.check import PlanBasis
    from rfsw_plan.export.format import parse_formats
    from rfsw_plan.files import sha256_file
    from rfsw_plan.planfiles.folder import read_plan_samples

    formats = parse_formats(args.export, "--export")
    spacing, cycle, tol = _checked(args)
    cycle = 0.004 if cycle is None else cycle
    stream = _stream_at_cycle(args, result, cycle) if "stream" in formats else None
    d = result.model.robot.description
    samples = read_plan_samples(out / "waypoints.csv", d.convention.column_names(),
                                (d.lower, d.upper))
    normal, depth, reference, _ = plate_surface(str(record.get("problem_file") or args.problem),
                                                samples)
    basis = PlanBasis(samples, record, str(record.get("problem_file") or args.problem),
                      result.model, result.task, result.window)
    res = export_programs(result.model.robot, samples, record, formats, out,
                          plan_sha256=sha256_file(out / "waypoints.csv"), spacing=spacing,
                          path_tol=tol, check=_plan_check(result), stream=stream,
                          cycle=cycle, options=_options(args), normal=normal, depth=depth,
                          reference=reference, basis=basis)
    for note in res.notes:
        if note.startswith(("PAYLOAD UNKNOWN", "WORK OBJECT")):
            print(f"rfsw-plan plan: note: {note}", file=sys.stderr)
    return res


def _stream_at_cycle(args: argparse.Namespace, result: PlanResult, cycle: float) -> Any:
    """The verified plan timed again by the planner's time parameterisation at the cycle."""
    import numpy as np

    from rfsw_plan.export.stream import samples_of
    from rfsw_plan.planning.api import deflection_of
    from rfsw_plan.planning.verify import seam_frames_at
    from rfsw_plan.process.problem import load_problem
    from rfsw_plan.timing.trajectory import time_parameterise, timing_limits

    opts = result.options
    process = load_problem(args.problem).process
    traj = time_parameterise(result.model.robot, result.task, result.q, result.offsets,
                             timing_limits(opts, process, cycle),
                             deflection_of(result.model, result.task))
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
        if sv is not None:  # the failures alone: the judge computes the claim as run
            sv(model, task, window, s, robust=False).raise_if_failed()
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
                        help="output folder for the programs (default: PLAN_DIR, whose "
                             "plan.json then vouches for them)")
    add_export_arguments(parser, "--format")
    parser.add_argument("--json", action="store_true", help="print the export record")


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.export.api import export_plan_folder
    from rfsw_plan.export.format import format_names, parse_formats
    from rfsw_plan.files import OutputLock, prepare_output_dir, strict_json

    folder = Path(args.plan_dir)
    if not folder.is_dir():
        raise InputError(folder, "", "not a folder", "a plan folder written by rfsw-plan plan")
    formats = (parse_formats(args.format, "--format") if args.format is not None
               else list(format_names()))
    spacing, cycle, tol = _checked(args)
    options = _options(args)
    out = prepare_output_dir(args.output if args.output else folder)
    with OutputLock(out):
        if cycle is not None and "stream" in formats:
            _check_cycle(folder, cycle)
        res = export_plan_folder(folder, formats, out, spacing=spacing, path_tol=tol,
                                 options=options)
    record = {"status": "exported", "plan": str(folder), **res.to_dict(),
              "files": [str(f) for f in res.files]}  # printed: paths the user can open
    for note in res.notes:
        if note.startswith(("PAYLOAD UNKNOWN", "WORK OBJECT", "plate normal")):
            print(f"rfsw-plan export: note: {note}", file=sys.stderr)
    if args.json:
        print(strict_json(record), end="")
        return 0
    for line in res.below_plan():  # what the controller will run, said first
        print(line)
    # The round trips and `check` count the points a motion moves to; a point held by a wait
    # (the dwell) is one of the program's points but not a move: both numbers, named.
    moved = res.n_moved if res.n_moved >= 0 else \
        min((len(t.q) for t in res.round_trips.values()), default=res.n_points)
    held = res.n_points - moved
    points = f"{res.n_points} points" + (f" ({moved} moved to, {held} held by a wait)"
                                         if 0 < held < res.n_points else "")
    print(f"{res.header.plan_id}: {points} at {res.header.spacing * 1e3:.3g} mm, "
          f"path within {res.max_path_deviation * 1e3:.4f} mm of the verified samples "
          f"(tolerance {tol * 1e3:.3g} mm, blending included)")
    for fmt, trip in res.round_trips.items():
        u = res.held_as_run.get(fmt)
        run = "" if u is None else f"; as run it holds +-{100 * u[0]:.2f} % ({u[1]} first)"
        print(f"  {fmt:<9} round trip: {trip.summary()}{run}")
    for f in res.files:
        print(f"  wrote {f}")
    return 0


def _check_cycle(folder: Path, cycle: float) -> None:
    """A stream from a written plan is its samples: the cycle must be their sample time."""
    from rfsw_plan.planfiles.folder import sample_time

    dt = sample_time(folder)
    if dt is None:
        return  # the strict reader names the damage
    if abs(dt - cycle) > 1e-6:
        raise InputError("--stream-cycle-ms", "", f"{cycle * 1e3:g} ms is not the plan's "
                         f"sample time {dt * 1e3:g} ms", "the plan's sample time (the "
                         "default), or plan again with --export stream (it times the plan at "
                         "the cycle)")
