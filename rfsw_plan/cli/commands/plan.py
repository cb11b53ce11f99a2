"""``rfsw-plan plan PROBLEM -o DIR``: plan, verify, time and write corrected waypoints."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from rfsw_plan.cli.numbers import number, percent
from rfsw_plan.exceptions import InfeasibleError, InputError, RfswError

NAME = "plan"
HELP = "plan poses and fake-target offsets, verify them, time them and write waypoint files"


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("problem", help="bundled problem name (e.g. zk500_table6_seam) or file")
    parser.add_argument("-o", "--output", default=None,
                        help="output directory (default: out/plan/<problem>)")
    parser.add_argument("--json", action="store_true", help="print the plan.json summary")
    parser.add_argument("--spacing-mm", type=number(0.01, 1e4, "mm"), default=None,
                        help="waypoint spacing along the seam [mm] (default: the problem's)")
    parser.add_argument("--force-uncertainty", type=percent(), default=None, metavar="PERCENT",
                        help="relative force uncertainty per seam-frame component: 20%%, "
                        "'20 %%' or the fraction 0.2 (default: the problem's)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a [planning] option, file units (e.g. w_stiffness=0)")
    from rfsw_plan.cli.commands.export import add_export_arguments

    add_export_arguments(parser, "--export")
    from rfsw_plan.cli import plan_forces as force_log_cli

    force_log_cli.register(parser)


def _set_table(items: list[str]) -> dict[str, Any]:
    """``--set KEY=VALUE`` items as a ``[planning]`` table in file units (numbers, true/false
    or a name such as ``solver=full``); the job checks the keys and values.

    Raises:
        InputError: An item without ``=``.
    """
    table: dict[str, Any] = {}
    for it in items:
        key, sep, val = it.partition("=")
        if not sep:
            raise InputError("--set", it, "missing '='", "KEY=VALUE")
        v: Any
        if val.strip().lower() in ("true", "false"):
            v = val.strip().lower() == "true"
        else:
            try:
                v = float(val)
            except ValueError:
                v = val.strip()  # a name (solver=full); numeric keys reject it with one line
            else:
                if v.is_integer() and abs(v) < 2**53:
                    v = int(v)
        table[key.strip()] = v
    return table


def request(args: argparse.Namespace) -> Any:
    """The :class:`~rfsw_plan.planfiles.job.PlanRequest` of the command line."""
    from rfsw_plan.planfiles.job import PlanRequest

    return PlanRequest(args.problem, _set_table(args.set), args.force_uncertainty,
                       None if args.spacing_mm is None else args.spacing_mm * 1e-3,
                       args.forces, args.forces_frame, args.robot)


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.cli import plan_forces as force_log_cli
    from rfsw_plan.cli.commands.export import check_export_arguments, export_plan_result
    from rfsw_plan.files import OutputLock, prepare_output_dir, strict_json
    from rfsw_plan.planfiles.job import write_refusal
    from rfsw_plan.planning.verdict import PROGRAM_REFUSED

    check_export_arguments(args)
    prepared = request(args).prepare()
    problem, flog = prepared.problem, prepared.force_log
    out = prepare_output_dir(args.output if args.output else default_output(problem.name))
    with OutputLock(out):  # taken before planning: a second writer is refused at once
        what = ""
        try:
            run_ = prepared.run(draw_ahead=True)
            # A program that cannot hold what the plan verified (export's judgement) refuses
            # the request: recorded and printed as a planner's refusal is, saying what failed.
            what = PROGRAM_REFUSED
            written = run_.write(out, lambda result, folder, record:
                                 export_plan_result(args, result, folder, record))
        except RfswError as exc:  # the refusal is recorded (verdict NO), printed first
            record = write_refusal(out, problem.name, exc, prepared.options.force_uncertainty,
                                   what)
            if isinstance(exc, InfeasibleError) and not args.json:
                print(record["verdict_text"])
            raise
    result, check, summary = run_.result, run_.check, written.record
    for line in written.failed_plots:  # the plan is whole without its plots: exit 0
        print(f"rfsw-plan plan: warning: {line}; the data files and plan.json are complete",
              file=sys.stderr)
    if args.json:
        force_log_cli.print_text(flog, check, result, quiet=True)
        brief = {k: v for k, v in summary.items() if k != "waypoints"}
        print(strict_json(brief), end="")
        return 0
    _print_text(problem, result, summary, written.files, out)
    force_log_cli.print_text(flog, check, result)
    return 0


def default_output(name: str) -> Path:
    """The default output folder of ``plan``: ``out/plan/<problem>``."""
    return Path("out") / NAME / name


def _print_text(problem: Any, result: Any, summary: dict[str, Any], written: list[Path],
                out: Path) -> None:
    """The verdict first, then the levers, the strategy table, the trade-off and the files."""
    verdict = result.verdict()
    print(verdict.line)
    for line in _programs_below_plan(summary):
        print(f"  {line}")
    if verdict.depth_note:
        print(f"  {verdict.depth_note}")
    if verdict.held:
        print(f"  {verdict.held}")
    if verdict.traded:
        print(f"  note: {verdict.traded}")
    for k, lever in enumerate(verdict.levers, 1):
        print(f"  lever {k}: {lever.text()}")
    if verdict.levers and not result.options.robust_hard:
        print("  to refuse such plans instead: --set robust_hard=true")
    print(f"{problem.name}: {summary['status']} ({result.solver_status}, "
          f"{result.iterations} IPOPT iterations, branch {result.branch})")
    print(f"robot {problem.robot.name} from {problem.robot.path}")
    _print_table(result)
    ww = summary["worst_waypoint"]
    print(f"worst waypoint {ww['waypoint']} ({ww['phase']}, s = {ww['s_mm']:.1f} mm, "
          f"t = {ww['t_s']:.2f} s): e = {ww['e_lat_mm']:+.3f} mm, margin {ww['margin_mm']:.3f} mm")
    if result.samples is not None:
        sv = result.samples
        print(f"written samples: {len(sv.e_lat)} ({int(sv.contact.sum())} in the material), "
              f"all in the window; smallest window margin {sv.min_margin * 1e3:.3f} mm")
        env = summary["envelope"]
        dep = env.get("depth_error_mm") or []
        spd = env.get("pin_speed_deviation_pct") or []
        loop = " (the force loop's equilibrium)" if env["axial_control"] == "force" else ""
        depth = (f"depth {dep[0]:+.3f} to {dep[1]:+.3f} mm of the planned depth{loop} (window "
                 f"{env['depth_window_mm'][0]:+g} to {env['depth_window_mm'][1]:+g} mm)"
                 if dep else "depth not sampled")
        tilt = env.get("max_tilt_error_deg")
        print(f"weld envelope at every written sample: {depth}; tilt within "
              f"{0.0 if tilt is None else tilt:.3f} deg (tolerance {env['tilt_tol_deg']:g}); "
              f"pin speed off the commanded by at most "
              f"{max(abs(x) for x in spd) if spd else 0.0:.2f} % of the weld speed, the "
              f"acceleration included (tolerance {env['speed_tol_pct']:g} %); pin "
              f"{env['min_height_before_plunge_mm']:.2f} mm above the plate before the plunge")
        _print_plunge(problem, env)
    print(f"plan time {result.total_time:.2f} s (NLP {result.solve_time:.2f} s); wrote "
          f"{len(written)} files in {out}:")
    for f in written:
        print(f"  {f}")


def _programs_below_plan(summary: dict[str, Any]) -> list[str]:
    """The exported programs whose controller runs them holding less force uncertainty than
    the plan (``plan.json``'s ``export.held_as_run``,
    :func:`~rfsw_plan.export.api.below_plan_lines`)."""
    held = (summary.get("export") or {}).get("held_as_run") or {}
    plan = summary.get("tolerated_force_uncertainty")
    if not held or not isinstance(plan, float):
        return []
    from rfsw_plan.export.api import below_plan_lines

    return below_plan_lines({k: (d["tolerated_pct"] / 100.0, d["limited_by"])
                             for k, d in held.items() if d.get("tolerated_pct") is not None},
                            plan)


def _print_plunge(problem: Any, env: dict[str, Any]) -> None:
    """The plunge as written: where the pin is when it ends, the TCP depth commanded for it,
    the spindle run-up; a problem's commanded plunge that the planner did not use; and the end
    stop (its length, the forces it relaxed to, the pin's sideways motion)."""
    if "commanded_plunge_mm" not in env:
        return
    from rfsw_plan.process.task import STANDING_DEPTH_TOL

    err = env.get("plunge_end_depth_error_mm")
    planned = problem.process.plunge_depth * 1e3
    tol = STANDING_DEPTH_TOL * 1e3
    how = (f"within {tol:g} mm" if abs(err or 0.0) <= tol + 1e-9 else
           f"NOT reached: {abs(err or 0.0):.3f} mm {'short' if (err or 0.0) > 0 else 'deep'}")
    reach = ("" if err is None else
             f"the pin at {planned - err:.2f} mm of the planned {planned:.2f} mm when it ends "
             f"({how}), ")
    print(f"plunge: {reach}the TCP commanded {env['commanded_plunge_mm']:.2f} mm below the "
          f"surface there; spindle run-up {env['spindle_runup_s']:.2f} s before it")
    want, got = problem.process.dwell_time, env["dwell_s"]
    print(f"dwell: {got:.2f} s, " + ("the problem's" if abs(got - want) <= 0.011 else
          f"not the problem's {want:g} s: lengthened where the joint limits need it "
          "between stationary waypoints"))
    if problem.coupling is not None:
        print(f"  not used by the planner: [process.coupling] commanded_depth_mm = "
              f"{problem.coupling.commanded_depth * 1e3:g} (the co-simulation's input; the "
              f"plan commands {env['commanded_plunge_mm']:.2f} mm for the planned depth)")
    if "end_stop_s" in env:
        from rfsw_plan.process.task import STANDSTILL_MOTION

        f_t, f_l, _ = env["end_stop_force_N"]
        moved = env["end_stop_pin_motion_mm"]
        print(f"end stop: {env['end_stop_s']:.2f} s at the seam end, the forces relaxed to "
              f"{abs(f_t):.0f} N traverse and {abs(f_l):.0f} N lateral before the retract lifts "
              "the pin" + ("" if moved is None else
                           f"; the pin moves {moved:.3f} mm sideways (limit "
                           f"{STANDSTILL_MOTION * 1e3:g} mm)"))


def _print_table(result: Any) -> None:
    """The strategies on the same waypoints (one computation: :class:`BaselineMetrics`) and
    the trade-off's requested point."""
    from rfsw_plan.planning.verdict import pct

    u = result.options.force_uncertainty
    print(f"{'strategy':<10} {'max|e| mm':>10} {'RMS mm':>8} {'worst mm':>9} "
          f"{'worst margin mm':>16} {'k_lat N/mm':>11}  {'force uncertainty held':<22}")
    names = {"nlp": "plan", "none": "none", "mirror": "mirror"}
    for b in result.baselines:
        d = b.to_dict()
        print(f"{names.get(b.name, b.name):<10} {d['max_abs_lateral_mm']:>10.3f} "
              f"{d['rms_lateral_mm']:>8.3f} {d['worst_case_lateral_mm']:>9.3f} "
              f"{d['worst_case_window_margin_mm']:>16.3f} "
              f"{d['min_lateral_stiffness_N_mm']:>11.1f}  "
              f"{'holds none: cannot be written' if b.unwritten else _held(b.tolerated):<22}")
    req = next(p for p in result.tradeoff() if p.name == "requested")
    k_need = ("" if req.min_lateral_stiffness != req.min_lateral_stiffness
              else f"{req.min_lateral_stiffness * 1e-3:.1f}")
    print(f"{'requested':<10} {'':>10} {'':>8} {'':>9} {'':>16} {k_need:>11}  "
          f"{pct(u)} (k_lat: what the plan's errors need)")
    print(f"(worst: largest |e| under +-{u * 100:.3g} % force; worst margin: distance of that "
          "worst case to the window, negative = outside; held: the largest uniform +-u on the "
          "seam-frame force components for which lateral error, depth, tilt and pin speed hold "
          "at every in-material waypoint, and for the plan every written sample)")
    for b in result.baselines:
        if b.unwritten and b.claim is not None:
            print(f"{names.get(b.name, b.name)}: {_held(b.claim.tolerated)} at its waypoints "
                  f"alone, but cannot be written: {b.unwritten}")


def _held(u: float) -> str:
    """``holds up to +-9 %`` for a tolerated relative uncertainty."""
    if u != u:
        return ""
    if u <= 0:
        return "holds none (nominal outside)"
    if u == float("inf"):
        return "holds any (no lateral force)"
    return f"holds up to +-{100 * u:.3g} %"
