"""rfsw_plan: offline planning of robotic friction stir welding around the robot's elasticity.

Public API (a tour: docs/guide/planning.md; every name: docs/reference/api.md):

* robots: :func:`load_robot`, :class:`Robot`, :func:`load_robot_description`
* elastostatics: :class:`ElastostaticModel`, :func:`identify`
* measurements: :func:`read_measurements`, :class:`MeasurementSet`
* process: :class:`WeldWindow`, :class:`SeamFrames`, :class:`LoadSchedule`,
  :func:`load_problem`
* planning: :func:`plan` (problem -> verified, timed :class:`PlanResult`)
* plan files: :func:`write_plan` (a :class:`PlanResult` -> ``waypoints.csv``, plots,
  ``plan.json``, exactly as ``rfsw-plan plan -o`` writes them), :class:`PlanFolder` (the
  one reader: ``PlanFolder.open(dir)`` -> its :class:`PlanRecord`, samples, ``rebuild()``)

Every name is imported on first use, so ``import rfsw_plan`` loads none of the heavy
libraries (CasADi, Pinocchio, SciPy, matplotlib) until they are needed.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rfsw_plan.elastostatics.identification import IdentificationResult, identify
    from rfsw_plan.elastostatics.model import ElastostaticModel, load_model
    from rfsw_plan.exceptions import RfswError
    from rfsw_plan.io.measurements import MeasurementSet, read_measurements, write_measurements
    from rfsw_plan.planfiles import PlanFolder, PlanRecord, write_plan
    from rfsw_plan.planfiles.job import PlanRequest
    from rfsw_plan.planning.api import plan
    from rfsw_plan.planning.result import PlanResult
    from rfsw_plan.process.frames import LoadSchedule, SeamFrames
    from rfsw_plan.process.problem import load_problem
    from rfsw_plan.process.window import WeldWindow
    from rfsw_plan.robot.description import RobotDescription, load_robot_description
    from rfsw_plan.robot.kinematics import Robot, load_robot

__version__ = "0.1.0"

# Every public name is imported on first use (PEP 562), so ``import rfsw_plan`` and the CLI's
# ``--help`` load neither Pinocchio, SciPy nor CasADi.
_EXPORTS = {
    "IdentificationResult": "rfsw_plan.elastostatics.identification",
    "identify": "rfsw_plan.elastostatics.identification",
    "ElastostaticModel": "rfsw_plan.elastostatics.model",
    "load_model": "rfsw_plan.elastostatics.model",
    "RfswError": "rfsw_plan.exceptions",
    "MeasurementSet": "rfsw_plan.io.measurements",
    "read_measurements": "rfsw_plan.io.measurements",
    "write_measurements": "rfsw_plan.io.measurements",
    "plan": "rfsw_plan.planning.api",
    "PlanResult": "rfsw_plan.planning.result",
    "write_plan": "rfsw_plan.planfiles",
    "PlanRequest": "rfsw_plan.planfiles.job",
    "PlanFolder": "rfsw_plan.planfiles.folder",
    "PlanRecord": "rfsw_plan.planfiles.record",
    "LoadSchedule": "rfsw_plan.process.frames",
    "SeamFrames": "rfsw_plan.process.frames",
    "load_problem": "rfsw_plan.process.problem",
    "WeldWindow": "rfsw_plan.process.window",
    "RobotDescription": "rfsw_plan.robot.description",
    "load_robot_description": "rfsw_plan.robot.description",
    "Robot": "rfsw_plan.robot.kinematics",
    "load_robot": "rfsw_plan.robot.kinematics",
}


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'rfsw_plan' has no attribute '{name}'")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))


__all__ = [
    "ElastostaticModel",
    "IdentificationResult",
    "LoadSchedule",
    "MeasurementSet",
    "PlanFolder",
    "PlanRecord",
    "PlanRequest",
    "PlanResult",
    "RfswError",
    "Robot",
    "RobotDescription",
    "SeamFrames",
    "WeldWindow",
    "identify",
    "load_model",
    "load_problem",
    "load_robot",
    "load_robot_description",
    "plan",
    "read_measurements",
    "write_measurements",
    "write_plan",
]
