"""Typed results of the planner."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.planning.baselines import BaselineMetrics
from rfsw_plan.planning.verdict import GO, TradeoffPoint, Verdict, tradeoff, verdict_of
from rfsw_plan.planning.verify import SampleVerification, Verification
from rfsw_plan.process.plan_options import PlanOptions
from rfsw_plan.process.task import PlanTask
from rfsw_plan.process.window import WeldWindow

if TYPE_CHECKING:  # the timing (SciPy's splines) is not on the path of a plan reader
    from rfsw_plan.timing.trajectory import TimedTrajectory

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class BranchInfo:
    """One configuration branch tried by the multi-start.

    Attributes:
        name: Seed name (``seed``, ``wrist_flip``, ...).
        feasible: IK reached every waypoint on this branch.
        q_start: Its configuration at the first waypoint [rad], (n,) (NaN if infeasible).
        min_lateral_stiffness: min 1 / (l^T C_tt l) on the taught path [N/m] (NaN if none).
        max_worst_case: max worst-case lateral deviation r on the taught path [m].
        note: Why it was rejected, or empty.
    """

    name: str
    feasible: bool
    q_start: FloatArray
    min_lateral_stiffness: float
    max_worst_case: float
    note: str = ""


@dataclass(frozen=True)
class PlanResult:
    """Everything the planner produces for one problem.

    Attributes:
        status: ``optimal`` (IPOPT converged, verified) or ``verified`` (IPOPT stopped early,
            or the mirror baseline was written, and the numeric verification holds); with
            ``_nominal`` when the requested force uncertainty is not held (see
            :meth:`verdict`).
        problem_name: The problem.
        robot_name: The robot.
        euler: Maker Euler convention of the robot (``none``, ``kuka_abc``, ``fanuc_wpr``).
        task: The planned waypoints (stationary start waypoints, then the weld).
        window: The weld window.
        options: The options used.
        q: Planned joint values [rad], (K, n).
        offsets: Planned offsets (lateral, normal, along-track) [m], (K, 3).
        tool_rotation: Tool rotation about its axis relative to tcp_orientation at rotation 0
            [rad], (K,).
        verification: The independent numeric verification.
        baselines: Metrics of ``none``, ``mirror`` and ``nlp`` (the written plan, its samples
            included), in that order: the one computation behind the table, the verdict,
            ``plan.json`` and the plots.
        e_none: Predicted lateral error without compensation [m], (K,).
        e_mirror: Predicted lateral error of the mirror baseline [m], (K,).
        branch: Name of the chosen configuration branch.
        branches: All branches tried.
        solver_status: IPOPT return status of the last solve.
        iterations: IPOPT iterations, summed over the outer loop.
        outer_iterations: Outer correction iterations.
        skipped_effects: Effects corrected by the outer loop instead of the NLP.
        solve_time: NLP wall time [s] (build + solves).
        verify_time: Verification wall time [s].
        timing_time: Time parameterisation wall time [s].
        total_time: Wall time of :func:`plan` [s].
        trajectory: The timed trajectory.
        model: The elastostatic model the plan was made and verified with; the writers
            predict deflections and errors with it (never with a model rebuilt from the
            robot file, which may differ from a ``plan(model=...)``).
        samples: The sample-by-sample verification of the written trajectory.
        source: What was written: ``nlp``, or ``mirror`` when the NLP's plan tolerated less
            force uncertainty than the mirror baseline (robust first).
        forces_calibrated: The forces and their uncertainty come from a trial weld's force
            log (``plan --forces``); the verdict then never advises it.
        measured_force_uncertainty: That log's uncertainty as a relative box at the plan's
            poses, or None.
    """

    status: str
    problem_name: str
    robot_name: str
    euler: str
    task: PlanTask
    window: WeldWindow
    options: PlanOptions
    q: FloatArray
    offsets: FloatArray
    tool_rotation: FloatArray
    verification: Verification
    baselines: tuple[BaselineMetrics, ...]
    e_none: FloatArray
    e_mirror: FloatArray
    branch: str
    branches: tuple[BranchInfo, ...]
    solver_status: str
    iterations: int
    outer_iterations: int
    skipped_effects: tuple[str, ...]
    solve_time: float
    verify_time: float
    timing_time: float
    total_time: float
    trajectory: TimedTrajectory
    model: ElastostaticModel
    samples: SampleVerification | None = None
    source: str = "nlp"
    forces_calibrated: bool = False
    measured_force_uncertainty: float | None = None

    @property
    def plan_metrics(self) -> BaselineMetrics:
        """The written plan's metrics (waypoints and written samples): the one computation
        the table, the verdict, ``plan.json`` and the plots quote."""
        return next(b for b in self.baselines if b.name == "nlp")

    @property
    def tolerated_force_uncertainty(self) -> float:
        """The largest uniform relative force uncertainty for which every weld quantity
        (lateral error, depth, work and travel angle, pin speed) holds at every in-material
        waypoint and written sample (:func:`~rfsw_plan.planning.verify.robust_claim`; inf: no
        uncertain force moves any)."""
        return self.plan_metrics.tolerated

    @property
    def tolerated_by_quantity(self) -> dict[str, float]:
        """Tolerated relative force uncertainty of every weld quantity of the written plan
        (``lateral``, ``depth``, ``tilt``, ``speed``; inf: no uncertain force moves it)."""
        claim = self.plan_metrics.claim
        return {} if claim is None else claim.levels

    @property
    def claim_force_model(self) -> dict[str, Any]:
        """The force model of the claim (``plan.json``): ``name`` (``force box`` or
        ``coupled axial law``) and ``penetration_stiffness_N_per_mm`` (k_p; null for the
        force box)."""
        claim = self.plan_metrics.claim
        k = 0.0 if claim is None else claim.penetration_stiffness
        return {"name": "coupled axial law" if k > 0 else "force box",
                "penetration_stiffness_N_per_mm": k * 1e-3 if k > 0 else None}

    @property
    def tolerated_by_strategy(self) -> dict[str, float]:
        """Tolerated relative force uncertainty of ``none``, ``mirror`` and ``nlp``."""
        return {b.name: b.tolerated for b in self.baselines}

    @property
    def robust_held(self) -> bool:
        """The plan holds the window under the requested force uncertainty at every
        in-material waypoint and written sample."""
        return self.verdict().word == GO

    def verdict(self) -> Verdict:
        """GO, HOLDS NOMINALLY (with the three levers) for this plan
        (:mod:`rfsw_plan.planning.verdict`)."""
        return verdict_of(self.baselines, self.options.force_uncertainty,
                          self.options.robust_first, self.forces_calibrated,
                          self.measured_force_uncertainty,
                          self.task.axial_control == "position")

    def tradeoff(self) -> tuple[TradeoffPoint, ...]:
        """Tolerated uncertainty against the weakest lateral stiffness: the plan, the
        baselines and the requested point (:func:`rfsw_plan.planning.verdict.tradeoff`)."""
        return tradeoff(self.baselines, self.options.force_uncertainty)

    @property
    def e_lat(self) -> FloatArray:
        """Verified predicted lateral pin error of the plan [m], (K,)."""
        return self.verification.prediction.e_lat

    def waypoint_times(self) -> FloatArray:
        """When the written samples pass each waypoint, on the clock of ``waypoints.csv``
        (``t_s``: approach first, the dwell as lengthened for the joint limits) [s], (K,).

        The schedule's own times (:attr:`PlanTask.time`, from the plunge start, the dwell as
        scheduled) are another clock; a time printed beside the files is this one. A travel
        waypoint is passed where the samples' arc length is its own; a plunge or dwell
        waypoint at the sample of its phase nearest to its joint values (the samples rest
        there).
        """
        tr, task = self.trajectory, self.task
        out = np.empty(len(task))
        travel = np.isin(tr.phase, ("accelerate", "weld", "decelerate"))
        for k in range(len(task)):
            ph = str(task.phase[k])
            if ph in ("accelerate", "weld", "decelerate") and travel.any():
                idx = np.flatnonzero(travel)
                out[k] = tr.t[idx[np.argmin(np.abs(tr.s[idx] - task.s[k]))]]
                continue
            idx = np.flatnonzero(tr.phase == ph)
            if not len(idx):
                idx = np.arange(len(tr.t))
            out[k] = tr.t[idx[np.argmin(np.linalg.norm(tr.q[idx] - self.q[k], axis=1))]]
        return out

    @property
    def worst_waypoint(self) -> int:
        """Waypoint with the smallest window margin."""
        return int(np.argmin(self.verification.margin))

    def envelope(self) -> dict[str, Any]:
        """The weld envelope as written (file units): the window of each quantity and its
        range over the written samples (:func:`~rfsw_plan.planning.verify.verify_samples`):
        depth error along the plate normal at full depth (+ shallow) [mm], largest tilt
        error [deg], pin speed along the seam less the commanded, in % of the weld speed, where
        the seam point moves [%], the
        pin's lowest height above the plate before the plunge [mm]; and the plunge as written:
        the predicted pin's depth error when the plunge ends (+ shallow) [mm], the depth of the
        commanded TCP below the plate surface there (the plunge the robot is commanded, the
        pin's planned depth plus the robot's give under the axial force) [mm], the spindle
        run-up before it and the dwell as written [s]."""
        w, sv = self.window, self.samples
        out: dict[str, Any] = {
            "axial_control": self.task.axial_control,
            # The force the controller's axial loop holds (force control; for the force_on
            # hook): the process model's steady axial force at the weld waypoints.
            "set_force_N": float(np.max(self.task.force_seam[self.task.weld, 2]))
            if self.task.axial_control == "force" else None,
            "depth_window_mm": [-w.depth_deep * 1e3, w.depth_shallow * 1e3],
            "tilt_tol_deg": float(np.rad2deg(w.tilt_tol)),
            "speed_tol_pct": w.speed_tol * 100,
        }
        if sv is None:
            return out
        before = self.trajectory.phase == "approach"
        h = sv.height
        tilt = _nanrange(sv.tilt_error, float(np.rad2deg(1.0)))
        out.update({
            "depth_error_mm": _nanrange(sv.depth_error, 1e3),
            "max_tilt_error_deg": tilt[1] if tilt else None,
            "pin_speed_deviation_pct": _nanrange(
                None if sv.speed_ratio is None else sv.speed_ratio - 1.0, 100.0),
            "min_height_before_plunge_mm": float(np.min(h[before])) * 1e3
            if h is not None and before.any() else None,
        })
        out.update(self._plunge_end())
        return out

    def _plunge_end(self) -> dict[str, Any]:
        """The last plunge sample (the pin at full depth): the pin's depth error there (+
        shallow) and the commanded TCP's depth below the surface along the plate normal [mm],
        and the run-up time the spindle had before the plunge moved down [s]."""
        tr, task, sv = self.trajectory, self.task, self.samples
        idx = np.flatnonzero(tr.phase == "plunge")
        if not len(idx) or not task.n_start:
            return {}
        i = int(idx[-1])
        m = task.n_start
        depth = float(np.max(task.depth))
        npl = task.plate_normal[m]
        tcp = self.model.robot.fk(tr.q[i])[:3, 3]
        commanded = depth - float(np.dot(npl, tcp - task.frames.p[m]))
        on = np.flatnonzero(tr.spindle_on)
        # From the spindle's start to the plunge's first move (the samples before stand at
        # the spindle's joint values).
        moved = (np.flatnonzero(np.any(np.abs(tr.q[idx] - tr.q[on[0]]) > 1e-12, axis=1))
                 if len(on) else np.zeros(0, dtype=int))
        runup = float(tr.t[idx[moved[0]] - 1] - tr.t[on[0]]) if len(moved) else 0.0
        dwell = np.flatnonzero(tr.phase == "dwell")
        stop = np.flatnonzero(tr.phase == "stop")
        end: dict[str, Any] = {}
        if len(stop):
            # The end stop from the weld's last sample: its length, the pin's sideways motion
            # (the sample check's), and the seam-frame force it relaxed to before the retract.
            rows = np.concatenate([stop[:1] - 1, stop])
            f_end = task.frames.rotation()[-1].T @ tr.wrench[stop[-1], :3]
            end = {"end_stop_s": float(tr.t[stop[-1]] - tr.t[rows[0]]),
                   "end_stop_pin_motion_mm": None if sv is None
                   else float(np.ptp(sv.e_lat[rows])) * 1e3,
                   "end_stop_force_N": [float(x) for x in f_end]}
        return {
            **end,
            "dwell_s": float(tr.t[dwell[-1]] - tr.t[i]) if len(dwell) else 0.0,
            "plunge_end_depth_error_mm": None if sv is None or sv.height is None
            else (float(sv.height[i]) + depth) * 1e3,
            "commanded_plunge_mm": commanded * 1e3,
            "spindle_runup_s": runup,
        }

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary in file units (mm, deg, N/mm, s)."""
        v = self.verification
        k = self.worst_waypoint
        t_k = float(self.waypoint_times()[k])
        sl = self.task.weld
        verdict = self.verdict()
        return {
            **verdict.to_dict(),
            "status": self.status,
            "problem": self.problem_name,
            "plan_source": self.source,
            "robust_first": self.options.robust_first,
            "force_uncertainty_requested": self.options.force_uncertainty,
            "tolerated_force_uncertainty": self.tolerated_force_uncertainty,
            # The level each weld quantity holds (fractions like the one above; null: no
            # uncertain force moves it, or under axial force control the depth).
            "tolerated_force_uncertainty_by_quantity": self.tolerated_by_quantity,
            # The force model the levels are on: the force box, or the axial force coupled
            # to the penetration ([process.coupling], position control) with its k_p.
            "claim_force_model": self.claim_force_model,
            "tolerated_force_uncertainty_by_strategy": dict(self.tolerated_by_strategy),
            "robust_window_held": verdict.word == GO,
            "tradeoff": [p.to_dict() for p in self.tradeoff()],
            "warning": verdict.traded or None,
            "samples": None if self.samples is None else {
                "n": len(self.samples.e_lat),
                "in_material": int(np.sum(self.samples.contact)),
                "verified": self.samples.ok,
                "min_margin_mm": self.samples.min_margin * 1e3,
                "max_abs_lateral_mm": float(np.max(np.abs(
                    self.samples.e_lat[self.samples.contact]))) * 1e3
                if self.samples.contact.any() else None,
                "limit_ratios": self.samples.limit_ratios,
                "stationarity_excess_mm": self.samples.station_excess * 1e3,
            },
            "envelope": self.envelope(),
            "robot": self.robot_name,
            "solver_status": self.solver_status,
            "ipopt_iterations": self.iterations,
            "outer_iterations": self.outer_iterations,
            "skipped_effects": list(self.skipped_effects),
            "branch": self.branch,
            "branches": [{"name": b.name, "feasible": b.feasible,
                          "min_lateral_stiffness_N_mm": b.min_lateral_stiffness * 1e-3,
                          "max_worst_case_mm": b.max_worst_case * 1e3, "note": b.note}
                         for b in self.branches],
            "n_waypoints": len(self.task),
            "n_start_waypoints": self.task.n_start,
            "window_mm": [self.window.lower * 1e3, self.window.upper * 1e3],
            "seam_reference": self.task.reference,
            "force_uncertainty": self.options.force_uncertainty,
            "weights": self.options.weights,
            "baselines": [b.to_dict() for b in self.baselines],
            "worst_waypoint": {
                # the phase of the written sample that passes it (a weld waypoint within the
                # acceleration's length is passed while the tool accelerates)
                "waypoint": k + 1, "index": k, "phase": str(self.trajectory.phase[int(
                    np.argmin(np.abs(self.trajectory.t - t_k)))]),
                "s_mm": self.task.s[k] * 1e3, "t_s": t_k,
                "e_lat_mm": v.prediction.e_lat[k] * 1e3, "margin_mm": v.margin[k] * 1e3,
                "worst_case_mm": v.prediction.worst[k] * 1e3,
                "robust_margin_mm": v.robust_margin[k] * 1e3,
            },
            # The travel waypoints only (named so: samples.max_abs_lateral_mm and the plan's
            # baseline row also count the plunge and dwell in the material).
            "max_abs_lateral_weld_mm": float(np.max(np.abs(v.prediction.e_lat[sl]))) * 1e3,
            "min_margin_mm": float(np.min(v.margin)) * 1e3,
            "robust_window_held_fraction": float(np.mean(v.robust_margin >= -1e-9)),
            "weld_speed_mm_s": self.trajectory.weld_speed * 1e3,
            "pin_speed_during_weld_mm_s": _range(self.trajectory.pin_speed()[
                self.trajectory.phase == "weld"][1:-1] * 1e3),
            "max_abs_along_track_error_mm": float(np.max(np.abs(v.along_error))) * 1e3,
            "max_feasible_weld_speed_mm_s": self.trajectory.max_weld_speed * 1e3,
            "duration_s": float(self.trajectory.t[-1]),
            "waypoints": {
                "phase": [str(p) for p in self.task.phase],
                "s_mm": (self.task.s * 1e3).tolist(),
                "q_deg": np.rad2deg(self.q).tolist(),
                "off_lat_mm": (self.offsets[:, 0] * 1e3).tolist(),
                "off_norm_mm": (self.offsets[:, 1] * 1e3).tolist(),
                "off_along_mm": (self.offsets[:, 2] * 1e3).tolist(),
                "tool_rotation_deg": np.rad2deg(self.tool_rotation).tolist(),
                "e_lat_mm": (v.prediction.e_lat * 1e3).tolist(),
                "e_along_mm": (v.along_error * 1e3).tolist(),
                "e_lat_none_mm": (self.e_none * 1e3).tolist(),
                "e_lat_mirror_mm": (self.e_mirror * 1e3).tolist(),
                "worst_case_mm": (v.prediction.worst * 1e3).tolist(),
                "margin_mm": (v.margin * 1e3).tolist(),
                "lateral_stiffness_N_mm": (v.prediction.lateral_stiffness * 1e-3).tolist(),
                "kappa_f": v.prediction.kappa.tolist(),
            },
        }


def _nanrange(x: FloatArray | None, scale: float) -> list[float]:
    """[min, max] of the finite values of x times scale, or [] if none."""
    if x is None:
        return []
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return [float(np.min(x)) * scale, float(np.max(x)) * scale] if len(x) else []


def _range(x: FloatArray) -> list[float]:
    """[min, max] of x, or [] if empty."""
    return [float(np.min(x)), float(np.max(x))] if len(x) else []
