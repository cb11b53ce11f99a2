"""Plan with the forces of a trial weld (``rfsw-plan plan PROBLEM --forces LOG.csv``).

1. The log is read and fitted as ``deviation --forces`` does
   (:func:`~rfsw_plan.process.force_fit.fit_process_forces`, seed 001 eq. 15 over the whole
   series: steady forces, plunge peak, dwell build-up, weld ramp).
2. The force uncertainty is derived from the fit
   (:func:`~rfsw_plan.process.force_fit.derive_force_uncertainty`): per phase and seam-frame
   component, max |drift| + c sigma [N], at the stated coverage c.
3. The planner's robust constraint is a relative box |delta f_i| <= u |f_i| per seam component
   (seed 000 eq. 11 worst case). The measured box is absolute, delta_i [N]; the plan uses the
   smallest u that covers it at every waypoint for the lateral worst case::

       u_k = sum_i delta_i |l^T C_tt b_i| / sum_i |f_k,i| |l^T C_tt b_i|,   u = max_k u_k

   (b_i the seam axes, C_tt the translational compliance at the waypoint's pose; waypoints
   loaded less than :data:`LOADED_SHARE` of the weld are left out). u depends on
   the poses, so it is evaluated on the plan and the plan is repeated once if the plan's own
   poses need a larger u.
4. The exact worst case under the measured box, r_k = sum_i delta_i |l^T C_tt b_i|, is checked
   at the plan's poses: the plan holds if e_k +- r_k stays inside the window at every
   waypoint.

A log the force model cannot describe is reported and not used (the problem's forces and
uncertainty stay).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError
from rfsw_plan.io.force_series import ForceSeries, read_force_series
from rfsw_plan.process.force_fit import (
    COVERAGE_SIGMA,
    ForceFit,
    ForceUncertainty,
    derive_force_uncertainty,
    fit_process_forces,
    series_in_seam_frame,
)
from rfsw_plan.process.frames import FloatArray
from rfsw_plan.process.problem import Problem, with_process

#: A log whose median axial force during the weld is below this share of the problem's axial
#: force has no axial force (an unconnected channel, a log of another axis).
MIN_AXIAL_SHARE = 0.05
#: Waypoints whose force moves the pin laterally by less than this share of the weld's (the
#: start of the plunge) are left out of the relative box: a relative box cannot cover an
#: absolute uncertainty at zero force; their exact worst case is in :func:`check_measured_box`.
LOADED_SHARE = 0.5
#: The plan is repeated when its own poses need a u this much larger than the one planned.
U_TOLERANCE = 1e-3


@dataclass(frozen=True)
class ForceLog:
    """A fitted force log ready for planning.

    Attributes:
        source: The CSV file.
        fit: The force-model fit.
        uncertainty: The derived force uncertainty (its ``usable`` says whether the plan uses
            the log).
        problem: The problem with the fitted forces if usable, else the original problem.
    """

    source: str
    fit: ForceFit
    uncertainty: ForceUncertainty
    problem: Problem

    @property
    def usable(self) -> bool:
        """The plan uses the fitted forces and the derived uncertainty."""
        return self.uncertainty.usable

    def summary(self) -> str:
        """Fit quality and uncertainty, printed by ``plan --forces``."""
        head = (f"force log {self.source}: " + ("used for planning" if self.usable else
                                                 f"NOT used: {self.uncertainty.reason}"))
        return "\n".join([head, self.fit.summary(), self.uncertainty.summary()])


def check_axial(series: ForceSeries, problem: Problem, tool_rotation: float = 0.0) -> None:
    """Reject a log without an axial force during the weld.

    Raises:
        InputError: The median axial (seam n) force over the log's weld samples is below
            :data:`MIN_AXIAL_SHARE` of the problem's steady axial force, or the log has no
            loaded sample at all.
    """
    sched = problem.process.evaluate(problem.frames(), series.t)
    f, _ = series_in_seam_frame(series, sched, tool_rotation)
    weld = np.asarray(sched.phase) == "weld"
    use = weld if np.any(weld) else np.isin(sched.phase, ("plunge", "dwell"))
    if not np.any(use):
        raise InputError(series.source, "t_s", f"the log ({series.t[0]:g}..{series.t[-1]:g} s) "
                         "has no sample in the plunge, dwell or weld of this problem",
                         "a log timed from the process start")
    med = float(np.median(f[use, 2]))
    ref = problem.process.forces.axial
    if not med > MIN_AXIAL_SHARE * ref:
        raise InputError(series.source, f"frame {series.frame}",
                         f"no axial force: median f_n {med:.0f} N over the weld (the problem "
                         f"expects about {ref:.0f} N)",
                         "the axial force on the tool (+n, pushing the tool up) in fx/fy/fz_N; "
                         "check the frame (`forces_frame`) and the channel")


def load_force_log(
    problem: Problem, path: str | Path, frame: str | None = None,
    coverage: float = COVERAGE_SIGMA,
) -> ForceLog:
    """Read, check and fit a force log and derive its uncertainty.

    Raises:
        InputError: Unreadable log, no axial force (:func:`check_axial`).
        IdentificationError: Too few samples for the fit.
    """
    series = read_force_series(path, frame)
    rot = problem.planning.tool_rotation
    check_axial(series, problem, rot)
    frames = problem.frames()
    fit = fit_process_forces(problem.process, frames, series, rot)
    unc = derive_force_uncertainty(fit, frames, series, rot, coverage)
    fitted = with_process(problem, fit.process) if unc.usable else problem
    return ForceLog(str(path), fit, unc, fitted)


def lateral_sensitivity(model: ElastostaticModel, task: Any, q: FloatArray) -> FloatArray:
    """|l^T C_tt b_i| for the seam axes b = (t, l, n) at every waypoint [m/N], shape (K, 3)."""
    batch = model.batch(np.atleast_2d(q))
    Ctt = model.physical().cartesian_compliance(batch)[:, :3, :3]
    fr = task.frames
    lC = np.einsum("ki,kij->kj", fr.l, Ctt)
    return np.abs(np.stack([np.einsum("kj,kj->k", lC, b) for b in (fr.t, fr.l, fr.n)], axis=1))


def equivalent_uncertainty(
    model: ElastostaticModel, task: Any, q: FloatArray, unc: ForceUncertainty
) -> float:
    """The smallest relative box u covering the measured box at every waypoint (module
    docstring, step 3) [-]."""
    sens = lateral_sensitivity(model, task, q)
    box = unc.box(np.asarray(task.phase))
    num = np.sum(box * sens, axis=1)
    den = np.sum(np.abs(task.force_seam) * sens, axis=1)
    weld = np.asarray(task.phase) == "weld"
    ref = float(np.median(den[weld])) if np.any(weld) else float(np.max(den))
    loaded = den >= LOADED_SHARE * ref
    if not np.any(loaded):
        return 0.0
    return float(np.max(num[loaded] / den[loaded]))


@dataclass(frozen=True)
class MeasuredBoxCheck:
    """The plan under the measured force box (module docstring, step 4).

    Attributes:
        worst: r_k [m], shape (K,).
        robust_margin: Distance of e_k +- r_k to the nearest window bound [m], (K,).
        u_equivalent: The relative box that covers the measured one at the plan's poses [-].
        u_planned: The relative box the plan was made for [-].
    """

    worst: FloatArray
    robust_margin: FloatArray
    u_equivalent: float
    u_planned: float

    @property
    def holds(self) -> bool:
        """e +- r inside the window at every waypoint."""
        return bool(np.all(self.robust_margin >= -1e-9))

    @property
    def held_fraction(self) -> float:
        """Share of the waypoints where e +- r is inside the window."""
        return float(np.mean(self.robust_margin >= -1e-9))


def check_measured_box(result: Any, model: ElastostaticModel, unc: ForceUncertainty
                       ) -> MeasuredBoxCheck:
    """Worst case of a plan under the measured force box at its own poses."""
    task = result.task
    sens = lateral_sensitivity(model, task, result.q)
    r = np.sum(unc.box(np.asarray(task.phase)) * sens, axis=1)
    e = result.e_lat
    w = result.window
    margin = np.minimum(e - r - w.lower, w.upper - (e + r))
    return MeasuredBoxCheck(r, margin, equivalent_uncertainty(model, task, result.q, unc),
                            float(result.options.force_uncertainty))


def plan_with_force_log(
    log: ForceLog, options: Any, spacing: float | None = None,
    model: ElastostaticModel | None = None,
) -> tuple[Any, MeasuredBoxCheck | None]:
    """Plan with the fitted forces and the derived uncertainty (module docstring).

    Args:
        log: The fitted log (if not usable, this is a plain :func:`plan` of its problem).
        options: :class:`~rfsw_plan.process.plan_options.PlanOptions`; its ``force_uncertainty``
            is replaced by the equivalent of the measured box when the log is usable.
        spacing: Waypoint spacing [m].
        model: Elastostatic model (default: the problem's robot).

    Returns:
        The plan result and its check under the measured box (None if the log is unused).

    Raises:
        InfeasibleError: No plan holds (as :func:`~rfsw_plan.planning.api.plan`).
    """
    from dataclasses import replace

    from rfsw_plan.planning.api import plan
    from rfsw_plan.robot.kinematics import load_robot

    if not log.usable:
        return plan(log.problem, options, spacing=spacing, model=model), None
    model = model or ElastostaticModel(load_robot(log.problem.robot))
    # u depends on the poses: measure it on a plan at the problem's u, then plan at it.
    first = plan(log.problem, options, spacing=spacing, model=model)
    u = equivalent_uncertainty(model, first.task, first.q, log.uncertainty)
    result = plan(log.problem, replace(options, force_uncertainty=u), spacing=spacing,
                  model=model)
    check = check_measured_box(result, model, log.uncertainty)
    if check.u_equivalent > u * (1 + U_TOLERANCE):
        result = plan(log.problem, replace(options, force_uncertainty=check.u_equivalent),
                      spacing=spacing, model=model)
        check = check_measured_box(result, model, log.uncertainty)
    # The verdict reports the calibration as done and never advises it again.
    return replace(result, forces_calibrated=True,
                   measured_force_uncertainty=check.u_equivalent), check


def force_log_json(log: ForceLog, check: MeasuredBoxCheck | None) -> dict[str, Any]:
    """The ``force_log`` block of ``plan.json``: fit quality, derived uncertainty, and the
    plan under the measured box."""
    fit = log.fit
    out: dict[str, Any] = {
        "file": log.source, "used": log.usable, "reason": log.uncertainty.reason,
        "fit": {"params": fit.params, "std": fit.std, "fixed": list(fit.fixed),
                "rms_N": [float(x) for x in fit.rms],
                "r2": [float(x) if np.isfinite(x) else None for x in fit.r2],
                "rms_total_N": fit.rms_total, "n_samples": fit.n_samples,
                "notes": list(fit.notes)},
        "measured_force_uncertainty": log.uncertainty.to_json(),
    }
    if check is not None:
        out["plan_under_measured_uncertainty"] = {
            "holds": check.holds, "held_fraction": check.held_fraction,
            "min_robust_margin_mm": float(np.min(check.robust_margin)) * 1e3,
            "max_worst_case_mm": float(np.max(check.worst)) * 1e3,
            "equivalent_relative_uncertainty": check.u_equivalent,
            "planned_relative_uncertainty": check.u_planned,
        }
    return out


def check_text(check: MeasuredBoxCheck, window: Any) -> str:
    """One line: does the plan hold under the measured force uncertainty."""
    k = int(np.argmin(check.robust_margin))
    verdict = "HOLDS" if check.holds else "does NOT hold"
    return (f"plan under the measured force uncertainty (relative box {100 * check.u_planned:.1f}"
            f" % planned, {100 * check.u_equivalent:.1f} % needed at its poses): {verdict}; "
            f"worst case +-{check.worst[k] * 1e3:.3f} mm at waypoint {k}, robust margin "
            f"{check.robust_margin[k] * 1e3:+.3f} mm, window [{window.lower * 1e3:g}, "
            f"{window.upper * 1e3:g}] mm")
