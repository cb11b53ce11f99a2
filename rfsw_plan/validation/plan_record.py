"""The plan that was run, read back from its folder (``validate-weld PLAN_DIR``).

:func:`read_plan_dir` is the only place the workbench reads a plan folder, through the one strict
plan-folder reader (:func:`rfsw_plan.planfiles.read_plan_folder`): a damaged or unverified
folder is refused by ``validate-weld`` exactly as by ``export`` and ``check``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.exceptions import InputError
from rfsw_plan.process.forces import FIT_PARAMS
from rfsw_plan.process.frames import FloatArray
from rfsw_plan.process.problem import Problem, load_problem, with_process
from rfsw_plan.realtime.compare import PlannedWaypoints


@dataclass(frozen=True)
class PlanRecord:
    """A verified plan read back from its folder.

    Attributes:
        folder: The plan folder.
        data: ``plan.json``.
        problem: The problem it was planned for (with the fitted forces if it was planned
            with ``--forces``).
        robot: The robot file or name the plan was made with.
        waypoints: The planned joints per waypoint.
    """

    folder: Path
    data: dict[str, Any]
    problem: Problem
    robot: str
    waypoints: PlannedWaypoints


def read_plan_dir(folder: str | Path, problem: str | None = None) -> PlanRecord:
    """Read ``plan.json`` of a plan folder and the problem it was planned for.

    Args:
        folder: Output folder of ``rfsw-plan plan``.
        problem: Problem file or bundled name (default: the one ``plan.json`` names).

    Raises:
        InputError: No ``plan.json``, not strict JSON, a vouched file changed, not a verified
            plan, or no waypoints (exit 2).
        InfeasibleError: The folder holds an infeasible plan (exit 3, with its reason).
    """
    folder = Path(folder)
    path = folder / "plan.json"
    data = _plan_json(folder)
    pb = _planned_problem(path, data, problem)
    robot_ref = data.get("robot_file")
    return PlanRecord(folder, data, pb, str(robot_ref or data.get("robot", "")),
                      _waypoints(path, data["waypoints"], pb))


def _plan_json(folder: Path) -> dict[str, Any]:
    """``plan.json`` of a verified plan (read by the strict plan-folder reader: strict JSON,
    a verified status, every file it vouches for whole), with its waypoints."""
    from rfsw_plan.planfiles.folder import read_plan_folder

    path = folder / "plan.json"
    data = read_plan_folder(folder).record
    wp = data.get("waypoints")
    if not isinstance(wp, dict) or not all(k in wp for k in ("q_deg", "s_mm", "phase")):
        raise InputError(path, "waypoints", "missing q_deg/s_mm/phase",
                         "plan.json with its waypoints")
    return data


def _planned_problem(path: Path, data: dict[str, Any], problem: str | None) -> Problem:
    """The problem the plan was made for, on its robot file, with its fitted forces."""
    name = problem or data.get("problem_file") or data.get("problem")
    if not name:
        raise InputError(path, "problem", "no problem named", "--problem FILE")
    pb = load_problem(name)
    robot_ref = data.get("robot_file")
    if robot_ref:
        from rfsw_plan.robot.description import load_robot_description

        pb = replace(pb, robot=load_robot_description(robot_ref))
    fl = data.get("force_log")
    if isinstance(fl, dict) and fl.get("used"):
        params = fl.get("fit", {}).get("params", {})
        try:
            x = np.array([float(params[n]) for n in FIT_PARAMS])
        except (KeyError, TypeError, ValueError):
            raise InputError(path, "force_log.fit.params", "incomplete",
                             ", ".join(FIT_PARAMS)) from None
        pb = with_process(pb, _with_forces(pb, x))
    return pb


def _waypoints(path: Path, wp: dict[str, Any], pb: Problem) -> PlannedWaypoints:
    """The planned joints per waypoint [rad], arc length [m] from the first, and the time of
    the stationary ones (plunge, dwell) from the process schedule [s]."""
    q = np.deg2rad(np.asarray(wp["q_deg"], dtype=float))
    s = np.asarray(wp["s_mm"], dtype=float) * 1e-3
    phase = np.asarray(wp["phase"]).astype(str)
    if q.ndim != 2 or q.shape[0] != s.size or s.size != phase.size:
        raise InputError(path, "waypoints", "q_deg, s_mm and phase differ in length")
    sched = pb.process.schedule(pb.frames(), 0.05, approach=False)
    t = np.zeros(s.size)
    for ph in ("plunge", "dwell"):
        m = phase == ph
        ms = np.asarray(sched.phase) == ph
        if np.any(m) and np.any(ms):
            t[m] = np.linspace(sched.t[ms][0], sched.t[ms][-1], int(np.sum(m)))
    return PlannedWaypoints(time=t, phase=phase, s=s - s[0], q=q)


def _with_forces(problem: Problem, x: FloatArray) -> Any:
    proc = problem.process
    return replace(proc, forces=proc.forces.with_vector(x, source="fitted (plan.json)"))


__all__ = ["PlanRecord", "read_plan_dir"]
