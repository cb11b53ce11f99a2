"""The welding side: seam, process forces over time, weld window, problems, deviation.

Data flow: a :class:`Problem` holds the robot, the :class:`Seam` (its :meth:`Seam.frames`
give :class:`SeamFrames`), the :class:`ProcessModel` (its :meth:`ProcessModel.schedule` gives
a :class:`LoadSchedule`) and the :class:`WeldWindow`. :func:`taught_path` turns the frames
into joint values; :func:`predict_deviation` says how far the loaded robot misses the seam;
:func:`task_from_schedule` joins frames and schedule into the :class:`PlanTask` the planner
places the robot along; :func:`task_for` is that recipe for a problem, shared by every caller.
"""

from rfsw_plan.process.cosim import CosimResult, PenetrationLaw, cosimulate
from rfsw_plan.process.deviation import (
    DeviationResult,
    predict_deviation,
    problem_deviation,
    problem_penetration_law,
)
from rfsw_plan.process.force_fit import ForceFit, fit_process_forces
from rfsw_plan.process.forces import ProcessForces, ProcessModel
from rfsw_plan.process.frames import PHASES, LoadSchedule, SeamFrames, tcp_orientation
from rfsw_plan.process.presets import PROCESS_PRESETS, process_preset
from rfsw_plan.process.problem import (
    Coupling,
    Problem,
    bundled_problem_names,
    load_problem,
    resolve_problem_path,
)
from rfsw_plan.process.seam import Seam, interpolate_frames
from rfsw_plan.process.task import (
    PlanTask,
    offsets3,
    schedule_for,
    task_constant_force,
    task_for,
    task_from_schedule,
)
from rfsw_plan.process.taught import joints_at, taught_path, taught_poses
from rfsw_plan.process.window import WeldWindow

__all__ = [
    "PHASES",
    "PROCESS_PRESETS",
    "CosimResult",
    "Coupling",
    "DeviationResult",
    "ForceFit",
    "LoadSchedule",
    "PenetrationLaw",
    "PlanTask",
    "Problem",
    "ProcessForces",
    "ProcessModel",
    "Seam",
    "SeamFrames",
    "WeldWindow",
    "bundled_problem_names",
    "cosimulate",
    "fit_process_forces",
    "interpolate_frames",
    "joints_at",
    "load_problem",
    "offsets3",
    "predict_deviation",
    "problem_deviation",
    "problem_penetration_law",
    "process_preset",
    "resolve_problem_path",
    "schedule_for",
    "task_constant_force",
    "task_for",
    "task_from_schedule",
    "taught_path",
    "taught_poses",
    "tcp_orientation",
]
