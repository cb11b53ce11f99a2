"""The planner: CasADi NLP for poses and fake-target offsets, baselines, verification.

The planner takes a :class:`~rfsw_plan.process.task.PlanTask` (built in ``process/``), places
the robot with the NLP, verifies the result and times it (``timing/``).
"""

from rfsw_plan.planning.api import plan, plan_task
from rfsw_plan.planning.nlp import build_plan_nlp, solve_plan_nlp
from rfsw_plan.planning.options import PlanOptions
from rfsw_plan.planning.result import PlanResult
from rfsw_plan.planning.verify import verify_plan

__all__ = [
    "PlanOptions",
    "PlanResult",
    "build_plan_nlp",
    "plan",
    "plan_task",
    "solve_plan_nlp",
    "verify_plan",
]
