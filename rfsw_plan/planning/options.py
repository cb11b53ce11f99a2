"""Planner options (re-exported; they live in :mod:`rfsw_plan.process.plan_options`).

The options belong to a problem (``Problem.planning``), which is built in ``process/``; the
planner reads them from there. This module keeps the import path
``rfsw_plan.planning.options`` that the planner and user code use, and adds the planner's
own check that the options make a well-posed NLP (:func:`check_well_posed`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rfsw_plan.exceptions import InputError
from rfsw_plan.process.plan_options import (
    OPTION_KEYS,
    OptionKey,
    PlanOptions,
    options_from_table,
)

__all__ = ["OPTION_KEYS", "OptionKey", "PlanOptions", "check_well_posed", "options_from_table"]


def check_well_posed(options: PlanOptions, window: Any, source: str = "planning") -> None:
    """Reject option combinations that make the planning NLP ill-posed, before any solver runs.

    The nominal lateral error must lie in [lower + margin, upper - margin], which is empty
    unless 2 margin < upper - lower (IPOPT then fails with "Ill-posed problem detected:
    LBG <= UBG" deep inside CasADi).

    Args:
        options: The planner options.
        window: The weld window (``lower``, ``upper`` [m]).
        source: Where the options came from, for the message.

    Raises:
        InputError: one line naming the options and the valid range (exit 2).
    """
    lo, hi = float(window.lower), float(window.upper)
    if not (np.isfinite(lo) and np.isfinite(hi)) or not lo < hi:
        raise InputError(source, "window", f"lower {lo * 1e3:g} mm, upper {hi * 1e3:g} mm",
                         "finite bounds with lower < upper")
    half = 0.5 * (hi - lo)
    if not options.margin < half:
        raise InputError(
            source, "margin_mm",
            f"margin {options.margin * 1e3:g} mm leaves no room in the window "
            f"[{lo * 1e3:g}, {hi * 1e3:+g}] mm (width {2 * half * 1e3:g} mm)",
            f"0 <= margin_mm < {half * 1e3:g} (half the window width), or a wider window")
