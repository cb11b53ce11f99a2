"""The planner: CasADi NLP for poses and fake-target offsets, baselines, verification.

Public names are loaded lazily (the timing package imports ``planning.task``; an eager import
of the pipeline here would be circular).
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "plan": "rfsw_plan.planning.api",
    "plan_task": "rfsw_plan.planning.api",
    "PlanResult": "rfsw_plan.planning.result",
    "PlanOptions": "rfsw_plan.planning.options",
    "PlanTask": "rfsw_plan.planning.task",
    "build_plan_nlp": "rfsw_plan.planning.nlp",
    "solve_plan_nlp": "rfsw_plan.planning.nlp",
    "verify_plan": "rfsw_plan.planning.verify",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'rfsw_plan.planning' has no attribute '{name}'")
