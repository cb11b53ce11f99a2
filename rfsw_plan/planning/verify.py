"""Independent numeric verification of a plan (Pinocchio and the numeric elastostatic model).

Nothing here uses CasADi: the commanded poses come from the numeric forward kinematics, the
deflection from :meth:`~rfsw_plan.elastostatics.model.ElastostaticModel.process_deflection_batch`
with *all* the model's physical effects and the task's seam reference (``taught``: what the robot
already does at zero process load is in the taught points), so a modelling slip in the symbolic
NLP cannot verify itself. Every waypoint is checked:

* commanded pose: FK_p(q_k) = p_k + o_lat l_k + o_norm n_k + o_along t_k, TCP z axis = -n_k;
* predicted pin error e_k = l_k . (FK_p(q_k) + dX_p(q_k, F_k) - p_k) inside the window;
* the predicted pin on the waypoint's seam point along the track:
  |t_k . (FK_p(q_k) + dX_p(q_k, F_k) - p_k)| <= ``ALONG_TOL`` (the force F_k is the one the
  process model gives with the pin at s_k, and the weld is timed on s_k);
* worst case over the force box |delta f_i| <= u |f_i|: r_k = sum_i u |f_i| |l^T C_tt b_i|
  (deflection is linear in F for compliance effects; seed 000 eq. 11);
* joint limits, joint steps between neighbours, kappa_f (seed 000 eq. 5) below its bound;
* the offsets' change between neighbours beyond the change the load demands (the reference
  offsets', the mirror baseline's): per travel (and per time while stationary), and per time
  while moving.

Every row family the NLP declares (:mod:`rfsw_plan.planning.rows`) names its check here, in
:data:`ROW_CHECKS`; this module refuses to import if a declared check is missing, so a new
planner constraint cannot go without its independent check.

:func:`pin_track` evaluates the timed trajectory the same way at every sample.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.compliance import dexterity
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InfeasibleError
from rfsw_plan.planning.layout import OFFSET_LABELS, OFFSETS
from rfsw_plan.planning.rows import checks as declared_checks
from rfsw_plan.process.plan_options import PlanOptions
from rfsw_plan.process.task import (
    STANDING_DEPTH_TOL,
    STANDSTILL_MOTION,
    PlanTask,
    offsets3,
    plate_normals,
)
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.timing.trajectory import TimedTrajectory

FloatArray = NDArray[np.float64]

#: Tolerance of the commanded position [m] and tool-axis direction [rad].
POSE_TOL = 1e-5
AXIS_TOL = 1e-4
#: Tolerance of the predicted pin's along-track error [m].
ALONG_TOL = 1e-5
#: Tolerance of the pin's height above the surface at the plunge start [m] (IPOPT's
#: constraint tolerance, 1e-7 mm, rounded up).
SURFACE_TOL = 1e-9
#: Tolerance of the offsets' change between neighbours [m]: the NLP rows' own slack (1e-6 mm)
#: plus IPOPT's constraint tolerance (1e-7 mm), rounded up.
OFFSET_TOL = 2e-9


@dataclass(frozen=True)
class Prediction:
    """Numeric prediction of the pin under load, per waypoint (base frame, SI).

    Attributes:
        T: Commanded TCP poses FK(q) [m], (K, 4, 4).
        dX: Predicted TCP deflection [m, rad], (K, 6).
        e_lat: Lateral pin error l . (FK_p + dX_p - p) [m], (K,).
        e_norm: Normal pin error n . (FK_p + dX_p - p) [m], (K,).
        e_along: Along-track pin error t . (FK_p + dX_p - p) [m], (K,) (p: the nominal target,
            the seam point while welding).
        worst: Worst-case change of e_lat under the force uncertainty r_k [m], (K,).
        lateral_compliance: l^T C_tt l [m/N], (K,).
        kappa: Kinetostatic index kappa_f, (K,).
    """

    T: FloatArray
    dX: FloatArray
    e_lat: FloatArray
    e_norm: FloatArray
    e_along: FloatArray
    worst: FloatArray
    lateral_compliance: FloatArray
    kappa: FloatArray

    @property
    def lateral_stiffness(self) -> FloatArray:
        """1 / (l^T C_tt l) [N/m], (K,)."""
        return 1.0 / self.lateral_compliance


def predict(
    model: ElastostaticModel, task: PlanTask, q: FloatArray, uncertainty: float = 0.2,
    length_scale: float = 1.0,
) -> Prediction:
    """Predicted pin errors of joint values q (K, n) [rad] on a task, numerically.

    Uses the numeric forward kinematics (the vectorised kinematics of
    :meth:`~rfsw_plan.robot.kinematics.Robot.batch_fk_jacobian`, equal to Pinocchio's to
    1e-12) for the commanded pose and the model's process deflection
    (:meth:`~rfsw_plan.elastostatics.model.ElastostaticModel.process_deflection_batch`: every
    physical effect, the task's seam reference) for the deflection.
    """
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    batch = model.batch(Q)
    T = batch.T
    F = task.wrench_base
    dX = model.process_deflection_batch(batch, F, task.reference)
    fr = task.frames
    pin = T[:, :3, 3] + dX[:, :3]
    # The seam point, not the raised plunge target: the pin error is measured to the joint
    # line (normal and along-track errors are to the target on the tool axis).
    e_lat = np.einsum("ki,ki->k", fr.l, pin - fr.p)
    e_norm = np.einsum("ki,ki->k", fr.n, pin - task.target)
    e_along = np.einsum("ki,ki->k", fr.t, pin - task.target)
    Ctt = model.physical().cartesian_compliance(batch)[:, :3, :3]
    lC = np.einsum("ki,kij->kj", fr.l, Ctt)
    proj = np.stack([np.einsum("kj,kj->k", lC, b) for b in (fr.t, fr.l, fr.n)], axis=1)
    worst = uncertainty * np.sum(np.abs(task.force_seam) * task.spread_weights * np.abs(proj),
                                 axis=1)
    kappa = dexterity_batch(batch.J, length_scale)
    return Prediction(T, dX, e_lat, e_norm, e_along, worst, proj[:, 1], kappa)


def dexterity_batch(J: FloatArray, length_scale: float = 1.0) -> FloatArray:
    """kappa_f (seed 000 eq. 5) of many Jacobians (m, 6, n), shape (m,): the vectorised
    :func:`~rfsw_plan.elastostatics.compliance.dexterity` (inf where J^T J is singular)."""
    Jn = np.array(J, dtype=float)
    Jn[:, :3] /= length_scale
    A = np.einsum("kij,kil->kjl", Jn, Jn)
    try:
        inv_tr = np.trace(np.linalg.inv(A), axis1=1, axis2=2)
    except np.linalg.LinAlgError:  # a singular pose: the scalar version reports inf there
        return np.array([dexterity(j, length_scale) for j in J])
    with np.errstate(invalid="ignore"):
        out = np.sqrt(np.trace(A, axis1=1, axis2=2) * inv_tr) / Jn.shape[2]
    return np.where(np.isfinite(inv_tr) & (inv_tr > 0), out, np.inf)


@dataclass(frozen=True)
class Verification:
    """Result of :func:`verify_plan`.

    Attributes:
        feasible: Every hard check holds at every waypoint.
        prediction: The numeric prediction.
        margin: Distance of e_lat to the nearest window bound [m] (>= 0 inside), (K,).
        robust_margin: Same for the worst case e_lat +- r [m], (K,).
        pose_error: Commanded position error |FK_p - (p + offsets)| [m], (K,).
        along_error: Predicted pin's along-track error t . (FK_p + dX_p - p) [m], (K,).
        axis_error: Angle between the TCP z axis and -n [rad], (K,).
        worst_waypoint: Waypoint with the smallest margin of its binding constraint.
        binding: Name of that constraint (``window``, ``robust_window``, ``pose``,
            ``along_track``, ``tool_axis``, ``joint_limit_qj``, ``joint_step_qj``,
            ``singularity``, ``offset_rate_lat`` (``_norm``, ``_along``),
            ``offset_speed_lat``...).
        binding_margin: Its margin (negative = violated) [m for window, pose and offsets, rad
            for joints, 1 for kappa].
        messages: One line per violated check.
        skipped: Checks not run for want of their input (``offset_rate`` and
            ``offset_speed`` without ``options``).
    """

    feasible: bool
    prediction: Prediction
    margin: FloatArray
    robust_margin: FloatArray
    pose_error: FloatArray
    along_error: FloatArray
    axis_error: FloatArray
    worst_waypoint: int
    binding: str
    binding_margin: float
    messages: tuple[str, ...]
    skipped: tuple[str, ...] = ()

    def raise_if_infeasible(self) -> None:
        """Raise :class:`InfeasibleError` naming the waypoint, margin and constraint."""
        if not self.feasible:
            raise InfeasibleError(self.messages[0], self.worst_waypoint, self.binding,
                                  self.binding_margin)


@dataclass(frozen=True)
class CheckInput:
    """What a row check sees: the plan, its numeric prediction and the limits (SI).

    Attributes:
        model: The elastostatic model.
        task: The planned task.
        window: The weld window [m].
        q: Joint values [rad], (K, n).
        offsets: Offsets (lateral, normal, along-track) [m], (K, 3).
        prediction: The numeric prediction of q.
        robust_hard: The worst-case window is a hard check.
        joint_step: Largest joint step [rad], or None.
        kappa_max: Largest kappa_f.
        options: The planner options (offset rate and speeds), or None.
        reference_offsets: Offsets whose change the load itself demands [m], (K, 3) (the
            mirror baseline's), or None (zero).
    """

    model: ElastostaticModel
    task: PlanTask
    window: WeldWindow
    q: FloatArray
    offsets: FloatArray
    prediction: Prediction
    robust_hard: bool
    joint_step: float | None
    kappa_max: float
    options: PlanOptions | None
    reference_offsets: FloatArray | None

    @property
    def commanded(self) -> FloatArray:
        """Commanded TCP positions p + o_lat l + o_norm n + o_along t [m], (K, 3)."""
        fr, o = self.task.frames, OFFSETS.split(self.offsets)
        return self.task.target + o["lateral"] * fr.l + o["normal"] * fr.n + o["along"] * fr.t

    def offset_steps(self) -> tuple[FloatArray, FloatArray]:
        """|delta o| and the reference's |delta o_ref| between neighbours [m], (K - 1, 3)."""
        ref = (np.zeros_like(self.offsets) if self.reference_offsets is None
               else offsets3(self.reference_offsets))
        return np.abs(np.diff(self.offsets, axis=0)), np.abs(np.diff(ref, axis=0))


#: A named margin series: (check name, margin (K,) (>= 0 holds), unit: "m", "rad", "speed"
#: (a share of the weld speed), "offset" or "").
Margins = list[tuple[str, FloatArray, str]]
#: A check: the margins of its rows, or None when its input is missing (reported as skipped).
RowCheck = Callable[[CheckInput], "Margins | None"]


def _check_robust(c: CheckInput) -> Margins:
    p, w = c.prediction, c.window
    e = p.e_lat
    return [("robust_window", np.minimum(e - p.worst - w.lower, w.upper - e - p.worst), "m")
            ] if c.robust_hard else []


def _check_window(c: CheckInput) -> Margins:
    e = c.prediction.e_lat
    return [("window", np.minimum(e - c.window.lower, c.window.upper - e), "m")]


def _pose_error(c: CheckInput) -> FloatArray:
    """|FK_p(q) - (p + offsets)| [m], (K,)."""
    return np.asarray(np.linalg.norm(c.prediction.T[:, :3, 3] - c.commanded, axis=1))


def _check_pose(c: CheckInput) -> Margins:
    return [("pose", POSE_TOL - _pose_error(c), "m")]


def _check_along(c: CheckInput) -> Margins:
    return [("along_track", ALONG_TOL - np.abs(c.prediction.e_along), "m")]


def _check_axis(c: CheckInput) -> Margins:
    return [("tool_axis", AXIS_TOL - _axis_error(c.prediction, c.task), "rad")]


def _check_singularity(c: CheckInput) -> Margins:
    return [("singularity", c.kappa_max - c.prediction.kappa, "")]


def _check_joint_limits(c: CheckInput) -> Margins:
    d = c.model.robot.description
    # 1e-7 rad: IPOPT may touch a bound within its bound relaxation.
    return [(f"joint_limit_q{j + 1}", np.minimum(c.q[:, j] - d.lower[j],
                                                d.upper[j] - c.q[:, j]) + 1e-7, "rad")
            for j in range(c.q.shape[1])]


def _check_joint_steps(c: CheckInput) -> Margins:
    if c.joint_step is None or len(c.q) < 2:
        return []
    step = np.abs(np.diff(c.q, axis=0))
    return [(f"joint_step_q{j + 1}", np.append(c.joint_step - step[:, j], np.inf), "rad")
            for j in range(c.q.shape[1])]


def _offset_margins(name: str, c: CheckInput, bound: FloatArray) -> Margins:
    """Margins of |delta o| <= bound + |delta o_ref| + OFFSET_TOL per offset component, named
    ``{name}_lat`` etc., at the link's first waypoint."""
    step, ref = c.offset_steps()
    m = bound[:, None] + ref + OFFSET_TOL - step
    return [(f"{name}_{label}", np.append(m[:, OFFSETS[comp]][:, 0], np.inf), "offset")
            for comp, label in zip(OFFSETS.names, OFFSET_LABELS, strict=True)]


def _check_offset_rate(c: CheckInput) -> Margins | None:
    """|delta o| <= offset_rate x travel (+ offset_speed_stationary x time while stationary)
    + |delta o_ref|."""
    if c.options is None:
        return None
    if len(c.q) < 2:
        return []
    ds, dt = np.diff(c.task.s), np.diff(c.task.time)
    o = c.options
    bound = o.offset_rate * ds + np.where(ds <= 1e-12, o.offset_speed_stationary * dt, 0.0)
    return _offset_margins("offset_rate", c, bound)


def _check_offset_speed(c: CheckInput) -> Margins | None:
    """|delta o| <= offset_speed x time + |delta o_ref| on every link with travel."""
    if c.options is None:
        return None
    if len(c.q) < 2:
        return []
    ds, dt = np.diff(c.task.s), np.diff(c.task.time)
    bound = np.where(ds <= 1e-12, np.inf, c.options.offset_speed * dt)
    return _offset_margins("offset_speed", c, bound)


def _check_depth(c: CheckInput) -> Margins:
    """The normal pin error inside the depth window wherever the pin is in the plate (every
    waypoint but the plunge start; under axial force control the force loop's equilibrium
    the plan's poses model); along the plate normal it is cos(tilt) times this."""
    e, w = c.prediction.e_norm, c.window
    m = np.minimum(e + w.depth_deep, w.depth_shallow - e)
    return [("depth", np.where(c.task.at_surface, np.inf, m), "m")]


def _check_surface(c: CheckInput) -> Margins:
    """At the plunge start (plunge waypoint at depth 0, zero force) the pin is on the plate
    surface: not below it, nor above it by more than the depth window's shallow side."""
    e, w = c.prediction.e_norm, c.window
    m = np.minimum(e + SURFACE_TOL, w.depth_shallow - e)
    return [("surface", np.where(c.task.at_surface, m, np.inf), "m")]


def _check_tilt(c: CheckInput) -> Margins:
    """Work angle (about t) and travel angle (about l) of the TCP z axis from the planned
    tool axis -n within the tilt tolerance."""
    z, fr = c.prediction.T[:, :3, 2], c.task.frames
    work = np.arcsin(np.clip(np.einsum("ki,ki->k", z, fr.l), -1.0, 1.0))
    travel = np.arcsin(np.clip(np.einsum("ki,ki->k", z, fr.t), -1.0, 1.0))
    tol = c.window.tilt_tol
    return [("work_angle", tol - np.abs(work), "rad"), ("travel_angle", tol - np.abs(travel),
                                                         "rad")]


def _check_travel_speed(c: CheckInput) -> Margins:
    """The predicted pin's travel between neighbouring weld waypoints within ``speed_tol`` of
    the seam's: | (e_along,k+1 - e_along,k) / h_k | <= speed_tol for every weld link k of
    travel h_k (the pin's mean speed over the link relative to the weld speed, minus 1).

    The NLP's ``travel_speed`` rows ask for more (every pin within speed_tol x h_min / 2 of its
    seam point along the track, which implies this); what the process needs is the speed, so
    that is what is checked. The margin of link k is at its first waypoint (unit ``speed``:
    a ratio of the weld speed)."""
    m = c.task.n_start
    travel = c.task.link_travel()[m:]
    margin = np.full(len(c.task), np.inf)
    if not len(travel):
        return []
    moving = travel > 1e-12
    de = np.diff(c.prediction.e_along[m:])
    ratio = np.abs(de[moving]) / travel[moving]
    margin[m + np.flatnonzero(moving)] = c.window.speed_tol - ratio
    return [("travel_speed", margin, "speed")]


def _check_standstill(c: CheckInput) -> Margins:
    """While the tool stands with the pin in the plate (:attr:`PlanTask.standing`), the
    predicted pin moves at most :data:`~rfsw_plan.process.task.STANDSTILL_MOTION` sideways:
    max - min of the lateral error over those waypoints, margin at each of them (the NLP's
    rows hold each one near the window centre, which implies this)."""
    stand = c.task.standing
    margin = np.full(len(c.task), np.inf)
    if stand.sum() >= 2:
        e = c.prediction.e_lat[stand]
        margin[stand] = STANDSTILL_MOTION - float(np.max(e) - np.min(e))
    return [("standstill", margin, "m")]


def _check_standing_depth(c: CheckInput) -> Margins:
    """While the tool stands at full depth (:attr:`PlanTask.standing_full`: the plunge's
    end, the dwell, the weld start) the predicted pin is at the planned depth along the tool
    axis within :data:`~rfsw_plan.process.task.STANDING_DEPTH_TOL`."""
    full = c.task.standing_full
    m = STANDING_DEPTH_TOL - np.abs(c.prediction.e_norm)
    return [("standing_depth", np.where(full, m, np.inf), "m")]


#: The independent checks, by the name the row declarations use, in the order a plan's
#: first failure is reported. ``joint_limit`` checks the variable bounds (no row family).
ROW_CHECKS: dict[str, RowCheck] = {
    "robust_window": _check_robust,
    "window": _check_window,
    "pose": _check_pose,
    "along_track": _check_along,
    "depth": _check_depth,
    "surface": _check_surface,
    "standstill": _check_standstill,
    "standing_depth": _check_standing_depth,
    "tilt": _check_tilt,
    "travel_speed": _check_travel_speed,
    "tool_axis": _check_axis,
    "singularity": _check_singularity,
    "joint_limit": _check_joint_limits,
    "joint_step": _check_joint_steps,
    "offset_rate": _check_offset_rate,
    "offset_speed": _check_offset_speed,
}


def _require_declared_checks() -> None:
    """Every row family declared in :mod:`rfsw_plan.planning.rows` names a check here."""
    missing = {fam: chk for fam, chk in declared_checks().items() if chk not in ROW_CHECKS}
    if missing:
        raise TypeError(f"row families without their check in verify.ROW_CHECKS: {missing}; "
                        f"the checks are {sorted(ROW_CHECKS)}")


_require_declared_checks()


def _axis_error(pred: Prediction, task: PlanTask) -> FloatArray:
    """Angle between the TCP z axis and -n [rad], (K,)."""
    cosang = np.clip(-np.einsum("ki,ki->k", pred.T[:, :3, 2], task.frames.n), -1.0, 1.0)
    return np.asarray(np.arccos(cosang))


def verify_plan(
    model: ElastostaticModel,
    task: PlanTask,
    window: WeldWindow,
    q: FloatArray,
    offsets: FloatArray,
    uncertainty: float = 0.2,
    robust_hard: bool = False,
    joint_step: float | None = None,
    kappa_max: float = np.inf,
    length_scale: float = 1.0,
    *,
    options: PlanOptions | None = None,
    reference_offsets: FloatArray | None = None,
) -> Verification:
    """Re-evaluate a plan numerically and run every check of :data:`ROW_CHECKS` at every
    waypoint (one per row family the NLP declares, and the joint limits).

    Args:
        model: Elastostatic model (all effects are evaluated).
        task: The task that was planned.
        window: Weld window [m].
        q: Planned joint values [rad], (K, n).
        offsets: Planned offsets (lateral, normal, along-track) [m], (K, 3) (or (K, 2): no
            along-track offset).
        uncertainty: Relative force uncertainty u.
        robust_hard: Treat the worst-case window as a hard check.
        joint_step: Largest joint step between neighbours [rad], or None to skip.
        kappa_max: Largest kappa_f.
        length_scale: Length scale for kappa_f [m].
        options: The planner options: the offsets' change between neighbours is checked
            against ``offset_rate``, ``offset_speed_stationary`` and ``offset_speed``
            (skipped without them, and listed in :attr:`Verification.skipped`).
        reference_offsets: The offsets whose change the load itself demands [m], (K, 3) (the
            mirror baseline's, as the planner's ``load_steps``); None: zero.
    """
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    pred = predict(model, task, Q, uncertainty, length_scale)
    o = offsets3(offsets)
    c = CheckInput(model, task, window, Q, o, pred, robust_hard, joint_step, kappa_max, options,
                   reference_offsets)
    checks: Margins = []
    skipped: list[str] = []
    for name, check in ROW_CHECKS.items():
        margins = check(c)
        if margins is None:
            skipped.append(name)
        else:
            checks += margins
    e = pred.e_lat
    margin = _check_window(c)[0][1]
    rmargin = np.minimum(e - pred.worst - window.lower, window.upper - e - pred.worst)
    pose_err = _pose_error(c)
    messages = []
    worst_k, worst_name, worst_m = int(np.argmin(rmargin if robust_hard else margin)), \
        "robust_window" if robust_hard else "window", float(np.min(rmargin if robust_hard
                                                                   else margin))
    first_bad: tuple[int, str, float] | None = None
    for name, m, unit in checks:
        bad = np.flatnonzero(m < 0)
        if len(bad):
            k = int(bad[np.argmin(m[bad])])
            if first_bad is None:
                first_bad = (k, name, float(m[k]))
            messages.append(_message(task, k, name, float(m[k]), unit, e, pred))
    if first_bad is not None:
        worst_k, worst_name, worst_m = first_bad
    return Verification(not messages, pred, margin, rmargin, pose_err, pred.e_along,
                        _axis_error(pred, task), worst_k, worst_name, worst_m, tuple(messages),
                        tuple(skipped))


def _message(task: PlanTask, k: int, name: str, m: float, unit: str, e: FloatArray,
             pred: Prediction) -> str:
    where = (f"waypoint {k + 1} ({task.phase[k]}, s = {task.s[k] * 1e3:.2f} mm, t = "
             f"{task.time[k]:.2f} s)")
    if name in ("window", "robust_window"):
        extra = f"; e_lat = {e[k] * 1e3:+.3f} mm, worst case +-{pred.worst[k] * 1e3:.3f} mm"
        return (f"plan infeasible at {where}: {name} violated by {-m * 1e3:.3f} mm{extra}")
    if name == "along_track":
        return (f"plan infeasible at {where}: the predicted pin is "
                f"{pred.e_along[k] * 1e3:+.4f} mm along the track from its seam point "
                f"(tolerance {ALONG_TOL * 1e3:g} mm)")
    if unit == "offset":
        return (f"plan infeasible at {where}: {name}: the offset changes to the next waypoint "
                f"by {-m * 1e3:.4f} mm more than its bound")
    if unit == "m":
        return f"plan infeasible at {where}: {name} off by {-m * 1e3:.4f} mm"
    if unit == "speed":
        return (f"plan infeasible at {where}: {name}: the predicted pin's speed to the next "
                f"waypoint is off the weld speed by {100 * -m:.3g} % more than its tolerance")
    if unit == "rad":
        return f"plan infeasible at {where}: {name} exceeded by {np.rad2deg(-m):.3f} deg"
    return (f"plan infeasible at {where}: {name}: kappa_f = {pred.kappa[k]:.1f} exceeds the "
            f"bound by {-m:.1f}")


def pin_track(model: ElastostaticModel, task: PlanTask, traj: TimedTrajectory) -> FloatArray:
    """Predicted (loaded) pin arc length along the seam at every sample of a timed trajectory
    [m], (N,), by the numeric model, independently of the timing.

    sigma_i = s_i + t(s_i) . (FK_p(q_i) + dX_p(q_i, F_i) - p(s_i)), with the seam point p and
    tangent t interpolated linearly in the trajectory's arc length s_i (the seam point the plan
    puts the pin on), dX the process deflection with the task's seam reference. Its time
    derivative is the pin's travel speed (:meth:`TimedTrajectory.pin_speed`).
    """
    m = task.n_start
    fr = task.frames
    sw = fr.s[m:]

    def at_s(a: FloatArray) -> FloatArray:
        return np.stack([np.interp(traj.s, sw, a[m:, i]) for i in range(3)], axis=1)

    batch = model.batch(traj.q)
    dX = model.process_deflection_batch(batch, traj.wrench, task.reference)
    t = at_s(fr.t)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    pin = batch.T[:, :3, 3] + dX[:, :3]
    return np.asarray(traj.s + np.einsum("ki,ki->k", t, pin - at_s(fr.p)))


# --------------------------------------------------------------------------------------------
# Sample-by-sample verification of what is written

#: Phases in which the pin is in the material.
CONTACT_PHASES = ("plunge", "dwell", "accelerate", "weld", "decelerate")
#: Tolerance of the lateral window check on samples [m] (IPOPT's constraint tolerance).
WINDOW_TOL = 1e-6
#: Stationarity while the pin is plunged and not travelling. Every joint of every plunge and
#: dwell sample stays within the range of the planned stationary waypoints of its phase
#: (shape-preserving interpolation: between its neighbouring waypoints) [rad] ...
JOINT_RANGE_TOL = 1e-9
#: ... and the commanded TCP inside the box of those waypoints' commanded TCP, widened by this
#: much [m]: joint-space interpolation is not straight in Cartesian space (kr600_curved_seam,
#: offset head, with the tool turning during the dwell: up to 0.25 mm outside the box); the
#: overshoot this catches was 5 to 25 mm.
STATION_TOL = 1e-3
#: Relative tolerance of the joint velocity, acceleration and jerk limits.
LIMIT_TOL = 1e-9
#: A plunge sample more than this above the plate surface is in the air, not in the material
#: [m] (1 um: above the rounding of the written joint values, about 1e-5 mm of position).
AIR_TOL = 1e-6
#: Phases with the pin at full depth in the plate (where the depth window applies).
FULL_DEPTH_PHASES = ("dwell", "accelerate", "weld", "decelerate")
#: Tolerance of the tilt check on samples [rad] (the NLP's tool-axis tolerance).
TILT_TOL = 1e-4
#: Tolerance of the pin-speed check [1] (finite differences of 10 ms samples).
SPEED_TOL = 1e-6


class SampleLike(Protocol):
    """What :func:`verify_samples` needs of a sampled trajectory (a
    :class:`~rfsw_plan.timing.trajectory.TimedTrajectory`, or samples re-read from a written
    file or controller program): time [s] (N,), phase (N,), the pin's arc length along the
    seam [m] (N,), joint values [rad] (N, n) and the wrench on the tool [N, N m] (N, 6), base
    frame."""

    @property
    def t(self) -> FloatArray: ...

    @property
    def phase(self) -> NDArray[np.str_]: ...

    @property
    def s(self) -> FloatArray: ...

    @property
    def q(self) -> FloatArray: ...

    @property
    def wrench(self) -> FloatArray: ...


@dataclass(frozen=True)
class SampleFailure:
    """The first sample failing one check.

    Attributes:
        index: 0-based sample index (``sample`` is the 1-based row of ``waypoints.csv``).
        t: Its time [s].
        phase: Its phase.
        s: Its arc length [m].
        check: ``window``, ``depth``, ``surface`` (pin below the plate before the plunge),
            ``work_angle``, ``travel_angle``, ``pin_speed``, ``joint_limit_qj``,
            ``joint_velocity_qj``, ``joint_acceleration_qj``, ``joint_jerk_qj``,
            ``plunge_stationarity`` or ``dwell_stationarity`` (and ``_joint_range``).
        value: The offending value (file units: mm, deg, %, deg/s, deg/s^2, deg/s^3).
        bound: The bound it breaks (same unit).
        unit: The unit of value and bound.
    """

    index: int
    t: float
    phase: str
    s: float
    check: str
    value: float
    bound: float
    unit: str

    @property
    def sample(self) -> int:
        """1-based sample number (the row of ``waypoints.csv`` below the header)."""
        return self.index + 1

    @property
    def quantity(self) -> str:
        """The weld-envelope quantity the check guards (``lateral``, ``depth``, ``tilt``,
        ``speed``, ``clearance``), or the check's name for the others."""
        return {"window": "lateral", "depth": "depth", "surface": "clearance",
                "work_angle": "tilt", "travel_angle": "tilt",
                "pin_speed": "speed"}.get(self.check, self.check)

    @property
    def levers(self) -> str:
        """What can make this quantity hold (empty for joint-limit and stationarity checks)."""
        return ENVELOPE_LEVERS.get(self.quantity, "")

    @property
    def message(self) -> str:
        """One line: which sample, where, what, value and bound."""
        what = {"window": "lateral pin error outside the window with the margin",
                "depth": "pin depth error along the plate normal (+ shallow, - deep) outside "
                         "the depth window",
                "surface": "pin tip below the plate surface before the plunge",
                "work_angle": "work angle off the planned tilt",
                "travel_angle": "travel angle off the planned tilt",
                "pin_speed": "pin travel speed off the weld speed by",
                "dwell_stationarity": "commanded TCP leaves the box of the planned dwell "
                                      "waypoints by",
                "plunge_stationarity": "commanded TCP leaves the box of the planned plunge "
                                       "waypoints by",
                "plunge_joint_range": "a joint leaves the range of the planned plunge "
                                      "waypoints by",
                "dwell_joint_range": "a joint leaves the range of the planned dwell "
                                     "waypoints by"}.get(self.check, self.check)
        return (f"sample {self.sample} (t = {self.t:.3f} s, {self.phase}, s = "
                f"{self.s * 1e3:.2f} mm): {what}: {self.value:+.4g} {self.unit}, bound "
                f"{self.bound:.4g} {self.unit}")


#: The levers of each weld-envelope quantity, for the verdict when it fails.
ENVELOPE_LEVERS = {
    "lateral": "levers: a stiffer placement (rfsw-plan place), a calibrated force model (plan "
               "--forces), real-time compensation (rfsw-plan compare), or a smaller margin_mm",
    "depth": "levers: axial force control ([process] axial_control = \"force\": the controller "
             "holds the depth), a placement stiffer along the plate normal (rfsw-plan place), "
             "a larger offset_rate_mm_per_mm, or the tool's depth window ([window] "
             "depth_shallow_mm / depth_deep_mm)",
    "tilt": "levers: a larger joint_step_deg or another tool_rotation_deg (the path between "
            "waypoints turns the tool), a finer spacing_mm, or [window] tilt_tol_deg",
    "speed": "levers: a finer spacing_mm, a smaller offset_rate_mm_per_mm (the along-track "
             "offset changes the pin's speed), or [window] speed_tol_pct",
    "clearance": "levers: a larger offset_speed_stationary_mm_s (the normal offset must "
                 "follow the plunge force) or a slower plunge_speed_mm_s",
}


@dataclass(frozen=True)
class SampleVerification:
    """Result of :func:`verify_samples` (base frame, SI unless stated).

    Attributes:
        ok: Every sample passes every check.
        contact: In-material samples (plunge below the plate surface, dwell, accelerate, weld,
            decelerate), (N,).
        e_lat: Predicted lateral pin error l . (FK_p + dX_p - p) [m], (N,).
        margin: Distance of e_lat to the nearest window bound [m], (N,) (>= 0 inside).
        worst_per_unit: Change of e_lat per unit relative force uncertainty,
            R = sum_i |f_i| |l^T C_tt b_i| [m], (N,) (the worst case at +-u is u R).
        tolerated_uncertainty: Largest uniform u for which e +- u R stays in the window at
            every in-material sample (inf if no force reaches the lateral axis; 0 if a
            sample is outside the window).
        limit_ratios: max |derivative| / limit over all samples and joints per order
            (``velocity``, ``acceleration``, ``jerk``).
        station_excess: Largest distance of a plunge or dwell sample's commanded TCP outside
            the box of its planned stationary waypoints [m] (-inf if not checked).
        failures: The first failing sample of every failing check, in time order.
        depth_error: Predicted pin tip along the plate normal relative to the planned depth
            (positive: shallower) [m], (N,); NaN where not at full depth in the plate
            (approach, plunge, retract).
        tilt_error: Largest of |work angle| and |travel angle| off the planned tool axis
            [rad], (N,) (NaN outside the plate).
        speed_ratio: Pin travel speed / weld speed at constant-speed weld samples, (N,) (NaN
            elsewhere).
        height: Predicted pin tip height above the plate surface along the plate normal [m],
            (N,) (negative in the plate).
    """

    ok: bool
    contact: NDArray[np.bool_]
    e_lat: FloatArray
    margin: FloatArray
    worst_per_unit: FloatArray
    tolerated_uncertainty: float
    limit_ratios: dict[str, float]
    station_excess: float
    failures: tuple[SampleFailure, ...]
    depth_error: FloatArray | None = None
    tilt_error: FloatArray | None = None
    speed_ratio: FloatArray | None = None
    height: FloatArray | None = None

    @property
    def first_failure(self) -> SampleFailure | None:
        """The earliest failing sample, or None."""
        return self.failures[0] if self.failures else None

    @property
    def envelope_failure(self) -> SampleFailure | None:
        """The failure to report first: the earliest failing weld-envelope quantity (lateral,
        depth, tilt, speed, clearance), else the earliest failure of any check."""
        env = [f for f in self.failures if f.levers]
        return env[0] if env else self.first_failure

    @property
    def min_margin(self) -> float:
        """Smallest window margin over the in-material samples [m] (inf if none)."""
        return float(np.min(self.margin[self.contact])) if self.contact.any() else np.inf

    def raise_if_failed(self) -> None:
        """Raise :class:`InfeasibleError` naming the first failing sample."""
        f = self.envelope_failure
        if f is not None:
            more = f" (and {len(self.failures) - 1} more checks fail)" if len(
                self.failures) > 1 else ""
            head = (f"{f.quantity} fails first: " if f.levers
                    else "written trajectory fails the sample check at ")
            lev = f"; {f.levers}" if f.levers else ""
            raise InfeasibleError(head + f.message + more + lev, None, f.check, None)


def seam_frames_at(task: PlanTask, s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray,
                                                           FloatArray]:
    """Seam point p and unit tangent t, lateral l, normal n at arc lengths s [m] (N,), by
    linear interpolation between the task's weld waypoints (what ``waypoints.csv`` uses)."""
    m = task.n_start
    fr = task.frames
    sw = fr.s[m:]

    def at_s(a: FloatArray, unit: bool) -> FloatArray:
        out = np.stack([np.interp(s, sw, a[m:, i]) for i in range(3)], axis=1)
        if unit:
            out /= np.linalg.norm(out, axis=1, keepdims=True)
        return out

    return at_s(fr.p, False), at_s(fr.t, True), at_s(fr.l, True), at_s(fr.n, True)


def verify_samples(
    model: ElastostaticModel, task: PlanTask, window: WeldWindow, samples: SampleLike,
    margin: float = 0.0, q_waypoints: FloatArray | None = None, q_resolution: float = 0.0,
) -> SampleVerification:
    """Check every sample of a trajectory as it is written, numerically and independently.

    Nothing here uses CasADi or the planner's interpolation: the commanded pose is the
    forward kinematics of the sample's joint values, the deflection the model's process
    deflection (every physical effect, the task's seam reference) under the sample's wrench,
    the derivatives finite differences of the samples in time. Checks:

    * in-material samples (plunge below the plate surface, dwell, accelerate, weld,
      decelerate): the lateral pin error e = l . (FK_p(q) + dX_p(q, F) - p(s)) inside
      [lower + margin, upper - margin];
    * the rest of the weld envelope: the depth along the plate normal within the depth
      window at full depth (dwell to decelerate), work and travel angle within the tilt
      tolerance in the material, the pin's travel speed within the speed tolerance at
      constant-speed weld samples, and no pin below the plate surface before the plunge;
    * every sample: joint limits, and joint velocity, acceleration and jerk limits;
    * stationarity (with ``q_waypoints``): the commanded TCP of every plunge sample inside the
      box spanned by the planned plunge waypoints (and the first dwell one), of every dwell
      sample inside the box of the planned dwell waypoints (with the last plunge and the first
      weld waypoint), each widened by ``STATION_TOL``: the TCP moves only as the fake target
      must follow the force ramp, no overshoot between ramp points.

    It also gives the tolerated force uncertainty: the worst case of e over the force box
    |delta f_i| <= u |f_i| (seam-frame components) is e +- u R with
    R = sum_i |f_i| |l^T C_tt b_i| (deflection linear in F; seed 000 eq. 11), so the largest
    u keeping every in-material sample in the window is min_k dist_k / R_k (closed form;
    dist_k the distance of e_k to the nearest bound of the bare window).

    Args:
        model: Elastostatic model (all effects are evaluated).
        task: The planned task (seam frames, seam reference).
        window: Weld window [m].
        samples: The samples (:class:`SampleLike`).
        margin: Required margin to the window bounds [m].
        q_waypoints: The planned joint values of the task's waypoints [rad], (K, n), for the
            stationarity check (skipped if None).
        q_resolution: Rounding of the joint values as written [rad] (half a unit of the last
            written digit: ``waypoints.csv`` writes 1e-6 deg, so 0.5e-6 deg), added to the
            tolerance of the joint-limit and joint-range checks. The finite-difference
            derivatives see the rounding too (with 1e-6 deg and 10 ms samples, about
            1 deg/s^3 of jerk).

    Returns:
        The verification; ``ok`` False names the failing samples.
    """
    t = np.asarray(samples.t, dtype=float)
    phase = np.asarray(samples.phase).astype(str)
    s = np.asarray(samples.s, dtype=float)
    Q = np.atleast_2d(np.asarray(samples.q, dtype=float))
    W = np.asarray(samples.wrench, dtype=float)
    N = len(t)
    d = model.robot.description
    batch = model.batch(Q)
    dX = model.process_deflection_batch(batch, W, task.reference)
    p, tt, ll, nn = seam_frames_at(task, s)
    x = batch.T[:, :3, 3]
    e = np.einsum("ki,ki->k", ll, x + dX[:, :3] - p)
    # Height of the pin tip above the plate (seam point + plunge depth along the plate normal).
    pin = x + dX[:, :3]
    m0 = task.n_start
    npl = plate_normals(task.frames.s[m0:], task.frames.p[m0:], nn, s)
    depth_full = float(np.max(task.depth)) if len(task.depth) else 0.0
    height = np.einsum("ki,ki->k", npl, pin - p) - depth_full
    # In the material: the contact phases, less the plunge's start in the air (from the
    # spindle clearance down to the surface).
    contact = np.isin(phase, CONTACT_PHASES) & ~((phase == "plunge") & (height > AIR_TOL))
    dist = np.minimum(e - window.lower, window.upper - e)
    # Worst case per unit uncertainty, at the in-material samples only.
    R = np.zeros(N)
    if contact.any():
        sub = model.batch(Q[contact])
        Ctt = model.physical().cartesian_compliance(sub)[:, :3, :3]
        lC = np.einsum("ki,kij->kj", ll[contact], Ctt)
        f = W[contact, :3]
        for b, wgt in zip((tt[contact], ll[contact], nn[contact]), task.spread_weights,
                          strict=True):
            R[contact] += wgt * np.abs(np.einsum("ki,ki->k", f, b)) * np.abs(
                np.einsum("kj,kj->k", lC, b))
    with np.errstate(divide="ignore", invalid="ignore"):
        u_k = np.where(R > 0, np.maximum(dist, 0.0) / R, np.where(dist >= 0, np.inf, 0.0))
    tolerated = float(np.min(u_k[contact])) if contact.any() else np.inf

    fails: list[SampleFailure] = []

    def first(bad: NDArray[np.bool_], check: str, value: FloatArray, bound: FloatArray | float,
              unit: str) -> None:
        idx = np.flatnonzero(bad)
        if len(idx):
            i = int(idx[0])
            b = bound[i] if isinstance(bound, np.ndarray) else bound
            fails.append(SampleFailure(i, float(t[i]), str(phase[i]), float(s[i]), check,
                                       float(value[i]), float(b), unit))

    lo, hi = window.lower + margin, window.upper - margin
    bad = contact & ((e < lo - WINDOW_TOL) | (e > hi + WINDOW_TOL))
    first(bad, "window", e * 1e3, np.where(e < lo, lo, hi) * 1e3, "mm")
    # The rest of the weld envelope: depth along the plate normal, tilt, pin speed, and the
    # pin above the plate before the plunge.
    full = np.isin(phase, FULL_DEPTH_PHASES)
    derr = np.where(full, height + depth_full, np.nan)
    # The depth window itself (the planner's depth rows hold it with the margin at the
    # waypoints; between them the pin may use the margin, as it may not the window). Under
    # axial force control this is the force loop's equilibrium the poses model.
    dlo, dhi = -window.depth_deep, window.depth_shallow
    with np.errstate(invalid="ignore"):
        bad = full & ((derr < dlo - WINDOW_TOL) | (derr > dhi + WINDOW_TOL))
    first(bad, "depth", derr * 1e3, np.where(derr < dlo, dlo, dhi) * 1e3, "mm")
    before = phase == "approach"
    first(before & (height < -WINDOW_TOL), "surface", height * 1e3, 0.0, "mm")
    z = batch.T[:, :3, 2]
    work = np.arcsin(np.clip(np.einsum("ki,ki->k", z, ll), -1.0, 1.0))
    trav = np.arcsin(np.clip(np.einsum("ki,ki->k", z, tt), -1.0, 1.0))
    tol_t = window.tilt_tol + TILT_TOL
    for name, ang in (("work_angle", work), ("travel_angle", trav)):
        first(contact & (np.abs(ang) > tol_t), name, np.rad2deg(ang),
              float(np.rad2deg(window.tilt_tol)), "deg")
    tilt_err = np.where(contact, np.maximum(np.abs(work), np.abs(trav)), np.nan)
    speed_ratio = np.full(N, np.nan)
    welding = phase == "weld"
    if N >= 3 and welding.sum() >= 3 and task.travel_speed > 0:
        sigma = s + np.einsum("ki,ki->k", tt, pin - p)
        speed_ratio[welding] = np.gradient(sigma[welding], t[welding]) / task.travel_speed
        dev = np.abs(speed_ratio - 1.0)
        with np.errstate(invalid="ignore"):
            first(welding & (dev > window.speed_tol + SPEED_TOL), "pin_speed",
                  (speed_ratio - 1.0) * 100, window.speed_tol * 100, "%")
    for j in range(Q.shape[1]):
        qj = Q[:, j]
        bad = (qj < d.lower[j] - 1e-9 - q_resolution) | (qj > d.upper[j] + 1e-9 + q_resolution)
        first(bad, f"joint_limit_q{j + 1}", np.rad2deg(qj),
              np.rad2deg(np.where(qj < d.lower[j], d.lower[j], d.upper[j])), "deg")
    ratios: dict[str, float] = {}
    if N >= 3:
        der = Q
        for name, limit, unit in (("velocity", d.velocity, "deg/s"),
                                  ("acceleration", d.acceleration, "deg/s^2"),
                                  ("jerk", d.jerk, "deg/s^3")):
            der = np.gradient(der, t, axis=0)
            ratio = np.abs(der) / limit
            ratios[name] = float(np.max(ratio))
            for j in range(Q.shape[1]):
                first(ratio[:, j] > 1.0 + LIMIT_TOL, f"joint_{name}_q{j + 1}",
                      np.rad2deg(der[:, j]), float(np.rad2deg(limit[j])), unit)
    excess = -np.inf
    if q_waypoints is not None and task.n_start:
        m = task.n_start
        xw = model.robot.batch_fk_jacobian(np.asarray(q_waypoints, float)[:m + 1])[0][:, :3, 3]
        ph_w = task.phase[:m]
        plunge_w = np.flatnonzero(ph_w == "plunge")
        dwell_w = np.flatnonzero(ph_w == "dwell")
        for name, wk in (("plunge", np.append(plunge_w, dwell_w[:1] if len(dwell_w) else m)),
                         ("dwell", np.concatenate([plunge_w[-1:], dwell_w, [m]]))):
            rows = np.flatnonzero(phase == name)
            if not len(rows) or not len(wk):
                continue
            wk = wk.astype(int)
            qw = np.asarray(q_waypoints, float)[wk]
            jout = np.max(np.maximum(qw.min(axis=0) - Q[rows], Q[rows] - qw.max(axis=0)),
                          axis=1)
            out = np.max(np.maximum(xw[wk].min(axis=0) - x[rows], x[rows] - xw[wk].max(axis=0)),
                         axis=1)
            if name == "plunge":
                # Above the plunge start (in the air, from the spindle clearance down): on
                # the tool axis through the first plunge waypoint's commanded TCP, the joints
                # free (the IK of that line, not the range of the waypoints in the plate).
                n0 = task.frames.n[0]
                rel = x[rows] - xw[wk[0]]
                up = rel @ n0
                air = up > 1e-9
                off_axis = np.linalg.norm(rel - up[:, None] * n0[None], axis=1)
                out = np.where(air, off_axis, out)
                jout = np.where(air, -np.inf, jout)
            excess = max(excess, float(np.max(out)))
            for check, o, tol, scale, unit in (
                    (f"{name}_joint_range", jout, JOINT_RANGE_TOL + q_resolution,
                     float(np.rad2deg(1.0)), "deg"),
                    (f"{name}_stationarity", out, STATION_TOL, 1e3, "mm")):
                bad = np.zeros(N, dtype=bool)
                bad[rows] = o > tol
                val = np.zeros(N)
                val[rows] = o * scale
                first(bad, check, val, tol * scale, unit)
    fails.sort(key=lambda f: (f.index, f.check))
    return SampleVerification(not fails, contact, e, dist, R, tolerated, ratios, excess,
                              tuple(fails), derr, tilt_err, speed_ratio, height)


def tolerated_uncertainty(pred: Prediction, window: WeldWindow, uncertainty: float,
                          mask: NDArray[np.bool_] | None = None) -> float:
    """Largest uniform relative force uncertainty whose worst case keeps every waypoint of a
    :class:`Prediction` (made at ``uncertainty``) in the window: min_k dist_k / R_k, with
    R_k = worst_k / uncertainty (closed form; see :func:`verify_samples`). inf if no force
    reaches the lateral axis."""
    e = pred.e_lat if mask is None else pred.e_lat[mask]
    worst = pred.worst if mask is None else pred.worst[mask]
    if uncertainty <= 0:
        raise ValueError("tolerated_uncertainty needs the prediction at an uncertainty > 0")
    R = worst / uncertainty
    dist = np.minimum(e - window.lower, window.upper - e)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(R > 0, np.maximum(dist, 0.0) / R, np.where(dist >= 0, np.inf, 0.0))
    return float(np.min(u)) if len(u) else np.inf
