"""Real-time compensation and the virtual weld that compares it with the offline plan.

Data flow: a :class:`~rfsw_plan.process.frames.LoadSchedule` and a truth robot make a
:class:`VirtualWeld`; a nominal path (taught or planned) and a :class:`Strategy` (``none``,
the force-feedback filtered correction of seed 000 :class:`ForceFeedbackFilteredCorrection`,
the filtered PID with capped increments of seed 002 :class:`FilteredCappedPID`, hybrid) run on
it and give a :class:`WeldRun`, which :func:`weld_metrics` scores against the weld window.
:func:`compare` does all of it for a problem, with the sensitivity reruns.
"""

from rfsw_plan.realtime.base import ControllerInputs, NoCompensation, Strategy
from rfsw_plan.realtime.capped_pid import FilteredCappedPID
from rfsw_plan.realtime.compare import (
    STRATEGIES,
    CompareOptions,
    CompareResult,
    PlannedWaypoints,
    Scenario,
    compare,
)
from rfsw_plan.realtime.force_feedback import ForceFeedbackFilteredCorrection
from rfsw_plan.realtime.hybrid import HybridResidual
from rfsw_plan.realtime.metrics import DirectionChange, WeldMetrics, weld_metrics
from rfsw_plan.realtime.simulator import (
    NominalPath,
    ProcessVariation,
    SensorModel,
    SimConfig,
    VirtualWeld,
    WeldRun,
    truth_model,
)

__all__ = [
    "STRATEGIES",
    "CompareOptions",
    "CompareResult",
    "ControllerInputs",
    "DirectionChange",
    "FilteredCappedPID",
    "ForceFeedbackFilteredCorrection",
    "HybridResidual",
    "NoCompensation",
    "NominalPath",
    "PlannedWaypoints",
    "ProcessVariation",
    "Scenario",
    "SensorModel",
    "SimConfig",
    "Strategy",
    "VirtualWeld",
    "WeldMetrics",
    "WeldRun",
    "compare",
    "truth_model",
    "weld_metrics",
]
