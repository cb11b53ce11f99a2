"""Planner options (re-exported; they live in :mod:`rfsw_plan.process.plan_options`).

The options belong to a problem (``Problem.planning``), which is built in ``process/``; the
planner reads them from there. This module keeps the import path
``rfsw_plan.planning.options`` that the planner and user code use.
"""

from rfsw_plan.process.plan_options import (
    OPTION_KEYS,
    OptionKey,
    PlanOptions,
    options_from_table,
)

__all__ = ["OPTION_KEYS", "OptionKey", "PlanOptions", "options_from_table"]
