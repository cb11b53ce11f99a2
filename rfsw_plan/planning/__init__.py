"""The planner: CasADi NLP for poses and fake-target offsets, baselines, verification.

The planner takes a :class:`~rfsw_plan.process.task.PlanTask` (built in ``process/``), places
the robot with the NLP, verifies the result and times it (``timing/``).

The names below are imported on first use (PEP 562): reading a plan (``export``, ``check``)
needs :class:`PlanResult` and the verification, not the NLP, and never imports CasADi.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rfsw_plan.planning.api import plan, plan_task
    from rfsw_plan.planning.nlp import build_plan_nlp, solve_plan_nlp
    from rfsw_plan.planning.result import PlanResult
    from rfsw_plan.planning.verify import verify_plan
    from rfsw_plan.process.plan_options import PlanOptions

#: Public name -> the module that defines it.
_WHERE = {
    "PlanOptions": "rfsw_plan.process.plan_options",
    "PlanResult": "rfsw_plan.planning.result",
    "build_plan_nlp": "rfsw_plan.planning.nlp",
    "plan": "rfsw_plan.planning.api",
    "plan_task": "rfsw_plan.planning.api",
    "solve_plan_nlp": "rfsw_plan.planning.nlp",
    "verify_plan": "rfsw_plan.planning.verify",
}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(import_module(_WHERE[name]), name)


__all__ = [
    "PlanOptions",
    "PlanResult",
    "build_plan_nlp",
    "plan",
    "plan_task",
    "solve_plan_nlp",
    "verify_plan",
]
