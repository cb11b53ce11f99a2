"""The plan folder: ``waypoints.csv``, ``plan.json`` and their plots, written from a
:class:`~rfsw_plan.planning.result.PlanResult` and read back for re-verification.

This package sits above ``planning/`` (it consumes plan results) and below everything that
reads a written plan (real-time comparison, validation, export).
"""

from rfsw_plan.planfiles.folder import PlanFolder, PlanSamples, read_plan_folder
from rfsw_plan.planfiles.waypoints import write_plan_folder as write_plan

__all__ = ["PlanFolder", "PlanSamples", "read_plan_folder", "write_plan"]
