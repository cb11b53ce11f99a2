"""The ``plan`` job: a typed request, :meth:`PlanRequest.run`, then :meth:`PlanRun.write`.

What ``rfsw-plan plan PROBLEM -o DIR`` does, as one library call, so Python users write the
same folder::

    run = PlanRequest("zk500_table6_seam", overrides={"w_stiffness": 0}).run()
    written = run.write("out/plan/zk500_table6_seam")

The request is checked before any planning (:meth:`PlanRequest.prepare`: the problem, the
robot, a force log, the ``[planning]`` overrides, one line naming the parameter). A plan the
planner refuses is recorded by :func:`write_refusal` (``plan.json`` with the verdict NO).

The write is one transaction (:meth:`PlanRun.write`): the folder is locked, an earlier run's
outputs are marked stale, the data files are written and committed by ``plan.json``, then the
plots. Interrupted (Ctrl-C, SIGTERM) in a folder that was empty when the write began, it
leaves the folder empty again: never ``waypoints.csv``, ``plan.html`` or a plot without the
``plan.json`` that vouches for them (issue 39).
"""

from __future__ import annotations

import contextlib
import math
import shutil
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rfsw_plan.exceptions import InputError
from rfsw_plan.planfiles.record import PlanRecord

if TYPE_CHECKING:
    from rfsw_plan.planning.result import PlanResult
    from rfsw_plan.process.plan_options import PlanOptions
    from rfsw_plan.process.problem import Problem

#: ``programs(result, folder, record)``: controller programs written into the plan folder
#: before ``plan.json`` commits them (``rfsw-plan plan --export``); returns an object with
#: ``files`` (the written paths) and ``to_dict()`` (the ``export`` block of ``plan.json``),
#: or None when nothing was exported.
ProgramsStep = Callable[["PlanResult", Path, dict[str, Any]], Any]


@dataclass(frozen=True)
class PlanRequest:
    """One plan of a problem, as ``rfsw-plan plan`` makes it.

    Attributes:
        problem: Bundled problem name or problem file (or a loaded ``Problem``).
        overrides: ``[planning]`` options in file units (``w_stiffness``, ``margin_mm``...),
            applied over the problem's own.
        force_uncertainty: Relative force uncertainty per seam-frame component (0.2 = +-20
            %), instead of the problem's.
        spacing: Waypoint spacing along the seam [m] (default: the problem's).
        forces: Force log of a trial weld: the forces are fitted per phase and the force
            uncertainty derived from the fit (:mod:`rfsw_plan.planning.force_log`).
        forces_frame: Frame of the force log if it has no ``frame`` column (``base``,
            ``seam``, ``tool``).
        robot: Robot name or file instead of the problem's.
    """

    problem: str | Path | Problem
    overrides: Mapping[str, Any] = field(default_factory=dict)
    force_uncertainty: float | None = None
    spacing: float | None = None
    forces: str | Path | None = None
    forces_frame: str | None = None
    robot: str | Path | None = None

    def prepare(self) -> PreparedPlan:
        """The problem, force log and options, checked before any planning.

        Raises:
            InputError: A parameter that cannot be used (named: ``overrides``,
                ``force_uncertainty``, ``spacing``, ``forces``, ``forces_frame``), an
                ill-posed option combination. UnknownNameError: unknown problem or robot.
        """
        from rfsw_plan.process.problem import Problem, load_problem

        problem = (self.problem if isinstance(self.problem, Problem)
                   else load_problem(self.problem))
        if self.robot is not None:
            from rfsw_plan.robot.description import load_robot_description

            problem = replace(problem, robot=load_robot_description(self.robot))
        problem, flog = self._force_log(problem)
        if self.spacing is not None and not (math.isfinite(self.spacing) and self.spacing > 0):
            raise InputError("spacing", "", f"got {self.spacing!r} m", "a length > 0 [m]")
        return PreparedPlan(problem, flog, self._options(problem), self.spacing)

    def run(self) -> PlanRun:
        """Check the request and plan (:func:`rfsw_plan.planning.api.plan`).

        Raises:
            InputError: see :meth:`prepare`. InfeasibleError, UnreachableError: the planner
                refuses (record it with :func:`write_refusal`).
        """
        return self.prepare().run()

    def _force_log(self, problem: Problem) -> tuple[Problem, Any]:
        if self.forces is None:
            if self.forces_frame is not None:
                raise InputError("forces_frame", "", "given without `forces`",
                                 "`forces` LOG.csv `forces_frame` base|seam|tool")
            return problem, None
        if self.force_uncertainty is not None:
            raise InputError("force_uncertainty", "", "given with `forces`",
                             "one of them: `forces` derives the uncertainty from the log")
        from rfsw_plan.planning.force_log import load_force_log

        log = load_force_log(problem, self.forces, self.forces_frame)
        return log.problem, log

    def _options(self, problem: Problem) -> PlanOptions:
        from rfsw_plan.process.plan_options import check_well_posed, options_from_table

        opts = options_from_table(dict(self.overrides), "overrides", problem.planning,
                                  prefix="", what="option")
        if self.force_uncertainty is not None:
            u = float(self.force_uncertainty)
            if not (math.isfinite(u) and 0 <= u <= 10):
                raise InputError("force_uncertainty", "", f"got {u!r}",
                                 "a fraction in [0, 10] (0.2 = +-20 %)")
            opts = replace(opts, force_uncertainty=u)
        check_well_posed(opts, problem.window, f"{problem.name}: [planning] and `overrides`")
        return opts


@dataclass(frozen=True)
class PreparedPlan:
    """A checked :class:`PlanRequest`: the problem (with the fitted forces and the robot), the
    force log (or None), the planner options and the spacing [m] (None: the problem's)."""

    problem: Problem
    force_log: Any
    options: PlanOptions
    spacing: float | None

    def run(self, draw_ahead: bool = False) -> PlanRun:
        """Plan (with the force log's uncertainty when it has one).

        Args:
            draw_ahead: Fork the plots' drawing process before planning
                (:meth:`~rfsw_plan.planfiles.waypoints.PlotDrawing.warm`: it imports
                matplotlib on another core meanwhile) for :meth:`PlanRun.write`, which then
                hands it the plan; it is stopped if planning fails.
        """
        # The planner is imported before the drawing process forks: the child inherits it
        # (a plan it receives unpickles without importing) and imports only matplotlib.
        from rfsw_plan.planning.api import plan
        from rfsw_plan.planning.force_log import plan_with_force_log

        drawing = None
        if draw_ahead:
            from rfsw_plan.planfiles.waypoints import PlotDrawing

            drawing = PlotDrawing.warm()
        try:
            if self.force_log is None:
                result = plan(self.problem, self.options, spacing=self.spacing)
                return PlanRun(self, result, None, drawing)
            result, check = plan_with_force_log(self.force_log, self.options, self.spacing)
            return PlanRun(self, result, check, drawing)
        except BaseException:
            if drawing is not None:
                drawing.close()
            raise


@dataclass(frozen=True)
class PlanWritten:
    """What :meth:`PlanRun.write` wrote.

    Attributes:
        folder: The plan folder.
        record: The ``plan.json`` record as written.
        files: Every file written (``plan.json`` last).
        failed_plots: One line per plot that was not written (the plan is whole without it).
    """

    folder: Path
    record: dict[str, Any]
    files: list[Path]
    failed_plots: list[str]


@dataclass(frozen=True)
class PlanRun:
    """A plan made by :meth:`PlanRequest.run`.

    Attributes:
        prepared: The checked request it was made from.
        result: The plan.
        check: The plan's check under the measured force box (with ``forces``), or None.
        drawing: The plots' drawing process forked before planning (``run(draw_ahead=True)``),
            or None: :meth:`write` forks it with the plan.
    """

    prepared: PreparedPlan
    result: PlanResult
    check: Any = None
    drawing: Any = field(default=None, compare=False, repr=False)

    def write(self, folder: str | Path, programs: ProgramsStep | None = None) -> PlanWritten:
        """Write the plan folder: ``waypoints.csv``, ``plan.html``, the programs of
        ``programs`` (if given), ``plan.json`` (committing them), then the plots.

        One transaction (module docstring); the folder is created if needed and locked unless
        this process already holds its lock.

        Raises:
            OutputPathError: The folder cannot be written or another writer holds it.
        """
        from rfsw_plan.planfiles.record import provenance_keys
        from rfsw_plan.planfiles.waypoints import (
            PLAN_OUTPUTS,
            PlotDrawing,
            commit_plan,
            mark_outputs_stale,
            write_plan_data,
        )
        from rfsw_plan.progress import Stages

        problem, result = self.prepared.problem, self.result
        with _transaction(folder) as out:
            mark_outputs_stale(out, problem.name, PLAN_OUTPUTS)
            summary = result.summary()
            summary["robot_file"] = str(problem.robot.path)
            # The plots are drawn in another process while the data files are written here.
            drawing = (self.drawing.draw(out, result) if self.drawing is not None
                       else PlotDrawing(out, result))
            # The planner's own bar has closed; writing and plotting gets a bar of its own.
            with contextlib.closing(drawing), Stages("plan", ("files", "plots")) as stages:
                written = write_plan_data(out, result, problem.seam)
                exported = programs(result, out, summary) if programs is not None else None
                if exported is not None:
                    written += list(exported.files)
                    summary["export"] = exported.to_dict()
                summary.update(provenance_keys(problem, self.prepared.force_log, self.check))
                stages.start("plots")
                # plan.json commits the data files first, then the plots are drawn and
                # committed: a plot that fails or is killed never costs the waypoints or the
                # programs.
                path, failed = commit_plan(out, summary, written, result, drawing)
        files = [out / f for f in summary.get("files", [])] + [path]
        return PlanWritten(out, summary, files, failed)


def write_refusal(folder: str | Path, problem: str, exc: Exception,
                  force_uncertainty: float, what: str = "") -> PlanRecord:
    """Record a plan the planner refused in ``folder``: an earlier run's outputs are marked
    stale and removed, ``plan.json`` says ``infeasible`` (verdict NO) or ``failed``
    (:meth:`~rfsw_plan.planfiles.record.PlanRecord.refused`; ``what``: what is refused when
    it is not the plan).

    Returns:
        The record written.
    """
    from rfsw_plan.planfiles.waypoints import PLAN_OUTPUTS, mark_outputs_stale

    with _transaction(folder) as out:
        mark_outputs_stale(out, problem, PLAN_OUTPUTS)
        record = PlanRecord.refused(problem, exc, force_uncertainty, what)
        record.write(out / "plan.json")
    return record


@contextlib.contextmanager
def _transaction(folder: str | Path) -> Iterator[Path]:
    """The plan folder, created if needed and locked (unless this process holds its lock);
    interrupted, a folder that was empty when the transaction began is emptied again."""
    from rfsw_plan.files import OutputLock, prepare_output_dir

    out = prepare_output_dir(folder, "folder")
    was_empty = not any(out.iterdir())
    try:
        if OutputLock.held(out) is not None:
            yield out
        else:
            with OutputLock(out, "folder"):
                yield out
    except KeyboardInterrupt:  # Ctrl-C, and SIGTERM as the CLI raises it
        if was_empty:
            _empty(out)
        raise


def _empty(folder: Path) -> None:
    """Remove everything in ``folder`` (a folder this transaction found empty)."""
    for p in list(folder.iterdir()):
        with contextlib.suppress(OSError):
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p, ignore_errors=True)
            else:
                p.unlink()


__all__ = ["PlanRequest", "PlanRun", "PlanWritten", "PreparedPlan", "ProgramsStep",
           "write_refusal"]
