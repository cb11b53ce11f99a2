"""rfsw_plan: offline planning of robotic friction stir welding around the robot's elasticity.

Public API (see the README for a tour):

* robots: :func:`load_robot`, :class:`Robot`, :func:`load_robot_description`
* elastostatics: :class:`ElastostaticModel`, :func:`identify`
* measurements: :func:`read_measurements`, :class:`MeasurementSet`
* process: :class:`WeldWindow`, :class:`SeamFrames`, :class:`LoadSchedule`,
  :func:`load_problem`
* planning: :func:`plan` (problem -> verified, timed :class:`PlanResult`)

``plan`` and ``PlanResult`` are imported on first use, so ``import rfsw_plan`` does not load
CasADi.
"""

from typing import Any

from rfsw_plan.elastostatics.identification import IdentificationResult, identify
from rfsw_plan.elastostatics.model import ElastostaticModel, load_model
from rfsw_plan.exceptions import RfswError
from rfsw_plan.io.measurements import MeasurementSet, read_measurements, write_measurements
from rfsw_plan.process.frames import LoadSchedule, SeamFrames
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.robot.description import RobotDescription, load_robot_description
from rfsw_plan.robot.kinematics import Robot, load_robot

__version__ = "0.1.0"


def __getattr__(name: str) -> Any:
    if name in ("plan", "PlanResult"):
        from rfsw_plan.planning import api, result

        return api.plan if name == "plan" else result.PlanResult
    if name == "load_problem":
        from rfsw_plan.process.problem import load_problem

        return load_problem
    raise AttributeError(f"module 'rfsw_plan' has no attribute '{name}'")

__all__ = [
    "ElastostaticModel",
    "IdentificationResult",
    "LoadSchedule",
    "MeasurementSet",
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
]
