"""The welding side: seam, process forces over time, weld window, problems, deviation.

Data flow: a :class:`Problem` holds the robot, the :class:`Seam` (its :meth:`Seam.frames`
give :class:`SeamFrames`), the :class:`ProcessModel` (its :meth:`ProcessModel.schedule` gives
a :class:`LoadSchedule`) and the :class:`WeldWindow`. :func:`taught_path` turns the frames
into joint values; :func:`predict_deviation` says how far the loaded robot misses the seam;
:func:`task_from_schedule` joins frames and schedule into the :class:`PlanTask` the planner
places the robot along; :func:`task_for` is that recipe for a problem, shared by every caller.
"""

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
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

#: Where each name of the package lives: imported on first use (PEP 562), so that importing
#: one submodule (``rfsw_plan.process.forces``) does not import them all, SciPy's
#: interpolation with the seam among them (issue 41: every command at its import floor).
_WHERE = {
    "CosimResult": "cosim",
    "PenetrationLaw": "cosim",
    "cosimulate": "cosim",
    "DeviationResult": "deviation",
    "predict_deviation": "deviation",
    "problem_deviation": "deviation",
    "problem_penetration_law": "deviation",
    "ForceFit": "force_fit",
    "fit_process_forces": "force_fit",
    "ProcessForces": "forces",
    "ProcessModel": "forces",
    "PHASES": "frames",
    "LoadSchedule": "frames",
    "SeamFrames": "frames",
    "tcp_orientation": "frames",
    "PROCESS_PRESETS": "presets",
    "process_preset": "presets",
    "Coupling": "problem",
    "Problem": "problem",
    "bundled_problem_names": "problem",
    "load_problem": "problem",
    "resolve_problem_path": "problem",
    "Seam": "seam",
    "interpolate_frames": "seam",
    "PlanTask": "task",
    "offsets3": "task",
    "schedule_for": "task",
    "task_constant_force": "task",
    "task_for": "task",
    "task_from_schedule": "task",
    "joints_at": "taught",
    "taught_path": "taught",
    "taught_poses": "taught",
    "WeldWindow": "window",
}


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_WHERE[name]}"), name)
    globals()[name] = value
    return value


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
