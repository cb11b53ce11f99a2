"""A written plan rebuilt from its folder: the problem it was planned for (with the fitted
forces of ``plan --forces``), its robot, its waypoints and its task
(:meth:`rfsw_plan.planfiles.folder.PlanFolder.rebuild`).

``check`` re-verifies a program on the rebuilt task, ``validate-weld`` and the virtual trial
weld run the rebuilt waypoints: every reader of a plan gets the problem, robot and task from
here, through the one recipe :func:`rfsw_plan.process.task.task_for`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.planfiles.record import PlanRecord
from rfsw_plan.process.forces import FIT_PARAMS
from rfsw_plan.process.problem import Problem, load_problem, with_process
from rfsw_plan.process.task import PlanTask, schedule_for, task_for

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PlannedWaypoints:
    """The offline plan as the simulator needs it.

    Attributes:
        time: Time each waypoint is reached in the load schedule [s], shape (K,).
        phase: Phase of each waypoint (plunge/dwell stationary ones, then weld), shape (K,).
        s: Arc length from the seam start [m], shape (K,).
        q: Planned joint values [rad], shape (K, n).
        solve_time_s: Planner wall time [s].
    """

    time: FloatArray
    phase: np.ndarray
    s: FloatArray
    q: FloatArray
    solve_time_s: float = 0.0


@dataclass(frozen=True)
class RebuiltPlan:
    """A verified plan rebuilt from its folder.

    Attributes:
        folder: The plan folder.
        record: Its ``plan.json``.
        problem: The problem it was planned for (with the fitted forces if it was planned
            with ``--forces``, on the robot file it names).
        robot: The robot file or name the plan was made with.
        waypoints: The planned joints per waypoint.
    """

    folder: Path
    record: PlanRecord
    problem: Problem
    robot: str
    waypoints: PlannedWaypoints

    def task(self) -> PlanTask:
        """The task the plan was made on (:func:`rfsw_plan.process.task.task_for`): the
        problem at the plan's waypoint spacing, with the problem's ``max_start_waypoints``.

        The record holds the number of stationary waypoints the task got
        (``n_start_waypoints``, which may exceed the option: the first and last dwell sample
        are always kept); a plan made with another ``max_start_waypoints`` (``--set``) is
        rebuilt with the largest option up to that number that gives it.

        Raises:
            InputError: No option gives the recorded number of stationary waypoints.
        """
        n = self.record.n_start_waypoints
        first = self.problem.planning.max_start_waypoints
        task = task_for(self.problem, self.record.spacing, first)
        if n is None or task.n_start == n:
            return task
        for max_start in range(n, -1, -1):
            task = task_for(self.problem, self.record.spacing, max_start)
            if task.n_start == n:
                return task
        raise InputError(self.folder / "plan.json", "n_start_waypoints", f"{n}",
                         "the number of stationary waypoints of the problem's schedule")


def rebuild_plan(folder: Path, record: PlanRecord, problem: str | None = None) -> RebuiltPlan:
    """The plan of a folder whose record passed the strict reader (see the module docstring).

    Args:
        folder: The plan folder.
        record: Its ``plan.json`` (a verified plan).
        problem: Problem file or bundled name (default: the one ``plan.json`` names).

    Raises:
        InputError: No waypoints in the record, no problem named, an unreadable problem or
            robot file, or incomplete fitted forces (one line, exit 2).
    """
    path = folder / "plan.json"
    wp = record.waypoints
    if not all(k in wp for k in ("q_deg", "s_mm", "phase")):
        raise InputError(path, "waypoints", "missing q_deg/s_mm/phase",
                         "plan.json with its waypoints")
    pb = _planned_problem(path, record, problem)
    return RebuiltPlan(folder, record, pb, record.robot_file, _waypoints(path, wp, pb))


def _planned_problem(path: Path, record: PlanRecord, problem: str | None) -> Problem:
    """The problem the plan was made for, on its robot file, with its fitted forces."""
    name = problem or record.problem_file
    if not name:
        raise InputError(path, "problem", "no problem named", "the problem file of the plan")
    pb = load_problem(name)
    robot_ref = record.get("robot_file")
    if robot_ref:
        from rfsw_plan.robot.description import load_robot_description

        pb = replace(pb, robot=load_robot_description(robot_ref))
    fl = record.get("force_log")
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
    sched = schedule_for(pb)
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


__all__ = ["PlannedWaypoints", "RebuiltPlan", "rebuild_plan"]
