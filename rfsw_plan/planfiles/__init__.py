"""The plan folder: ``waypoints.csv``, ``plan.json`` and their plots, written from a
:class:`~rfsw_plan.planning.result.PlanResult` and read back for re-verification.

The one owner of a plan folder: :class:`PlanRecord` is ``plan.json`` (typed,
``to_json``/``from_json``), :class:`PlanFolder` the strict reader (``open`` -> record,
samples, ``rebuild()``), :func:`write_plan` the writer.

This package sits above ``planning/`` (it consumes plan results) and below everything that
reads a written plan (real-time comparison, validation, export).
"""

from rfsw_plan.planfiles.folder import PlanFolder, PlanSamples, read_plan_folder
from rfsw_plan.planfiles.rebuild import PlannedWaypoints, RebuiltPlan
from rfsw_plan.planfiles.record import PlanRecord
from rfsw_plan.planfiles.waypoints import write_plan_folder as write_plan

__all__ = ["PlanFolder", "PlanRecord", "PlanSamples", "PlannedWaypoints", "RebuiltPlan",
           "read_plan_folder", "write_plan"]
