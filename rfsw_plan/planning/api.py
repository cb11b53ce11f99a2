"""``plan(problem)``: the whole planning pipeline.

1. Waypoints: the seam frames at the problem's spacing plus stationary waypoints over the
   plunge and dwell force ramp (:func:`~rfsw_plan.process.task.task_from_schedule`), with the
   problem's seam reference (``taught``/``absolute``: how the modelled process wrench deflects
   the TCP, :meth:`~rfsw_plan.elastostatics.model.ElastostaticModel.process_deflection`).
2. Branches: the taught path (IK) from the problem's seed and from elbow/wrist/shoulder flips;
   the continuous ones are ranked by worst-case deviation and lateral stiffness, the best is
   planned (the others are reported).
3. Baselines: no compensation and the mirror fixed point (numeric; lateral, normal and
   along-track offsets).
4. NLP from the mirror baseline, with an outer correction loop for effects the symbolic model
   lacks and a re-linearisation of the singularity constraint.
5. Independent numeric verification; an infeasible plan raises :class:`InfeasibleError`.
6. Time parameterisation (TOPPRA speed check, Ruckig pieces, limit check at every sample) on
   the pin's arc length, and the pin's predicted travel along the seam at every sample
   (:func:`~rfsw_plan.planning.verify.pin_track`).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InfeasibleError, UnreachableError
from rfsw_plan.planning.baselines import (
    BaselineMetrics,
    BaselinePlan,
    branch_seeds,
    commanded_poses,
    ik_paths,
    metrics,
    metrics_and_prediction,
    mirror_compensation,
    no_compensation,
)
from rfsw_plan.planning.coarse import interpolate_coarse, project_fine, subsample_task
from rfsw_plan.planning.nlp import (
    PlanNLP,
    build_plan_nlp,
    nlp_prediction,
    solve_plan_nlp,
    update_parameters,
)
from rfsw_plan.planning.result import BranchInfo, PlanResult
from rfsw_plan.planning.robustness import DOMINANCE_TOL, SECOND_STAGE_SLACK, nlp_options
from rfsw_plan.planning.verify import (
    SampleVerification,
    Verification,
    pin_track,
    predict,
    shared_evaluations,
    tolerated_uncertainty,
    verify_plan,
    verify_samples,
)
from rfsw_plan.process.frames import tcp_orientation
from rfsw_plan.process.plan_options import PlanOptions, check_well_posed
from rfsw_plan.process.task import FloatArray, PlanTask, task_for
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.progress import Stages
from rfsw_plan.robot.kinematics import Robot, check_stiffness_scale, load_robot
from rfsw_plan.timing.trajectory import (
    TimedTrajectory,
    TimingLimits,
    time_parameterise,
    timing_limits,
)
from rfsw_plan.tomlreader import unknown_name_error

log = logging.getLogger(__name__)


def options_from_problem(problem: Any, overrides: dict[str, Any] | None = None) -> PlanOptions:
    """The problem's planner options (its ``[planning]`` table), with keyword overrides (SI).

    Raises:
        InputError: An override that is not a :class:`PlanOptions` field, or out of range.
    """
    opts: PlanOptions = problem.planning
    if not overrides:
        return opts
    known = {f.name for f in dataclasses.fields(PlanOptions)}
    for k in overrides:
        if k not in known:
            raise unknown_name_error("options", "", k, known, "option")
    return dataclasses.replace(opts, **overrides)


def tool_rotation_of(robot: Robot, task: PlanTask, q: FloatArray) -> FloatArray:
    """Rotation of the TCP x axis about the tool axis relative to rotation 0 [rad], (K,)."""
    R0 = tcp_orientation(task.frames, 0.0)
    T = robot.batch_fk_jacobian(q)[0]
    x = T[:, :3, 0]
    return np.unwrap(np.arctan2(np.einsum("ki,ki->k", x, R0[:, :, 1]),
                                np.einsum("ki,ki->k", x, R0[:, :, 0])))


def tool_is_coaxial(robot: Robot, tol: float = 1e-9) -> bool:
    """True if the tool axis (TCP z) is the last joint's axis: then a rotation about the tool
    axis turns the last joint only and cannot change the compliance, so the multi-start over
    tool rotations is skipped."""
    g = robot.geometry
    a = np.asarray(g.axes[-1], dtype=float)
    a = a / np.linalg.norm(a)
    T = g.tcp
    return bool(np.linalg.norm(np.cross(a, T[:3, 2])) < tol
                and np.linalg.norm(np.cross(a, T[:3, 3])) < tol * max(1.0, float(
                    np.linalg.norm(T[:3, 3]))) * 1e3)


def start_objective(model: ElastostaticModel, task: PlanTask, q: FloatArray, window: WeldWindow,
                    opts: PlanOptions, cref: float) -> tuple[float, Any]:
    """The NLP objective a taught path q (K, n) [rad] starts from (after the mirror offsets
    centre the nominal error), in the NLP's priority order: the robust excess
    max(r_k - (half width - margin), 0) (w_robust), the worst case r_k (w_worst) and the lateral
    compliance (w_stiffness: mean and weakest weld waypoint, relative to ``cref`` [m/N]).

    Returns the objective and the numeric prediction (weld waypoints ranked)."""
    pred = predict(model, task, q, opts.force_uncertainty, opts.length_scale)
    sl = task.weld
    hw = window.half_width
    r = pred.worst[sl]
    cll = pred.lateral_compliance[sl]
    share = opts.min_stiffness_share
    f = (opts.w_robust * float(np.mean(np.maximum(r - (hw - opts.margin), 0.0))) / hw
         + opts.w_worst * float(np.mean(r)) / hw
         + opts.w_stiffness * ((1 - share) * float(np.mean(cll)) + share * float(np.max(cll)))
         / cref)
    return f, pred


@dataclass(frozen=True)
class BranchChoice:
    """The taught path :func:`choose_branch` starts the planner from.

    Attributes:
        taught: The taught path on the full task (no offsets).
        name: Its branch name (``seed``, ``wrist_flip@90deg``, ...).
        branches: Every candidate's summary.
        rotation: Its tool rotation about the tool axis [rad].
        q_taught0: The configuration [rad] (n,) of the same branch at the problem's tool
            rotation at the first waypoint (the seed of baselines 1 and 2), or None.
    """

    taught: BaselinePlan
    name: str
    branches: tuple[BranchInfo, ...]
    rotation: float
    q_taught0: FloatArray | None


@dataclass
class _Candidates:
    """What the ranking of the taught paths collects (see :func:`choose_branch`)."""

    infos: list[BranchInfo] = field(default_factory=list)
    # (objective, order, name, coarse path, rotation)
    ranked: list[tuple[float, int, str, FloatArray, float]] = field(default_factory=list)
    taught_start: dict[str, FloatArray] = field(default_factory=dict)
    first_error: Exception | None = None


def _branch_starts(robot: Robot, q_seed: FloatArray, opts: PlanOptions
                   ) -> list[tuple[str, FloatArray, float]]:
    """(name, seed [rad] (n,), tool rotation [rad]) of every branch and tool rotation tried."""
    seeds = branch_seeds(robot, q_seed) if opts.branches else [("seed", q_seed)]
    n_rot = 1 if tool_is_coaxial(robot) else opts.rotation_starts
    return [
        (f"{name}" if k == 0 else f"{name}@{np.rad2deg(2 * np.pi * k / n_rot):.0f}deg",
         seed, opts.tool_rotation + 2 * np.pi * k / n_rot)
        for name, seed in seeds for k in range(n_rot)
    ]


def _rank_candidates(model: ElastostaticModel, coarse: PlanTask, opts: PlanOptions,
                     window: WeldWindow, step_max: float,
                     starts: list[tuple[str, FloatArray, float]]) -> _Candidates:
    """Teach every start on the coarse task and rank the continuous, non-singular paths by
    :func:`start_objective`."""
    robot = model.robot
    out = _Candidates()
    nan_q = np.full(robot.nq, np.nan)
    cref = np.nan
    zero = np.zeros((len(coarse), 3))
    paths = ik_paths(robot, np.stack([commanded_poses(coarse, zero, rot) for _, _, rot in starts]),
                     np.stack([seed for _, seed, _ in starts]), s=coarse.s)
    for (name, _, rotation), path in zip(starts, paths, strict=True):
        if isinstance(path, UnreachableError):
            out.first_error = out.first_error or path
            out.infos.append(BranchInfo(name, False, nan_q, np.nan, np.nan, str(path)))
            continue
        if rotation == opts.tool_rotation:
            out.taught_start.setdefault(name, path[0])
        if any(np.allclose(path, c[3], atol=1e-4) for c in out.ranked):
            out.infos.append(BranchInfo(name, False, path[0], np.nan, np.nan,
                                        "same branch as an earlier seed"))
            continue
        if not np.isfinite(cref):
            cref = float(np.mean(predict(model, coarse, path, 0.0)
                                 .lateral_compliance[coarse.weld]))
        f, pred = start_objective(model, coarse, path, window, opts, cref)
        note = _path_note(coarse, pred.kappa, path, opts.kappa_max, step_max)
        kmin = float(np.min(pred.lateral_stiffness[coarse.weld]))
        out.infos.append(BranchInfo(name, not note, path[0], kmin, float(np.max(pred.worst)),
                                    note))
        if not note:
            out.ranked.append((f, len(out.ranked), name, path, rotation))
    out.ranked.sort(key=lambda c: (round(c[0], 9), c[1]))
    return out


def _no_candidate(cands: _Candidates) -> Exception:
    """The error when no taught path is continuous and non-singular."""
    bad = [i for i in cands.infos if i.note and "singularity" in i.note]
    if bad:
        return InfeasibleError(bad[0].note, constraint="singularity")
    if cands.first_error is not None:
        return cands.first_error
    return InfeasibleError("no continuous configuration branch: " + cands.infos[0].note,
                           constraint="joint_step")


def choose_branch(
    model: ElastostaticModel, task: PlanTask, q_seed: FloatArray, opts: PlanOptions,
    window: WeldWindow | None = None,
) -> BranchChoice:
    """Taught paths on all branches and tool rotations; the best continuous, non-singular one.

    Every branch is tried at ``rotation_starts`` tool rotations about the tool axis (unless the
    tool is coaxial with the last joint, see :func:`tool_is_coaxial`), on a subsampled task.
    Candidates are ranked by :func:`start_objective`, the NLP's own priorities (robust window
    first, then worst case and stiffness), so the local NLP starts in the basin it would
    choose; ties keep the problem's branch and tool rotation. The winner is re-taught on the
    full task (the next candidate is taken if that path flips or passes a singularity).

    Raises:
        UnreachableError: No branch reaches every waypoint (the seed's error is re-raised).
        InfeasibleError: Every reachable branch passes a singularity or a joint-step jump.
    """
    robot = model.robot
    window = window or WeldWindow()
    coarse, idx = subsample_task(task)
    spread = max(float(np.max(np.diff(idx))) if len(idx) > 1 else 1.0, 1.0)
    step_max = min(opts.joint_step * spread, np.deg2rad(90.0))
    cands = _rank_candidates(model, coarse, opts, window, step_max,
                             _branch_starts(robot, q_seed, opts))
    if not cands.ranked:
        raise _no_candidate(cands)
    note = ""
    for _, _, name, q_coarse, rotation in cands.ranked:
        near = interpolate_coarse(task, idx, q_coarse) if coarse is not task else None
        try:
            taught = no_compensation(robot, task, q_coarse[0], rotation, q_near=near)
        except UnreachableError as exc:
            note = str(exc)
            continue
        if coarse is not task:
            pred = predict(model, task, taught.q, 0.0, opts.length_scale)
            note = _path_note(task, pred.kappa, taught.q, opts.kappa_max, opts.joint_step)
            if note:
                continue
        return BranchChoice(taught, name, tuple(cands.infos), rotation,
                            cands.taught_start.get(name.split("@")[0]))
    raise InfeasibleError(f"no candidate branch holds on the full seam: {note}",
                          constraint="singularity" if "singularity" in note else "joint_step")


def _path_note(task: PlanTask, kappa: FloatArray, q: FloatArray, kappa_max: float,
               step_max: float) -> str:
    """Why a taught path is rejected (singularity or a branch flip), or empty."""
    kmax = float(np.max(kappa))
    if kmax > kappa_max:
        k = int(np.argmax(kappa))
        return (f"path through a singularity at waypoint {k} (s = {task.s[k] * 1e3:.1f} mm): "
                f"kappa_f = {kmax:.3g} > {kappa_max:g}")
    step = float(np.max(np.abs(np.diff(q, axis=0)))) if len(q) > 1 else 0.0
    if step > step_max:
        return f"joint step {np.rad2deg(step):.1f} deg between waypoints (branch flip)"
    return ""


def plan(
    problem: Any,
    options: PlanOptions | None = None,
    spacing: float | None = None,
    model: ElastostaticModel | None = None,
    compile_c: bool | None = None,
) -> PlanResult:
    """Plan poses and fake-target offsets for a problem, verify and time them.

    Args:
        problem: A :class:`~rfsw_plan.process.problem.Problem` or a problem name / path.
        options: Planner options (default: from the problem's ``[planning]`` table).
        spacing: Waypoint spacing along the seam [m] (default: the problem's).
        model: Elastostatic model (default: the robot file's model).
        compile_c: Compile the NLP functions to C (None: automatic by size).

    Raises:
        UnreachableError: The seam leaves the workspace (first waypoint, by how far).
        InfeasibleError: Singular path, infeasible window, or infeasible weld speed; names the
            waypoint, constraint and margin. Exit code 3 in the CLI.
    """
    from rfsw_plan.process.problem import Problem, load_problem

    t_all = time.perf_counter()
    if not isinstance(problem, Problem):
        problem = load_problem(problem)
    opts = options or options_from_problem(problem)
    robot = load_robot(problem.robot)
    model = model or ElastostaticModel(robot)
    robot = model.robot
    window: WeldWindow = problem.window
    process = problem.process
    task = task_for(problem, spacing or problem.spacing, opts.max_start_waypoints)
    q_seed = np.asarray(opts.q_seed) if opts.q_seed is not None else problem.q_seed()
    return plan_task(model, task, window, q_seed, opts, problem.name, compile_c,
                     timing_limits(opts, process), t_all)


def plan_task(
    model: ElastostaticModel, task: PlanTask, window: WeldWindow, q_seed: FloatArray,
    opts: PlanOptions, name: str = "", compile_c: bool | None = None,
    timing: TimingLimits | None = None, t_start: float | None = None,
) -> PlanResult:
    """The pipeline of :func:`plan` on an explicit task (see there), with a progress bar over
    its stages on stderr (:mod:`rfsw_plan.progress`: only on a terminal, not with ``-q``).
    Its stages evaluate each joint-value array with the numeric model once
    (:func:`~rfsw_plan.planning.verify.shared_evaluations`).

    Raises:
        InputError: A joint stiffness so soft under the task's loads that it can only be in
            the wrong unit (:func:`~rfsw_plan.robot.kinematics.check_stiffness_scale`).
    """
    check_stiffness_scale(model.robot, q_seed, task.wrench_base)
    # Every joint-value array the stages share is evaluated once (verify.shared_evaluations).
    with Stages("plan", _STAGES) as stages, shared_evaluations(model):
        return _plan_task(model, task, window, q_seed, opts, name, compile_c, timing, t_start,
                          stages)


# Stages of the planning pipeline, as the progress bar names them.
_STAGES = ("branches and tool rotations", "baselines", "NLP (first run compiles C)",
           "verification", "timing", "sample check")


@dataclass(frozen=True)
class Baselines:
    """The taught path and the mirror fixed point the plan is compared with and started from.

    Attributes:
        taught: Baseline 1 at the problem's tool rotation on the chosen branch.
        mirror: Baseline 2 on ``taught``.
        warm: The mirror fixed point at the chosen tool rotation (the NLP's warm start; the
            same as ``mirror`` when the multi-start kept the problem's rotation).
    """

    taught: BaselinePlan
    mirror: BaselinePlan
    warm: BaselinePlan


def _baselines(model: ElastostaticModel, task: PlanTask, choice: BranchChoice,
               opts: PlanOptions) -> Baselines:
    """Baselines 1 and 2 are what an engineer gets at the taught tool rotation on this branch;
    the NLP may start elsewhere when the multi-start found a better rotation."""
    warm = mirror_compensation(model, task, choice.taught.q, choice.rotation)
    if choice.rotation == opts.tool_rotation:
        return Baselines(choice.taught, warm, warm)
    q0 = choice.taught.q[0] if choice.q_taught0 is None else choice.q_taught0
    try:
        taught = no_compensation(model.robot, task, q0, opts.tool_rotation)
        return Baselines(taught, mirror_compensation(model, task, taught.q, opts.tool_rotation),
                         warm)
    except UnreachableError:
        log.info("taught rotation unreachable on branch %s; baselines use the start",
                 choice.name)
        return Baselines(choice.taught, warm, warm)


@dataclass(frozen=True)
class Written:
    """A candidate plan verified at its waypoints, timed and checked at every sample.

    Attributes:
        q: Joint values [rad], (K, n).
        offsets: Offsets (lateral, normal, along-track) [m], (K, 3).
        verification: Its waypoint verification.
        trajectory: Its timed trajectory.
        samples: Its sample verification.
        metrics: Its metrics (waypoints and samples, at the requested uncertainty).
        source: ``nlp`` or the baseline it is (``mirror``).
        timing_time: Wall time of the timing [s].
    """

    q: FloatArray
    offsets: FloatArray
    verification: Verification
    trajectory: TimedTrajectory
    samples: SampleVerification
    metrics: BaselineMetrics
    source: str
    timing_time: float


def deflection_of(model: ElastostaticModel, task: PlanTask) -> Any:
    """The TCP deflection [m] (N, 3) of joint values (N, n) [rad] under wrenches (N, 6), by
    the numeric model with the task's seam reference (what the timing needs for the
    retract)."""
    def deflect(q: FloatArray, wrench: FloatArray) -> FloatArray:
        dX = model.process_deflection_batch(model.batch(np.atleast_2d(q)), wrench,
                                            task.reference)
        return np.asarray(dX[:, :3])
    return deflect


def written_plan(model: ElastostaticModel, task: PlanTask, window: WeldWindow,
                 opts: PlanOptions, q: FloatArray, offsets: FloatArray,
                 timing: TimingLimits | None, source: str = "nlp", note: str = "",
                 stages: Stages | None = None,
                 reference_offsets: FloatArray | None = None) -> Written:
    """Verify joint values and offsets at the waypoints, time them and check every sample.

    ``reference_offsets`` are the offsets whose change the load itself demands [m], (K, 3)
    (the warm start's mirror offsets, as the NLP's offset-rate rows use them).

    Raises:
        InfeasibleError: A waypoint check fails (``note`` is added to the message), the weld
            speed is not feasible, or a written sample fails.
    """
    ver = verify_plan(model, task, window, q, offsets, opts.force_uncertainty,
                      opts.robust_hard, opts.joint_step * (1 + 1e-6), opts.kappa_max,
                      opts.length_scale, options=opts, reference_offsets=reference_offsets)
    if stages is not None:
        stages.start("timing")
    if not ver.feasible:
        raise InfeasibleError(ver.messages[0] + note, ver.worst_waypoint, ver.binding,
                              ver.binding_margin)
    t0 = time.perf_counter()
    traj = time_parameterise(model.robot, task, q, offsets, timing,
                             deflection_of(model, task))
    traj = replace(traj, s_pin=pin_track(model, task, traj))
    timing_time = time.perf_counter() - t0
    if stages is not None:
        stages.start("sample check")
    # What is written is what is verified: every sample, independently of the timing.
    samples = verify_samples(model, task, window, traj, opts.margin, q)
    samples.raise_if_failed()
    m = metrics("nlp", model, task, q, window, opts.force_uncertainty, samples)
    return Written(q, offsets, ver, traj, samples, m, source, timing_time)


def dominant(model: ElastostaticModel, task: PlanTask, window: WeldWindow, opts: PlanOptions,
             plan: Written, mirror: BaselinePlan, mirror_metrics: BaselineMetrics,
             timing: TimingLimits | None) -> tuple[Written, BaselineMetrics]:
    """The plan, or the mirror baseline written as the plan when that tolerates more.

    Robust first (:mod:`rfsw_plan.planning.robustness`), the written plan must tolerate at
    least the mirror baseline's force uncertainty, less
    :data:`~rfsw_plan.planning.robustness.DOMINANCE_TOL`. The mirror's waypoints alone are
    judged first (``mirror_metrics``); if the NLP's plan holds less than they do, the mirror
    fixed point is verified, timed and sample-checked like the plan, so both are judged on
    what would be written: it is written instead when it tolerates more (by more than
    ``DOMINANCE_TOL``). A mirror that cannot be written (a written sample leaves the window
    between its waypoints, or another check the plan passed fails) holds nothing: its
    metrics then say why (``unwritten``) with a tolerated level of 0.

    Returns:
        The plan to write, and the mirror's metrics: ``mirror_metrics`` if the plan held at
        least its waypoints' level, else those of its written samples, or of its refusal.
    """
    if (not opts.robust_first
            or plan.metrics.tolerated >= mirror_metrics.tolerated - DOMINANCE_TOL):
        return plan, mirror_metrics
    try:
        alt = written_plan(model, task, window, opts, mirror.q, mirror.offsets, timing, "mirror",
                           reference_offsets=mirror.offsets)
    except InfeasibleError as exc:
        why = str(exc).split("; levers:")[0]
        log.info("the mirror baseline tolerates more at its waypoints but cannot be written: %s",
                 why)
        return plan, replace(mirror_metrics, tolerated=0.0, samples=True,
                             unwritten=why)
    # Written only when it tolerates more by more than the tolerance the trigger allows
    # (a level both share, such as the pin speed at the weld start, does not swap the plan).
    better = alt.metrics.tolerated > plan.metrics.tolerated + DOMINANCE_TOL
    log.info("the NLP plan tolerates %.4g, the mirror written and sample-checked %.4g "
             "(%.4g on its waypoints): writing the %s", plan.metrics.tolerated,
             alt.metrics.tolerated, mirror_metrics.tolerated, "mirror" if better else "NLP plan")
    return (alt if better else plan), replace(alt.metrics, name="mirror")


def _plan_task(
    model: ElastostaticModel, task: PlanTask, window: WeldWindow, q_seed: FloatArray,
    opts: PlanOptions, name: str, compile_c: bool | None, timing: TimingLimits | None,
    t_start: float | None, stages: Stages,
) -> PlanResult:
    t_all = t_start if t_start is not None else time.perf_counter()
    check_well_posed(opts, window)
    robot = model.robot
    nopts = nlp_options(opts)
    choice = choose_branch(model, task, np.asarray(q_seed, float), nopts, window)
    stages.start("baselines")
    base = _baselines(model, task, choice, opts)
    stages.start("NLP (first run compiles C)")
    t0 = time.perf_counter()
    sol = _solver_call(solve_plan, model, task, window, base.warm, nopts, compile_c)
    if opts.robust_first:
        sol = _second_stage(model, task, window, base.warm, opts, sol, compile_c)
    solve_time = time.perf_counter() - t0
    stages.start("verification")
    t0 = time.perf_counter()
    out = written_plan(model, task, window, opts, sol.q, sol.offsets, timing, "nlp",
                       "" if sol.success else f" (IPOPT: {sol.status})", stages,
                       reference_offsets=base.warm.offsets)
    # The baselines judged as the plan: the pin speed where the written weld runs at constant
    # speed (not while the tool accelerates and the traverse force ramps).
    steady = out.samples.constant_speed
    # (Their predictions give the baselines' pin errors: e_lat does not depend on the
    # uncertainty.)
    m_none, p_none = metrics_and_prediction("none", model, task, base.taught.q, window,
                                            opts.force_uncertainty, constant_speed=steady)
    m_mirror, p_mirror = metrics_and_prediction("mirror", model, task, base.mirror.q, window,
                                                opts.force_uncertainty, constant_speed=steady)
    out, m_mirror = dominant(model, task, window, opts, out, base.mirror, m_mirror, timing)
    verify_time = time.perf_counter() - t0 - out.timing_time
    held = out.metrics.tolerated >= opts.force_uncertainty * (1 - 1e-9)
    if opts.robust_hard and not held:
        raise InfeasibleError(
            f"robust_hard: the plan holds the window up to +-{100 * out.metrics.tolerated:.3g} "
            f"% force uncertainty, not the requested +-{100 * opts.force_uncertainty:.3g} %",
            constraint="robust_window")
    status = ("optimal" if sol.success and out.source == "nlp" else "verified")
    return PlanResult(
        status=status + ("" if held else "_nominal"),
        problem_name=name, robot_name=robot.name, euler=robot.description.euler, task=task,
        window=window, options=opts, q=out.q, offsets=out.offsets,
        tool_rotation=tool_rotation_of(robot, task, out.q), verification=out.verification,
        baselines=(m_none, m_mirror, out.metrics),
        e_none=p_none.e_lat, e_mirror=p_mirror.e_lat, branch=choice.name,
        branches=choice.branches,
        solver_status=sol.status if out.source == "nlp" else
        f"{sol.status}; the mirror baseline tolerates more and is written",
        iterations=sol.iterations, outer_iterations=sol.outer, skipped_effects=sol.skipped,
        solve_time=solve_time, verify_time=verify_time, timing_time=out.timing_time,
        total_time=time.perf_counter() - t_all, trajectory=out.trajectory, model=model,
        samples=out.samples, source=out.source,
    )


def _second_stage(model: ElastostaticModel, task: PlanTask, window: WeldWindow,
                  warm: BaselinePlan, opts: PlanOptions, first: Solved,
                  compile_c: bool | None) -> Solved:
    """The second stage of the lexicographic solve (:mod:`rfsw_plan.planning.robustness`).

    The first stage maximised the tolerated uncertainty x* (at the waypoints); pursuing the
    ceiling also drives the mean excess over every waypoint, which on an offset head swings the
    tool about its axis (kr600_curved_seam: 12.8 deg between 1.2 mm waypoints, the pin's speed
    off by 46 % between them). The second stage holds x* less :data:`SECOND_STAGE_SLACK` and
    spends the rest on stiffness, smoothness and proximity, from the same warm start; it is
    kept if it solved, else the first stage is."""
    x = tolerated_uncertainty(predict(model, task, first.q, 1.0), window, 1.0)
    if not np.isfinite(x) or x <= 0:
        return first
    stage2 = replace(opts, force_uncertainty=x * (1 - SECOND_STAGE_SLACK), robust_hard=False)
    try:
        sol = _solver_call(solve_plan, model, task, window, warm, stage2, compile_c,
                           first.coarse_correction)
    except InfeasibleError:
        return first
    return sol if sol.success else first


def _solver_call(fn: Any, *args: Any, **kwargs: Any) -> Any:
    """Call a CasADi/IPOPT step; a solver exception becomes one line (:class:`InfeasibleError`,
    exit 3) instead of a CasADi traceback."""
    try:
        return fn(*args, **kwargs)
    except RuntimeError as exc:
        lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
        reason = next((ln for ln in lines if "Ill-posed" in ln or ("Error" in ln
                       and ".cpp" not in ln)), lines[-1] if lines else type(exc).__name__)
        raise InfeasibleError(f"the NLP solver (CasADi/IPOPT) failed: {reason[:200]}",
                              constraint="solver") from None


@dataclass(frozen=True)
class Solved:
    """The planner's solution on the whole task.

    Attributes:
        q: Joint values [rad], (K, n).
        offsets: Offsets (lateral, normal, along-track) [m], (K, 3).
        success: IPOPT reported success (the coarse NLP's for the coarse-to-fine solve).
        status: IPOPT's return status, plus how the fine plan was obtained.
        iterations: IPOPT iterations (all solves).
        outer: Outer correction iterations (of the last NLP solved).
        skipped: Effects the symbolic model lacks.
        objective: The objective of the NLP on the whole task at the solution.
        method: ``full``, ``coarse`` (coarse NLP and exact fine projection) or
            ``coarse+full`` (the projection failed a row; the full NLP was solved).
        nlp: The NLP on the whole task (with its final outer correction).
        x: Its variable vector at the solution.
        coarse_correction: The coarse NLP's last outer correction [m] (M, 3), or None
            (the full NLP was solved).
    """

    q: FloatArray
    offsets: FloatArray
    success: bool
    status: str
    iterations: int
    outer: int
    skipped: tuple[str, ...]
    objective: float
    method: str
    nlp: PlanNLP
    x: FloatArray
    coarse_correction: FloatArray | None = None


def _solve_outer(model: ElastostaticModel, nlp: PlanNLP, opts: PlanOptions,
                 x0: FloatArray | None = None, correction: FloatArray | None = None
                 ) -> tuple[Any, PlanNLP, FloatArray, int, int]:
    """IPOPT with the outer correction loop (effects the symbolic model lacks) and the
    re-linearisation of the singularity row; returns (solution, NLP with the last
    correction, correction [m] (K, 3), IPOPT iterations, outer iterations).

    ``correction`` [m] (K, 3): the loop's first correction (a converged one of the same task,
    e.g. the first stage's: the loop then usually ends after one solve), else zero."""
    task = nlp.task
    x = nlp.x0 if x0 is None else x0
    corr = np.zeros((len(task), 3))
    if correction is not None and correction.shape == corr.shape:
        corr = np.asarray(correction, dtype=float)
        nlp = update_parameters(nlp, correction=corr)
    iters = 0
    sol = None
    outer = 0
    for outer in range(1, opts.max_outer + 1):
        sol = solve_plan_nlp(nlp, x)
        iters += sol.iterations
        x = sol.x
        pred = predict(model, task, sol.q, opts.force_uncertainty, opts.length_scale)
        full = np.column_stack([pred.e_lat, pred.e_norm, pred.e_along])
        new_corr = full - nlp_prediction(nlp, x)
        change = float(np.max(np.abs(new_corr - corr)))
        kappa_ok = bool(np.all(pred.kappa <= opts.kappa_max))
        log.info("outer %d: correction change %.3g m, max kappa %.3g", outer, change,
                 float(np.max(pred.kappa)))
        if change < opts.outer_tol and kappa_ok:
            break
        corr = new_corr
        nlp = update_parameters(nlp, correction=corr, q_lin=None if kappa_ok else sol.q)
    assert sol is not None
    return sol, nlp, corr, iters, outer


def solve_plan(model: ElastostaticModel, task: PlanTask, window: WeldWindow,
               warm: BaselinePlan, opts: PlanOptions, compile_c: bool | None = None,
               coarse_correction: FloatArray | None = None) -> Solved:
    """The NLP on the whole task: coarse-to-fine (:mod:`rfsw_plan.planning.coarse`) or the
    full NLP (``solver = "full"``, small tasks, or when the fine projection fails a row).

    ``coarse_correction`` [m]: the coarse NLP's first outer correction (an earlier solve's
    :attr:`Solved.coarse_correction` on the same task, see :func:`_solve_outer`)."""
    # The offset rows follow the mirror's offsets in the fine NLP as in the coarse one: both
    # solve the same problem (with load_steps here the full NLP's plan was 0.08-0.13 mm from
    # the default's at the travel-start ramp, issue 38).
    fine = build_plan_nlp(model, task, window, warm.q, warm.offsets, opts, compile_c=compile_c,
                          offset_reference=warm.offsets)
    sub, idx = subsample_task(task, opts.coarse_waypoints)
    x0 = None
    iters = 0
    if opts.solver == "coarse" and len(sub) < len(task) and model.robot.nq == 6:
        cnlp = build_plan_nlp(model, sub, window, warm.q[idx], warm.offsets[idx], opts,
                              compile_c=compile_c, offset_reference=warm.offsets[idx])
        csol, cnlp, ccorr, iters, outer = _solve_outer(model, cnlp, opts,
                                                       correction=coarse_correction)
        proj = project_fine(model, fine, idx, csol.q, csol.offsets, warm.q, warm.offsets,
                            ccorr)
        if proj.feasible and csol.success:
            return Solved(proj.q, proj.offsets, True,
                          f"{csol.status} (coarse NLP on {len(sub)} waypoints, exact fine "
                          f"projection on {len(task)})", iters, outer, fine.skipped,
                          proj.objective, "coarse", proj.nlp, proj.x, ccorr)
        log.info("coarse-to-fine: %s; solving the full NLP",
                 "coarse NLP " + csol.status if not csol.success else
                 f"fine row {proj.violations[0][0]} violated by {proj.violations[0][1]:.3g}")
        if np.all(np.isfinite(proj.x)):
            x0 = proj.x
        fine = proj.nlp
    sol, fine, _, it, outer = _solve_outer(model, fine, opts, x0)
    method = "full" if x0 is None and iters == 0 else "coarse+full"
    return Solved(sol.q, sol.offsets, sol.success, sol.status, iters + it, outer, fine.skipped,
                  sol.objective, method, fine, sol.x)


__all__ = [
    "BranchChoice",
    "Solved",
    "Written",
    "choose_branch",
    "dominant",
    "options_from_problem",
    "plan",
    "plan_task",
    "solve_plan",
    "start_objective",
    "subsample_task",
    "tool_is_coaxial",
    "written_plan",
]
