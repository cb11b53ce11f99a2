"""The ``plan --forces LOG.csv [--forces-frame F] [--robot FILE]`` hook of ``rfsw-plan plan``.

The arguments and the text; the job (:class:`rfsw_plan.planfiles.job.PlanRequest`) fits the
log and plans with the derived force uncertainty (:mod:`rfsw_plan.planning.force_log`).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any


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
