"""The ``plan --forces LOG.csv [--forces-frame F] [--robot FILE]`` hook of ``rfsw-plan plan``.

Kept out of :mod:`rfsw_plan.cli.commands.plan` so the plan command only calls five small
functions: the arguments, the problem with the fitted forces (and another robot), the plan
with the derived force uncertainty (:mod:`rfsw_plan.planning.force_log`), the ``plan.json``
entries and the text.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the parser answers before the heavy libraries are imported
    from rfsw_plan.process.problem import Problem


def register(parser: argparse.ArgumentParser) -> None:
    """Add ``--forces``, ``--forces-frame`` and ``--robot`` to the plan command."""
    parser.add_argument("--forces", metavar="LOG.csv", default=None,
                        help="force log of a trial weld (t_s, fx_N, fy_N, fz_N[, m*_Nm]"
                        "[, frame]): fit the force model per phase, plan with the fitted "
                        "forces and the force uncertainty derived from the fit (+-3 sigma "
                        "spread + drift) instead of --force-uncertainty")
    parser.add_argument("--forces-frame", choices=("base", "seam", "tool"), default=None,
                        help="frame of the force log if it has no 'frame' column")
    parser.add_argument("--robot", metavar="ROBOT", default=None,
                        help="robot name or TOML file instead of the problem's (e.g. one "
                        "re-identified by validate-weld --save-robot)")


def prepare(problem: Problem, args: argparse.Namespace) -> tuple[Problem, Any]:
    """The problem with ``--robot`` applied, and the fitted ``--forces`` log (or None).

    Raises:
        InputError: ``--forces-frame`` without ``--forces``, a bad log, a log without axial
            force; UnknownNameError: unknown robot.
    """
    from rfsw_plan.exceptions import InputError

    if args.robot is not None:
        from rfsw_plan.robot.description import load_robot_description

        problem = replace(problem, robot=load_robot_description(args.robot))
    if args.forces is None:
        if args.forces_frame is not None:
            raise InputError("--forces-frame", "", "given without --forces",
                             "--forces LOG.csv --forces-frame base|seam|tool")
        return problem, None
    from rfsw_plan.planning.force_log import load_force_log

    if args.force_uncertainty is not None:
        raise InputError("--force-uncertainty", "", "given with --forces",
                         "one of them: --forces derives the uncertainty from the log")
    log = load_force_log(problem, args.forces, args.forces_frame)
    return log.problem, log


def plan(problem: Problem, log: Any, options: Any, spacing: float | None,
         plan_fn: Callable[..., Any]) -> tuple[Any, Any]:
    """The plan (and its check under the measured force box, or None)."""
    if log is None:
        return plan_fn(problem, options, spacing=spacing), None
    from rfsw_plan.planning.force_log import plan_with_force_log

    return plan_with_force_log(log, options, spacing)


def plan_json(problem: Problem, args: argparse.Namespace, log: Any, check: Any
              ) -> dict[str, Any]:
    """Entries of ``plan.json``: where the problem and robot came from (for validate-weld),
    and the ``force_log`` block (:func:`rfsw_plan.planfiles.record.provenance_keys`)."""
    from rfsw_plan.planfiles.record import provenance_keys

    return provenance_keys(problem, log, check)


def print_text(log: Any, check: Any, result: Any, quiet: bool = False) -> None:
    """Fit quality, derived uncertainty and whether the plan holds under it (stdout), or
    just the one line on stderr for an unusable log when ``quiet`` (``--json``)."""
    if log is None:
        return
    from rfsw_plan.planning.force_log import check_text

    if not log.usable:
        print(f"force log {log.source} NOT used: {log.uncertainty.reason}", file=sys.stderr)
    if quiet:
        return
    if log.usable:
        print(log.summary())
    if check is not None:
        print(check_text(check, result.window))
        tol = float(getattr(result, "tolerated_force_uncertainty", float("nan")))
        if tol == tol:
            print(f"measured force uncertainty, as a relative box at the plan's poses: "
                  f"+-{100 * check.u_equivalent:.1f} %; the plan tolerates +-{100 * tol:.1f} %")
