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
:func:`verify_samples` checks every written sample, and :func:`robust_claim` gives how much
force uncertainty each weld quantity (lateral error, depth, tilt, pin speed) holds at the
vertices of the force box, on the model itself (the plan's claim and the verdict's).
"""

from __future__ import annotations

import itertools
from collections import OrderedDict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.compliance import dexterity
from rfsw_plan.elastostatics.effects.base import PoseBatch
from rfsw_plan.elastostatics.model import ElastostaticModel, SeamReference
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

if TYPE_CHECKING:  # the timing (SciPy's splines) is not on the path of a plan reader
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
        e_along: Along-track pin error t_p . (FK_p + dX_p - p) [m], (K,) (p: the nominal
            target, the seam point while welding; t_p the in-plane seam tangent,
            :func:`along_tangents`).
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


def along_tangents(task: PlanTask) -> FloatArray:
    """The seam tangent in the plate's plane at every waypoint, unit (K, 3): the frame tangent
    t (tilted with the tool) without its part along the plate normal n_p
    (:func:`~rfsw_plan.process.task.plate_normals` of the weld points), t - (t . n_p) n_p
    normalised. The along-track pin error is measured along it: the pin's travel along the
    seam in the plate. The frame tangent is perpendicular to the tilted tool axis, so a depth
    held along that axis, which moves the pin along the seam by the tilt's sine, was not
    counted, and with the depth centred in its window the pin lagged by up to 0.2 % of the
    weld speed."""
    fr, m = task.frames, task.n_start
    npl = plate_normals(fr.s[m:], fr.p[m:], fr.n, fr.s)
    t = fr.t - np.einsum("ki,ki->k", fr.t, npl)[:, None] * npl
    return np.asarray(t / np.linalg.norm(t, axis=1, keepdims=True))


#: How many joint-value arrays a :func:`shared_evaluations` scope keeps (a plan evaluates
#: about 15 distinct ones; the same array comes back up to five times).
SHARED_POSES = 8


@dataclass
class _Evaluated:
    """The numeric model's evaluations of one joint-value array inside a
    :func:`shared_evaluations` scope: its poses, and per (wrench, seam reference, effect
    parameters) its process deflection, per length scale its kappa_f."""

    batch: PoseBatch
    deflection: dict[tuple[Any, ...], FloatArray] = field(default_factory=dict)
    dexterity: dict[float, FloatArray] = field(default_factory=dict)
    claims: dict[tuple[Any, ...], tuple[PlanTask, RobustClaim]] = field(default_factory=dict)


#: The open scopes: id(model) -> (model, its evaluations by exact joint values, depth).
_SHARED: dict[int, tuple[ElastostaticModel, OrderedDict[tuple[Any, ...], _Evaluated],
                         list[int]]] = {}


@contextmanager
def shared_evaluations(model: ElastostaticModel) -> Iterator[None]:
    """Within this scope the model evaluates every joint-value array once.

    The planning pipeline evaluates the same joint values in several stages: the taught path
    in the branch choice, as the mirror's first iterate and as the ``none`` baseline; the plan
    in the fine projection, in the verification and in its metrics; the written samples in
    :func:`pin_track` and :func:`verify_samples`. Inside the scope :func:`predict`,
    :func:`pin_track`, :func:`verify_samples`, :func:`waypoint_claim` and
    :func:`~rfsw_plan.planning.baselines.metrics_and_prediction` take the poses
    (``model.batch``), the process deflection and kappa_f of an array they were already
    computed for (the same bytes, shape and strides; the same wrench, seam reference and
    effect parameters) from the scope instead of computing them again, and
    :func:`waypoint_claim` the claim of joint values already claimed on the same task, window,
    constant-speed stretch and deflection (the mirror's, when it is also written and
    sample-checked as the plan): the same numbers bit
    for bit, as every one is a function of those inputs alone (``tests/test_verify.py``
    compares a plan made with and without the scope). Outside a scope nothing is kept. Nested
    scopes of one model share the outermost one; the last :data:`SHARED_POSES` arrays are
    kept."""
    key = id(model)
    if key not in _SHARED:
        _SHARED[key] = (model, OrderedDict(), [0])
    _SHARED[key][2][0] += 1
    try:
        yield
    finally:
        depth = _SHARED[key][2]
        depth[0] -= 1
        if depth[0] == 0:
            del _SHARED[key]


def _params(model: ElastostaticModel) -> tuple[tuple[str, bytes], ...]:
    """The model's effects and their parameters, as a key."""
    return tuple((e.label, np.asarray(e.params).tobytes()) for e in model.effects)


def _shared(model: ElastostaticModel, Q: FloatArray, create: bool = True
            ) -> _Evaluated | None:
    """The scope's evaluations of joint values Q (m, n) (computed now if new and ``create``),
    or None outside a :func:`shared_evaluations` scope of the model."""
    scope = _SHARED.get(id(model))
    if scope is None or scope[0] is not model:
        return None
    memo = scope[1]
    key = (Q.shape, Q.strides, Q.tobytes())
    ev = memo.get(key)
    if not create and (ev is None or ev.batch.robot is not model.robot):
        return None
    if ev is None or ev.batch.robot is not model.robot:
        ev = _Evaluated(model.batch(Q))
        memo[key] = ev
        while len(memo) > SHARED_POSES:
            memo.popitem(last=False)
    else:
        memo.move_to_end(key)
    return ev


def evaluate_poses(model: ElastostaticModel, q: FloatArray, wrench: FloatArray,
                   reference: SeamReference) -> tuple[PoseBatch, FloatArray]:
    """``model.batch(q)`` and its process deflection [m, rad] (m, 6) under ``wrench``
    (:meth:`~rfsw_plan.elastostatics.model.ElastostaticModel.process_deflection_batch`),
    each computed once per :func:`shared_evaluations` scope (the deflection is a copy: the
    caller may change it)."""
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    ev = _shared(model, Q)
    if ev is None:
        batch = model.batch(Q)
        return batch, model.process_deflection_batch(batch, wrench, reference)
    W = np.asarray(wrench, dtype=float)
    key = (reference, W.shape, W.strides, W.tobytes(), _params(model))
    if key not in ev.deflection:
        ev.deflection[key] = model.process_deflection_batch(ev.batch, W, reference)
    return ev.batch, ev.deflection[key].copy()


def _dexterity_of(model: ElastostaticModel, Q: FloatArray, batch: PoseBatch,
                  length_scale: float) -> FloatArray:
    """:func:`dexterity_batch` of the poses of Q, once per :func:`shared_evaluations` scope
    and length scale (a copy)."""
    ev = _shared(model, Q)
    if ev is None or ev.batch is not batch:
        return dexterity_batch(batch.J, length_scale)
    if length_scale not in ev.dexterity:
        ev.dexterity[length_scale] = dexterity_batch(batch.J, length_scale)
    return ev.dexterity[length_scale].copy()


def predict(
    model: ElastostaticModel, task: PlanTask, q: FloatArray, uncertainty: float = 0.2,
    length_scale: float = 1.0, batch: PoseBatch | None = None,
    deflection: FloatArray | None = None,
) -> Prediction:
    """Predicted pin errors of joint values q (K, n) [rad] on a task, numerically.

    Uses the numeric forward kinematics (the vectorised kinematics of
    :meth:`~rfsw_plan.robot.kinematics.Robot.batch_fk_jacobian`, equal to Pinocchio's to
    1e-12) for the commanded pose and the model's process deflection
    (:meth:`~rfsw_plan.elastostatics.model.ElastostaticModel.process_deflection_batch`: every
    physical effect, the task's seam reference) for the deflection. ``batch``: the poses of q
    (``model.batch(q)``) when the caller has them, so that their effects' pose caches are
    shared with its other model calls, and ``deflection`` their process deflection under the
    task's wrench [m, rad] (K, 6) if it has that too. Inside a :func:`shared_evaluations`
    scope the poses, the deflection and kappa_f of joint values evaluated before are taken
    from it.
    """
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    F = task.wrench_base
    if batch is None:
        batch, dX = evaluate_poses(model, Q, F, task.reference)
    elif deflection is None:
        dX = model.process_deflection_batch(batch, F, task.reference)
    else:
        dX = deflection
    T = batch.T
    fr = task.frames
    pin = T[:, :3, 3] + dX[:, :3]
    # The seam point, not the raised plunge target: the pin error is measured to the joint
    # line (normal and along-track errors are to the target on the tool axis).
    e_lat = np.einsum("ki,ki->k", fr.l, pin - fr.p)
    e_norm = np.einsum("ki,ki->k", fr.n, pin - task.target)
    e_along = np.einsum("ki,ki->k", along_tangents(task), pin - task.target)
    Ctt = model.physical().cartesian_compliance(batch)[:, :3, :3]
    lC = np.einsum("ki,kij->kj", fr.l, Ctt)
    proj = np.stack([np.einsum("kj,kj->k", lC, b) for b in (fr.t, fr.l, fr.n)], axis=1)
    worst = uncertainty * np.sum(np.abs(task.force_seam) * task.spread_weights * np.abs(proj),
                                 axis=1)
    kappa = _dexterity_of(model, Q, batch, length_scale)
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
            mirror baseline's: the offset rows bound the departure from their change), or
            None (zero).
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

    def offset_steps(self) -> FloatArray:
        """|delta (o - o_ref)| between neighbours [m], (K - 1, 3): the offsets' change beyond
        the reference's (the change the load itself demands)."""
        ref = (np.zeros_like(self.offsets) if self.reference_offsets is None
               else offsets3(self.reference_offsets))
        return np.abs(np.diff(self.offsets - ref, axis=0))


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
    """Margins of |delta (o - o_ref)| <= bound + OFFSET_TOL per offset component, named
    ``{name}_lat`` etc., at the link's first waypoint."""
    m = bound[:, None] + OFFSET_TOL - c.offset_steps()
    return [(f"{name}_{label}", np.append(m[:, OFFSETS[comp]][:, 0], np.inf), "offset")
            for comp, label in zip(OFFSETS.names, OFFSET_LABELS, strict=True)]


def _check_offset_rate(c: CheckInput) -> Margins | None:
    """|delta (o - o_ref)| <= offset_rate x travel (+ offset_speed_stationary x time while
    stationary)."""
    if c.options is None:
        return None
    if len(c.q) < 2:
        return []
    ds, dt = np.diff(c.task.s), np.diff(c.task.time)
    o = c.options
    bound = o.offset_rate * ds + np.where(ds <= 1e-12, o.offset_speed_stationary * dt, 0.0)
    return _offset_margins("offset_rate", c, bound)


def _check_offset_speed(c: CheckInput) -> Margins | None:
    """|delta (o - o_ref)| <= offset_speed x time on every link with travel."""
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
    """The predicted pin's travel over each weld link along the seam within ``speed_tol`` of
    the seam's travel: | (q_{k+1} - q_k) . u_k + |p_{k+1} - p_k| - h_k | / h_k <= speed_tol
    for every weld link k of travel h_k, q = FK_p + dX_p - p the pin against its seam point,
    u_k the chord p_{k+1} - p_k normalised (the direction the seam point moves between the
    waypoints, on which :func:`verify_samples` projects the pin's velocity): the pin's mean
    speed along the seam over the link relative to the seam point's, minus 1, the chord's turn
    included (on a corner of radius R, a pin e inside the seam: about -e / R).

    The NLP's ``travel_speed`` rows ask for more (each waypoint holds half of each of its
    links, speed_tol h / 2, which implies this); what the process needs is the speed, so
    that is what is checked. The margin of link k is at its first waypoint (unit ``speed``:
    a ratio of the weld speed)."""
    m = c.task.n_start
    travel = c.task.link_travel()[m:]
    margin = np.full(len(c.task), np.inf)
    if not len(travel):
        return []
    p = c.task.frames.p[m:]
    pr = c.prediction
    q = pr.T[m:, :3, 3] + pr.dX[m:, :3] - p
    dp = np.diff(p, axis=0)
    chord = np.linalg.norm(dp, axis=1)
    moving = (travel > 1e-12) & (chord > 1e-12)
    u = dp[moving] / chord[moving, None]
    dev = np.einsum("ki,ki->k", np.diff(q, axis=0)[moving], u) + chord[moving] - travel[moving]
    margin[m + np.flatnonzero(moving)] = c.window.speed_tol - np.abs(dev) / travel[moving]
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
            mirror baseline's, the planner's ``offset_reference``): the offset checks bound
            the change of o - o_ref; None: zero.
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

    sigma_i = s_i + t_p(s_i) . (FK_p(q_i) + dX_p(q_i, F_i) - p(s_i)), with the seam point p and
    the in-plane seam tangent t_p (:func:`along_tangents`) interpolated linearly in the
    trajectory's arc length s_i (the seam point the plan puts the pin on), dX the process
    deflection with the task's seam reference. Its time derivative is the pin's travel speed
    (:meth:`TimedTrajectory.pin_speed`).
    """
    m = task.n_start
    fr = task.frames
    sw = fr.s[m:]

    def at_s(a: FloatArray) -> FloatArray:
        return np.stack([np.interp(traj.s, sw, a[m:, i]) for i in range(3)], axis=1)

    batch, dX = evaluate_poses(model, traj.q, traj.wrench, task.reference)
    t = at_s(along_tangents(task))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    pin = batch.T[:, :3, 3] + dX[:, :3]
    return np.asarray(traj.s + np.einsum("ki,ki->k", t, pin - at_s(fr.p)))


# --------------------------------------------------------------------------------------------
# Sample-by-sample verification of what is written

#: Phases in which the pin is in the material.
CONTACT_PHASES = ("plunge", "dwell", "accelerate", "weld", "decelerate", "stop")
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
FULL_DEPTH_PHASES = ("dwell", "accelerate", "weld", "decelerate", "stop")
#: Phases in which the seam point moves: the pin's travel speed is judged there, against the
#: commanded speed (:func:`_quantities`).
TRAVEL_PHASES = ("accelerate", "weld", "decelerate")
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
                                     "waypoints by",
                "stop_standstill": "the pin moves sideways during the end stop by"
                }.get(self.check, self.check)
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


# --------------------------------------------------------------------------------------------
# The robust claim: how much force uncertainty every weld quantity holds

#: The weld quantities of the robust claim, in the order a tie names the limiting one.
ROBUST_QUANTITIES = ("lateral", "depth", "tilt", "speed")
#: A model that is not linear in the wrench: the step of its linearisation at the nominal
#: force (relative, 0.1 %), the factor over the smallest linearised level within which a
#: point's vertices are evaluated with the model, the secant corrections of the level, the
#: halvings after them, and the tolerance of a vertex's margin [m, 1] (IPOPT's).
LINEARISATION_STEP = 1e-3
CANDIDATE_FACTOR = 1.5
SECANT_STEPS = 4
BISECTIONS = 8
VERTEX_TOL = 1e-7


@dataclass(frozen=True)
class RobustLimit:
    """Where one weld quantity reaches its tolerated force uncertainty.

    Attributes:
        quantity: ``lateral``, ``depth``, ``tilt`` or ``speed``.
        level: The largest uniform relative force uncertainty u for which the quantity holds
            at every vertex of the force box, at every sample it applies to (inf: no uncertain
            force moves it; 0: it fails at u = 0).
        index: 0-based sample (or waypoint) where it is reached, -1 if nowhere.
        t: Its time [s] (NaN if nowhere).
        phase: Its phase ("" if nowhere).
        s: Its arc length [m] (NaN if nowhere).
        kind: ``sample`` (a written sample, 1-based row of ``waypoints.csv``) or ``waypoint``.
    """

    quantity: str
    level: float
    index: int = -1
    t: float = float("nan")
    phase: str = ""
    s: float = float("nan")
    kind: str = "sample"

    @property
    def where(self) -> str:
        """``sample 1234 (t = 20.10 s, weld, s = 30.20 mm)`` (or ``waypoint ...``, its time
        on the schedule's clock), or ``""`` if nowhere."""
        if self.index < 0:
            return ""
        return (f"{self.kind} {self.index + 1} (t = {self.t:.2f} s, {self.phase}, s = "
                f"{self.s * 1e3:.2f} mm)")


@dataclass(frozen=True)
class RobustClaim:
    """The tolerated force uncertainty of every weld quantity (:func:`robust_claim`).

    Attributes:
        limits: Per quantity of :data:`ROBUST_QUANTITIES` its :class:`RobustLimit`.
        axial_force_control: The level every quantity but the depth would hold with the axial
            force exact and the depth the material's answer (axial force control); NaN where
            the plan already is under force control.
        linear: The model is linear in the wrench (closed form at the box's vertices), else
            the vertices were evaluated with the model and bisected.
        lateral_per_unit: Worst change of the lateral error per unit u at every point,
            sum_i |l . D_i| [m], (N,) (the closed form's; the secant's for a model that is
            not linear in the wrench).
        penetration_stiffness: k_p [N/m] of the penetration law the axial component was
            coupled with (:func:`coupled_deflection`), 0 where the box spreads the axial
            force itself.
    """

    limits: dict[str, RobustLimit]
    axial_force_control: float = float("nan")
    linear: bool = True
    lateral_per_unit: FloatArray = field(default_factory=lambda: np.zeros(0))
    penetration_stiffness: float = 0.0

    @property
    def force_model(self) -> str:
        """The force model of the claim, in the output's words: ``force box`` (every
        seam-frame force component spread by +-u) or ``coupled axial law, k_p 1056 N/mm``
        (traverse and lateral spread by +-u, the material's axial response by +-u and the
        axial force its answer to the penetration)."""
        if self.penetration_stiffness > 0:
            return f"coupled axial law, k_p {self.penetration_stiffness * 1e-3:.0f} N/mm"
        return "force box"

    @property
    def levels(self) -> dict[str, float]:
        """Quantity -> tolerated level."""
        return {q: lim.level for q, lim in self.limits.items()}

    @property
    def tolerated(self) -> float:
        """The level every quantity holds: the smallest one (inf if nothing is moved)."""
        return min(self.levels.values(), default=np.inf)

    @property
    def limiting(self) -> RobustLimit:
        """The quantity that limits the claim (the first of the smallest)."""
        return min(self.limits.values(), key=lambda lim: lim.level)

    def combined(self, other: RobustClaim) -> RobustClaim:
        """The claim over both point sets: per quantity the smaller level (ties: this one)."""
        limits = {q: (other.limits[q] if other.limits[q].level < lim.level else lim)
                  for q, lim in self.limits.items()}
        # Both from one task: both NaN (axial force control) or both levels.
        fc = min(self.axial_force_control, other.axial_force_control)
        return RobustClaim(limits, fc, self.linear and other.linear,
                           np.concatenate([self.lateral_per_unit, other.lateral_per_unit]),
                           self.penetration_stiffness)


@dataclass(frozen=True)
class ClaimInput:
    """The points a robust claim is computed on (written samples or planned waypoints; base
    frame, SI).

    Attributes:
        t: Time [s], (N,).
        phase: Phase, (N,).
        s: Arc length along the seam [m], (N,).
        batch: The model's kinematics of the joint values.
        wrench: Process wrench on the tool [N, N m], (N, 6).
        deflection: The model's process deflection under ``wrench`` [m, rad], (N, 6).
        p, t_dir, l_dir, n_dir: Seam point and unit tangent, lateral and tool-axis direction at
            every point, (N, 3).
        plate_normal: Plate normal, (N, 3).
        contact: Points in the material (lateral and tilt), (N,).
        full_depth: Points at full depth (depth), (N,).
        travel: Travel points (speed): the samples where the seam point moves (accelerate,
            weld, decelerate), or the constant-speed weld waypoints, (N,).
        speed_axis: Abscissa of the pin's speed: time [s] (samples) or arc length [m]
            (waypoints), (N,).
        speed_scale: 1 / weld speed [s/m] for time, 1 for arc length.
        cache: What :func:`_quantities` derives from the points alone (the seam's direction
            and the commanded speed), kept for the force box's many vertices.
    """

    t: FloatArray
    phase: NDArray[np.str_]
    s: FloatArray
    batch: PoseBatch
    wrench: FloatArray
    deflection: FloatArray
    p: FloatArray
    t_dir: FloatArray
    l_dir: FloatArray
    n_dir: FloatArray
    plate_normal: FloatArray
    contact: NDArray[np.bool_]
    full_depth: NDArray[np.bool_]
    travel: NDArray[np.bool_]
    speed_axis: FloatArray
    speed_scale: float
    cache: dict[str, tuple[FloatArray, FloatArray]] = field(default_factory=dict, compare=False,
                                                            repr=False)


def phase_gradient(y: FloatArray, x: FloatArray, phase: NDArray[np.str_]) -> FloatArray:
    """d y / d x (np.gradient, along the first axis) within each run of one phase, so no
    difference spans a phase change (the last weld sample's is not averaged with the
    deceleration's first step); a run of one point takes the difference across its
    neighbours (the whole array's gradient is taken only then: every run of two or more
    points overwrites its share of it)."""
    cut = np.flatnonzero(phase[1:] != phase[:-1]) + 1
    runs = list(zip(np.r_[0, cut], np.r_[cut, len(x)], strict=True))
    whole = not all(b - a >= 2 for a, b in runs)
    g: FloatArray = np.gradient(y, x, axis=0) if whole else np.empty(np.shape(y))
    for a, b in runs:
        if b - a >= 2:
            g[a:b] = np.gradient(y[a:b], x[a:b], axis=0)
    return g


def seam_direction(p: FloatArray, x: FloatArray, t_dir: FloatArray, normal: FloatArray
                   ) -> FloatArray:
    """The direction the seam point moves, unit (N, 3): the seam points p [m] (N, 3)
    differenced along x (time [s] or arc length [m]), i.e. the seam's own direction, in the
    plate; where p does not move, the frame tangent t_dir in the plate's plane,
    t - (t . n) n normalised (the tool-tilted frame tangent itself would count a depth change
    as travel)."""
    g = np.gradient(p, x, axis=0)
    n = np.linalg.norm(g, axis=1, keepdims=True)
    t = t_dir - np.einsum("ki,ki->k", t_dir, normal)[:, None] * normal
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return np.where(n > 1e-12, g / np.maximum(n, 1e-300), t)


def _quantities(c: ClaimInput, window: WeldWindow, dX: FloatArray, only: str = ""
                ) -> dict[str, tuple[FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]]:
    """Every weld quantity under the deflection dX (N, 6): value, lower and upper bound, and
    where it applies, each (M,) (tilt: work angles then travel angles, M = 2N). Every value is
    affine in dX, so for a wrench-linear model it is linear in the force box's u:

    * lateral: l . (FK_p + dX_p - p) in [lower, upper];
    * depth: n_plate . (FK_p + dX_p - p) in [-depth_deep, depth_shallow] (+ shallow);
    * tilt: sin of the work (travel) angle of the commanded tool axis z turned by the change
      of the deflection's rotation from the nominal one, (z + (dX_r - dX0_r) x z) . l (. t),
      in [-sin tol, sin tol] (the nominal rotation is the nominal tilt check's, which
      checks the commanded axis);
    * speed: the pin's travel speed along the seam off the commanded one, as a share of the
      weld speed, (t_p . d(FK_p + dX_p)/dx - v_c) x scale in [-speed_tol, speed_tol], t_p
      the direction the seam point moves (:func:`seam_direction`): on samples (x = time, scale =
      1 / v_weld) the pin's velocity along the seam against the commanded speed v_c (the weld
      speed in the weld phase, ds/dt while the tool accelerates and decelerates), wherever
      the seam point moves; at waypoints (x = s, scale 1) per unit of travel. The band is the
      weld speed's tolerance in mm/s, so it does not widen as the commanded speed passes
      through 0; on a curve the pin's own velocity counts (inside a corner at lateral error e
      it travels ds/dt (1 - kappa e)), not its projection's.

    ``only``: compute that quantity alone (the others are left out).
    """
    x = c.batch.T[:, :3, 3]
    pin = x + dX[:, :3] - c.p
    N = len(x)
    one = np.ones(N)
    out = {}
    if only in ("", "lateral"):
        out["lateral"] = (np.einsum("ki,ki->k", c.l_dir, pin), window.lower * one,
                          window.upper * one, c.contact)
    if only in ("", "depth"):
        out["depth"] = (np.einsum("ki,ki->k", c.plate_normal, pin), -window.depth_deep * one,
                        window.depth_shallow * one, c.full_depth)
    if only in ("", "tilt"):
        z = c.batch.T[:, :3, 2]
        zr = z + np.cross(dX[:, 3:] - c.deflection[:, 3:], z)
        sin_tol = np.sin(window.tilt_tol)
        out["tilt"] = (np.concatenate([np.einsum("ki,ki->k", zr, c.l_dir),
                                       np.einsum("ki,ki->k", zr, c.t_dir)]),
                       -sin_tol * np.ones(2 * N), sin_tol * np.ones(2 * N),
                       np.concatenate([c.contact, c.contact]))
    if only in ("", "speed"):
        speed = np.zeros(N)
        if c.travel.sum() >= 3:
            k, ax, ph = c.travel, c.speed_axis[c.travel], c.phase[c.travel]
            v = phase_gradient(x[k] + dX[k, :3], ax, ph)
            if "speed" not in c.cache:
                # The commanded speed: the weld speed itself at constant speed (so a program
                # that runs the weld slower is judged), ds/dt on the ramps.
                c.cache["speed"] = (
                    seam_direction(c.p[k], ax, c.t_dir[k], c.plate_normal[k]),
                    np.where(ph == "weld", 1.0, phase_gradient(c.s[k], ax, ph) * c.speed_scale))
            direction, ref = c.cache["speed"]
            speed[k] = np.einsum("ki,ki->k", direction, v) * c.speed_scale - ref
        out["speed"] = (speed, -window.speed_tol * one, window.speed_tol * one,
                        c.travel & (c.travel.sum() >= 3))
    return out


def _closed_form(value: FloatArray, lo: FloatArray, hi: FloatArray, mask: NDArray[np.bool_],
                 G: FloatArray) -> tuple[float, int]:
    """Largest u with value +- u G inside [lo, hi] at every masked point, and the point
    where it is reached: min dist / G (inf where G = 0 and inside, 0 where outside)."""
    if not mask.any():
        return np.inf, -1
    dist = np.minimum(value - lo, hi - value)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(G > 0, np.maximum(dist, 0.0) / G, np.where(dist >= 0, np.inf, 0.0))
    u = np.where(mask, u, np.inf)
    k = int(np.argmin(u))
    return float(u[k]), (k if np.isfinite(u[k]) else -1)


def _component_steps(task: PlanTask, c: ClaimInput) -> list[FloatArray]:
    """The wrench change (N, 6) of each seam-frame force component (traverse, lateral,
    axial) at u = 1: w_i f_i b_i (w = :attr:`PlanTask.spread_weights`)."""
    W = c.wrench
    dW = []
    for b, w in zip((c.t_dir, c.l_dir, c.n_dir), task.spread_weights, strict=True):
        d = np.zeros_like(W)
        d[:, :3] = (w * np.einsum("ki,ki->k", W[:, :3], b))[:, None] * b
        dW.append(d)
    return dW


def _component_deflections(model: ElastostaticModel, task: PlanTask, c: ClaimInput,
                           dW: list[FloatArray]) -> tuple[bool, list[FloatArray]]:
    """Whether the model is wrench-linear, and the deflection change D_i [m] (N, 6) per unit
    of each force component's change dW_i (see :func:`robust_claim`)."""
    phys = model.physical()
    if not phys.linear_compliance(c.batch.rows(slice(0, 1)))[1]:
        # dX = C F + const (the taught reference's load-independent part cancels): the
        # Cartesian compliance gives every D_i at once.
        C = phys.cartesian_compliance(c.batch)[:, :, :3]
        return True, [np.einsum("kij,kj->ki", C, d[:, :3]) for d in dW]
    h = LINEARISATION_STEP
    return False, [(model.process_deflection_batch(c.batch, c.wrench + h * d, task.reference)
                    - c.deflection) / h if np.any(d) else np.zeros_like(c.deflection)
                   for d in dW]


def robust_claim(model: ElastostaticModel, task: PlanTask, window: WeldWindow,
                 c: ClaimInput, kind: str = "sample") -> RobustClaim:
    """The largest uniform relative force uncertainty u each weld quantity holds.

    The force box: the seam-frame components f_i (traverse, lateral, axial) of every point's
    process force, each scaled by 1 +- u w_i (w = :attr:`PlanTask.spread_weights`: under axial
    force control the controller holds f_n, w_n = 0); the moments are kept. A quantity holds
    at u if at every vertex of the box (2^3 sign choices sigma) it stays inside its bounds at
    every point it applies to (:func:`_quantities`: lateral error, depth, work and travel
    angle, pin speed).

    * Wrench-linear model (every compliance effect has a Cartesian compliance: joints,
      springs, flange): the deflection at a vertex is dX0 + u sum_i sigma_i D_i, D_i the
      model's process deflection change for the component i alone (one batch call each), and
      every quantity is affine in dX, so its worst vertex is value0 +- u sum_i |g_i| and the
      largest u is min dist / sum_i |g_i| (closed form, exact: the vertices suffice, a
      linear function takes its extremes over a box at vertices).
    * Otherwise (torque- or direction-dependent stiffness, play): the closed form of the
      model linearised at the nominal force (D_i from a 0.1 % step) is the first guess; the
      vertices are then evaluated with the model itself (its public batch API) at every
      point whose linearised level is within :data:`CANDIDATE_FACTOR` of the smallest, the
      level is corrected by the vertices' own worst change (secant, up to
      :data:`SECANT_STEPS` times) and, if a vertex still fails, halved
      (:func:`_vertex_level`). That is exact
      where each quantity is monotone in each force component over the box (a stiffness that
      grows with the torque's size, or changes with its sign, keeps a joint's deflection
      monotone in its torque); where it is not, the worst case may lie inside the box and the
      vertices are a check, not a proof.

    Where the problem couples the axial force to the penetration (``[process.coupling]``
    under position control, ``task.penetration_stiffness`` > 0) the box spreads the
    material's axial response instead of the axial force, and every vertex is solved with the
    penetration law (:func:`coupled_claim`).

    Under position control the depth is the robot's: the force box moves it. Under axial
    force control the set force is exact and the depth is the material's answer to it, not
    the robot's deflection: the depth is not part of the claim (level inf). For position
    control :attr:`RobustClaim.axial_force_control` is the level the other quantities would
    hold with the axial force exact (w_n = 0; linearised at the nominal force for a model
    that is not wrench-linear): the measured gain of the force-control lever.
    """
    dW = _component_steps(task, c)
    linear, D = _component_deflections(model, task, c, dW)
    if task.penetration_stiffness > 0 and task.axial_control != "force":
        return coupled_claim(model, task, window, c, dW, D, kind)
    base = _quantities(c, window, c.deflection)
    gains = [{q: v[0] - base[q][0] for q, v in _quantities(c, window, c.deflection + Di).items()}
             for Di in D]
    force = task.axial_control == "force"
    limits: dict[str, RobustLimit] = {}
    fc = np.inf
    lateral = np.zeros(len(c.t))
    for q in ROBUST_QUANTITIES:
        u_k, G, fc_q = _linear_levels(base[q], [g[q] for g in gains], q == "depth" and force)
        fc = fc if q == "depth" else min(fc, fc_q)
        if q == "lateral":
            lateral = G
        k = int(np.argmin(u_k)) if len(u_k) else -1
        u = float(u_k[k]) if k >= 0 else np.inf
        if not linear and np.isfinite(u) and u > 0:
            u, k = _vertex_level(model, task, window, c, dW, q, u_k, u,
                                 [g[q] for g in gains])
        limits[q] = _limit_at(c, q, u, k, kind)
    return RobustClaim(limits, float("nan") if force else fc, linear, lateral)


def _linear_levels(quantity: tuple[FloatArray, FloatArray, FloatArray, NDArray[np.bool_]],
                   gains: list[FloatArray], exempt: bool,
                   ) -> tuple[FloatArray, FloatArray, float]:
    """One quantity's closed-form levels: per point u_k = dist / G (G = sum_i |g_i|, the
    worst vertex of a model linear in the wrench), G itself, and the smallest level with the
    axial component exact (traverse and lateral only: the force-control lever). ``exempt``
    (the depth under axial force control) gives every point level inf."""
    value, lo, hi, mask = quantity
    if exempt:
        mask = np.zeros_like(mask)
    G = np.sum([np.abs(g) for g in gains], axis=0)
    u_k = _levels(value, lo, hi, mask, G)
    fc = (float(np.min(_levels(value, lo, hi, mask, np.abs(gains[0]) + np.abs(gains[1]))))
          if len(u_k) else np.inf)
    return u_k, G, fc


def _limit_at(c: ClaimInput, q: str, u: float, k: int, kind: str) -> RobustLimit:
    """Quantity q's level u, reached at row k of ``c`` (k mod the number of points; -1 or an
    infinite level: nowhere)."""
    N = len(c.t)
    kk = k % N if k >= 0 and np.isfinite(u) else -1
    if kk < 0:
        return RobustLimit(q, u)
    return RobustLimit(q, u, kk, float(c.t[kk]), str(c.phase[kk]), float(c.s[kk]), kind)


def _levels(value: FloatArray, lo: FloatArray, hi: FloatArray, mask: NDArray[np.bool_],
            G: FloatArray) -> FloatArray:
    """Per point the largest u with value +- u G inside [lo, hi]: dist / G (inf where G = 0
    and inside, 0 where outside, inf where the quantity does not apply)."""
    dist = np.minimum(value - lo, hi - value)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(G > 0, np.maximum(dist, 0.0) / G, np.where(dist >= 0, np.inf, 0.0))
    return np.where(mask, u, np.inf)


def _take(c: ClaimInput, idx: NDArray[np.int_]) -> ClaimInput:
    """The claim's points ``idx`` (sorted)."""
    batch = c.batch.rows(idx)
    return ClaimInput(c.t[idx], c.phase[idx], c.s[idx], batch, c.wrench[idx],
                      c.deflection[idx], c.p[idx], c.t_dir[idx], c.l_dir[idx], c.n_dir[idx],
                      c.plate_normal[idx], c.contact[idx], c.full_depth[idx], c.travel[idx],
                      c.speed_axis[idx], c.speed_scale)


def _vertex_sets(q: str, gains: list[FloatArray], idx: NDArray[np.int_], N: int, blocks: int,
                 ) -> list[tuple[FloatArray, NDArray[np.bool_]]]:
    """The force box's vertices to evaluate for quantity q at the points ``idx`` (of N), as
    (sign per point and component (n, 3), the rows of the quantity's ``blocks`` x n values
    they judge): all 8 for the pin speed (a difference of neighbouring samples), else per
    block the two the linearised changes ``gains`` (3 x (blocks N,)) find worst,
    sigma = +-sign g."""
    n = len(idx)
    if q == "speed":
        return [(np.broadcast_to(np.array(sig), (n, 3)), np.ones(n, dtype=bool))
                for sig in itertools.product((-1.0, 1.0), repeat=3)]
    sets: list[tuple[FloatArray, NDArray[np.bool_]]] = []
    for blk in range(blocks):
        sgn = np.stack([np.where(g[blk * N:(blk + 1) * N][idx] >= 0, 1.0, -1.0)
                        for g in gains], axis=1)
        on = np.zeros(blocks * n, dtype=bool)
        on[blk * n:(blk + 1) * n] = True
        sets += [(sgn, on), (-sgn, on)]
    return sets


def _halved(vertices: Callable[[float], tuple[FloatArray, FloatArray]], u: float,
            idx: NDArray[np.int_]) -> tuple[float, int]:
    """The last resort of the vertex searches: u halved (up to :data:`BISECTIONS` times)
    until every vertex holds (else 0), and the point of ``idx`` with the smallest margin
    there."""
    lo_u = 0.0
    for _ in range(BISECTIONS):
        margin, _change = vertices(u)
        if np.min(margin) >= -VERTEX_TOL:
            lo_u = u
            break
        u *= 0.5
    return lo_u, int(idx[int(np.argmin(margin)) % len(idx)])


def _vertex_deflection(model: ElastostaticModel, task: PlanTask, batch: PoseBatch,
                       wrench: FloatArray, sgn: FloatArray,
                       done: list[tuple[FloatArray, FloatArray]]) -> FloatArray:
    """The model's process deflection at a vertex (signs ``sgn`` (n, 3), wrench (n, 6)),
    evaluated only at the points where no vertex of ``done`` (signs, deflection) of the same
    level u has the same signs (the same wrench: the tilt's work- and travel-angle vertices
    mostly coincide); the model is evaluated point by point, so each point's deflection is
    the one a call on every point gives."""
    if not done:
        return model.process_deflection_batch(batch, wrench, task.reference)
    dX = np.empty((len(batch), 6))
    todo = np.ones(len(batch), dtype=bool)
    for sg, dx in done:
        same = todo & np.all(sg == sgn, axis=1)
        dX[same] = dx[same]
        todo &= ~same
    if todo.all():
        return model.process_deflection_batch(batch, wrench, task.reference)
    if todo.any():
        rows = np.flatnonzero(todo)
        dX[rows] = model.process_deflection_batch(batch.rows(rows), wrench[rows],
                                                  task.reference)
    return dX


def _vertex_level(model: ElastostaticModel, task: PlanTask, window: WeldWindow,
                  c: ClaimInput, dW: list[FloatArray], q: str, u_k: FloatArray, u0: float,
                  gains: list[FloatArray]) -> tuple[float, int]:
    """The level of quantity q at the force box's vertices, each evaluated with the model,
    from the linearised per-point levels u_k (M,), their minimum u0 and the linearised
    changes per component ``gains`` (3 x (M,)): the level and the point (index into ``c``'s
    rows) where it is reached (see :func:`robust_claim`).

    A quantity of one point (lateral, depth, tilt) is checked at every point it applies to,
    at the two vertices the linearisation finds worst there (sigma = +-sign g: where the
    quantity is monotone in each component its extremes over the box are there); the pin
    speed, a difference of neighbouring samples, at all 8 vertices of one box for the whole
    weld, at the points whose linearised level is within :data:`CANDIDATE_FACTOR` of its
    smallest (and their neighbours)."""
    N = len(c.t)
    M = len(u_k)
    if q == "speed":
        cand = np.unique(np.flatnonzero(u_k <= CANDIDATE_FACTOR * u0) % N)
        idx = np.unique(np.clip(np.concatenate([cand - 1, cand, cand + 1]), 0, N - 1))
    else:
        idx = np.unique(np.flatnonzero(np.isfinite(u_k)) % N)
        cand = idx
    sub = _take(c, idx)
    n = len(idx)
    value, lo, hi, mask = _quantities(sub, window, sub.deflection, q)[q]
    rows = np.tile(np.isin(idx, cand), M // N)
    mask = mask & rows
    sets = _vertex_sets(q, gains, idx, N, M // N)  # tilt: work angles, then travel angles
    dWs = [d[idx] for d in dW]

    def vertices(u: float) -> tuple[FloatArray, FloatArray]:
        """Worst margin and worst change of q over the vertices at u, per point."""
        margin = np.full(len(value), np.inf)
        change = np.zeros(len(value))
        done: list[tuple[FloatArray, FloatArray]] = []
        for sgn, on in sets:
            Wv = sub.wrench + u * sum((sgn[:, i, None] * dWs[i] for i in range(3)),
                                      np.zeros_like(sub.wrench))
            dX = _vertex_deflection(model, task, sub.batch, Wv, sgn, done)
            done.append((sgn, dX))
            v = _quantities(sub, window, dX, q)[q][0]
            margin = np.where(on, np.minimum(margin, np.minimum(v - lo, hi - v)), margin)
            change = np.where(on, np.maximum(change, np.abs(v - value)), change)
        return np.where(mask, margin, np.inf), change

    u = u0
    for _ in range(SECANT_STEPS):
        margin, change = vertices(u)
        if np.min(margin) >= -VERTEX_TOL:
            return u, int(idx[int(np.argmin(margin)) % n])
        lv = _levels(value, lo, hi, mask, change / u)
        u = min(float(np.min(lv)), 0.999 * u)
    return _halved(vertices, u, idx)


def waypoint_claim(model: ElastostaticModel, task: PlanTask, window: WeldWindow,
                   q: FloatArray, constant_speed: tuple[float, float] | None = None,
                   prediction: tuple[PoseBatch, FloatArray] | None = None) -> RobustClaim:
    """:func:`robust_claim` of joint values q (K, n) [rad] at the task's waypoints (every one in
    the material but the plunge start; the pin's velocity along the seam per unit of travel
    over the weld waypoints (:func:`_quantities`), only those within ``constant_speed``
    (first, last arc length [m] of the constant-speed weld samples) where given: a waypoint
    has no time, so the acceleration and deceleration are judged on written samples only):
    how a baseline without written samples (the mirror) is judged, and the plan's waypoints
    beside its samples. ``prediction``: the poses of q and their process deflection [m, rad]
    (K, 6) when the caller has them (:func:`predict` with ``batch``), else computed here.
    Inside a :func:`shared_evaluations` scope a claim of the same joint values, task, window,
    constant-speed stretch and deflection is computed once."""
    W = task.wrench_base
    if prediction is None:
        batch, dX = evaluate_poses(model, q, W, task.reference)
    else:
        batch, dX = prediction
    ev = _shared(model, np.atleast_2d(np.asarray(q, dtype=float)), create=False)
    key: tuple[Any, ...] | None = None
    if ev is not None and ev.batch is batch:
        key = (id(task), window, constant_speed, dX.shape, dX.tobytes(), _params(model))
        hit = ev.claims.get(key)
        if hit is not None and hit[0] is task:
            return hit[1]
    claim = _waypoint_claim(model, task, window, batch, dX, constant_speed)
    if ev is not None and key is not None:
        ev.claims[key] = (task, claim)
    return claim


def _waypoint_claim(model: ElastostaticModel, task: PlanTask, window: WeldWindow,
                    batch: PoseBatch, dX: FloatArray,
                    constant_speed: tuple[float, float] | None) -> RobustClaim:
    """:func:`waypoint_claim` of the poses ``batch`` with their deflection dX."""
    W = task.wrench_base
    fr = task.frames
    travel = task.phase == "weld"
    if constant_speed is not None:
        tol = 1e-9
        travel = travel & (task.s >= constant_speed[0] - tol) & (task.s <= constant_speed[1] + tol)
    c = ClaimInput(task.time, task.phase, task.s, batch, W, dX, fr.p, fr.t, fr.l, fr.n,
                   task.plate_normal, ~task.at_surface, np.isin(task.phase, FULL_DEPTH_PHASES),
                   travel, task.s, 1.0)
    return robust_claim(model, task, window, c, "waypoint")


#: The coupled axial law (:func:`coupled_deflection`): Newton and secant steps of the axial
#: force per vertex and the residual [N] below which the rest of the step is taken linearly
#: (on zk500_table6_seam's samples the levels agree with a 1e-4 N solve to 1e-6 (lateral,
#: above it) and 2e-4 (depth, below it) relative: the linear rest errs by its nonlinear
#: part, below the vertices' tolerance :data:`VERTEX_TOL`).
COUPLED_STEPS = 8
#: Regula falsi steps of a coupled level after the secant found a feasible one below it.
REFINE_STEPS = 3
COUPLED_TOL = 5.0


@dataclass(frozen=True)
class AxialCoupling:
    """The penetration law of the process at the claim's points, linearised at the nominal
    force (:func:`coupled_deflection`).

    Attributes:
        force: Nominal axial force f0 = F . n [N], (N,) (the plan's).
        stiffness: k_p [N/m] where the pin presses on the material (f0 > 0), 0 elsewhere, (N,).
        per_newton: The deflection per newton of axial force A [m/N, rad/N], (N, 6).
        compliance: The robot's axial compliance c = n . A_p [m/N], (N,).
        cross: The pin's axial deflection n . D_i [m] per unit u of the traverse and the
            lateral component (the force box's, linearised), (N, 2).
    """

    force: FloatArray
    stiffness: FloatArray
    per_newton: FloatArray
    compliance: FloatArray
    cross: FloatArray


def _axial_coupling(model: ElastostaticModel, task: PlanTask, c: ClaimInput,
                    D: list[FloatArray]) -> AxialCoupling:
    """:class:`AxialCoupling` at the claim's points: A from a step of the axial force of
    max(:data:`LINEARISATION_STEP` f0, 1 N) along n (one model call; a relative step alone
    would be lost in rounding where the force ramps up from 0)."""
    f0 = np.einsum("ki,ki->k", c.wrench[:, :3], c.n_dir)
    on = f0 > 0
    h = np.maximum(LINEARISATION_STEP * f0, 1.0)
    W = c.wrench.copy()
    W[:, :3] += h[:, None] * c.n_dir
    dX = model.process_deflection_batch(c.batch, W, task.reference)
    A = np.where(on[:, None], (dX - c.deflection) / h[:, None], 0.0)
    return AxialCoupling(f0, np.where(on, task.penetration_stiffness, 0.0), A,
                         np.einsum("ki,ki->k", A[:, :3], c.n_dir),
                         np.stack([np.einsum("ki,ki->k", Di[:, :3], c.n_dir)
                                   for Di in D[:2]], axis=1))


def coupled_deflection(model: ElastostaticModel, task: PlanTask, c: ClaimInput,
                       ax: AxialCoupling, dW: list[FloatArray], sgn: FloatArray, u: float
                       ) -> FloatArray:
    """The deflection [m, rad] (N, 6) at the vertex sgn (N, 3) of the coupled force box at u.

    The traverse and lateral components are spread as in the force box (f_i (1 + sigma_i u));
    the axial force is the material's answer to the penetration, its response spread by
    sigma_n u (seed 001 Fig. 8's co-simulation, the law of ``[process.coupling]`` anchored at
    the plan's nominal force f0 at the planned penetration)::

        f = (1 + sigma_n u) max(0, f0 + k_p dp(f)),   dp(f) = -n . (dX_p(W(f)) - dX0_p)

    solved per point by a Newton step f <- f - r(f) / r', r = g - f, r' = -(1 + (1 + sigma_n u)
    k_p c) (exact in one step for a wrench-linear model: the map is affine), then secant
    steps (up to :data:`COUPLED_STEPS`, until |r| < :data:`COUPLED_TOL`, the rest of the step
    taken linearly, A r / |r'|) for the others; W(f) the vertex's wrench with the axial force
    f, 1 + sigma_n u not below 0.
    For a linear model f - f0 = (sigma_n u f0 - (1 + sigma_n u) k_p n . dX_tl) /
    (1 + (1 + sigma_n u) k_p c): a response spread eps moves the force by about
    eps / (1 + k_p c).
    """
    return coupled_deflections(model, task, c, ax, dW, [sgn], u)[0]


@dataclass(frozen=True)
class TiledVertices:
    """The claim's points repeated once per vertex of :func:`coupled_deflections` (row
    v N + k: vertex v at point k), with what does not depend on the level u gathered once, so
    a caller that evaluates the same vertices at several u (:func:`_coupled_vertex_level`)
    gathers them once and the effects' pose caches (:attr:`PoseBatch.cache`) live across the
    calls.

    Two rows of one point with the same signs (the tilt's work- and travel-angle vertices
    mostly coincide) have the same wrench at every step while both vertices step, so the
    model is evaluated once per distinct (point, signs) row: ``batch`` holds those rows,
    ``first`` the first tiled row of each and ``inverse`` each tiled row's (both None when
    every row is distinct: ``batch`` is then the tiled batch itself). Once some vertices have
    stopped, only the rows of those still stepping are evaluated (``parts``: per set of
    stepping vertices their rows' poses, kept across the calls at several u).

    Attributes:
        batch: The distinct rows' poses (``c.batch`` itself for one vertex).
        first: The first tiled row of each distinct row (U,), or None.
        inverse: The distinct row of each tiled row (V N,), or None.
        sgn: Sign per row and seam-frame component (V N, 3).
        wrench, dW_t, dW_l: The nominal wrench and the traverse and lateral changes at u = 1
            [N, N m] (V N, 6).
        n_dir: Tool-axis direction (V N, 3).
        deflection: Nominal deflection dX0 [m, rad] (V N, 6).
        force, stiffness, per_newton, compliance, cross_t, cross_l: :class:`AxialCoupling`'s
            fields, repeated.
    """

    batch: PoseBatch
    first: NDArray[np.int_] | None
    inverse: NDArray[np.int_] | None
    sgn: FloatArray
    wrench: FloatArray
    dW_t: FloatArray
    dW_l: FloatArray
    n_dir: FloatArray
    deflection: FloatArray
    force: FloatArray
    stiffness: FloatArray
    per_newton: FloatArray
    compliance: FloatArray
    cross_t: FloatArray
    cross_l: FloatArray
    parts: dict[bytes, tuple[PoseBatch, NDArray[np.int_], NDArray[np.int_]]] = field(
        default_factory=dict, compare=False, repr=False)


def tiled_vertices(c: ClaimInput, ax: AxialCoupling, dW: list[FloatArray],
                   signs: list[FloatArray]) -> TiledVertices:
    """:class:`TiledVertices` of the vertices ``signs`` (each (N, 3)) at the points of ``c``."""
    V, N = len(signs), len(c.t)
    tile = np.tile(np.arange(N), V)
    sgn = np.concatenate(signs)
    first: NDArray[np.int_] | None = None
    inverse: NDArray[np.int_] | None = None
    if V > 1 and np.all(np.abs(sgn) == 1.0):
        # One key per (point, signs): the point and a bit per positive component.
        key = tile * 8 + (sgn > 0) @ np.array([1, 2, 4])
        first, inverse = np.unique(key, return_index=True, return_inverse=True)[1:]
        if len(first) == len(key):
            first = inverse = None
    batch = (c.batch if V == 1 else c.batch.rows(tile) if first is None
             else c.batch.rows(tile[first]))
    return TiledVertices(batch, first, inverse, sgn,
                         c.wrench[tile], dW[0][tile], dW[1][tile], c.n_dir[tile],
                         c.deflection[tile], ax.force[tile], ax.stiffness[tile],
                         ax.per_newton[tile], ax.compliance[tile], ax.cross[tile, 0],
                         ax.cross[tile, 1])


def coupled_deflections(model: ElastostaticModel, task: PlanTask, c: ClaimInput,
                        ax: AxialCoupling, dW: list[FloatArray], signs: list[FloatArray],
                        u: float, tiled: TiledVertices | None = None) -> list[FloatArray]:
    """:func:`coupled_deflection` at several vertices (each ``signs[v]`` (N, 3)) with one model
    call per step for all of them: every vertex keeps its own steps and its own stop (the
    model is evaluated point by point, so the result is each vertex's alone).

    ``tiled``: :func:`tiled_vertices` of the same points and vertices, built once by a caller
    that evaluates them at several u."""
    V, N = len(signs), len(c.t)
    tv = tiled if tiled is not None else tiled_vertices(c, ax, dW, signs)
    batch, sgn = tv.batch, tv.sgn
    n_dir, dX0, f0 = tv.n_dir, tv.deflection, tv.force
    k_p, A = tv.stiffness, tv.per_newton
    scale = np.maximum(0.0, 1.0 + sgn[:, 2] * u)
    W = tv.wrench + u * (sgn[:, 0, None] * tv.dW_t + sgn[:, 1, None] * tv.dW_l)
    slope = 1.0 + scale * k_p * tv.compliance
    # The linear answer first (exact for a wrench-linear model).
    tl = u * (sgn[:, 0] * tv.cross_t + sgn[:, 1] * tv.cross_l)
    f = np.maximum(0.0, f0 + ((scale - 1.0) * f0 - scale * k_p * tl) / slope)
    dX = dX0.copy()
    r = np.zeros(len(f))
    prev_f, prev_r = np.zeros(len(f)), np.zeros(len(f))
    live = np.ones(V, dtype=bool)  # vertices still stepping
    for step in range(COUPLED_STEPS):
        # The whole tiled batch each step (its pose caches stay valid); a vertex that has
        # stopped keeps its deflection and residual.
        rows: slice | NDArray[np.int_] = (slice(None) if live.all()
                                          else np.flatnonzero(np.repeat(live, N)))
        Wf = W.copy()
        Wf[:, :3] += (f - f0)[:, None] * n_dir
        if not live.all():
            # The rows of the vertices still stepping, each distinct one once, its wrench
            # from a tiled row of it that still steps (a stopped vertex keeps its values).
            part, rep, pos = _stepping_part(tv, live, N)
            dX[rows] = model.process_deflection_batch(part, Wf[rep], task.reference)[pos]
        elif tv.first is None or tv.inverse is None:
            dX[:] = model.process_deflection_batch(batch, Wf, task.reference)
        else:
            dX[:] = model.process_deflection_batch(batch, Wf[tv.first],
                                                   task.reference)[tv.inverse]
        dp = -np.einsum("ki,ki->k", dX[rows, :3] - dX0[rows, :3], n_dir[rows])
        r[rows] = np.where(f0[rows] > 0, scale[rows] * np.maximum(0.0, f0[rows]
                                                                    + k_p[rows] * dp),
                           0.0) - f[rows]
        live &= np.max(np.abs(r).reshape(V, N), axis=1, initial=0.0) >= COUPLED_TOL
        if not np.any(live):
            break
        rows = slice(None) if live.all() else np.flatnonzero(np.repeat(live, N))
        # r(f) falls with f (a larger force lifts the pin: dr/df = -(1 + scale k_p c) <= -1):
        # secant slopes once two points are known, clamped to that sign.
        d = -slope[rows]
        if step > 0:
            with np.errstate(divide="ignore", invalid="ignore"):
                sec = (r[rows] - prev_r[rows]) / (f[rows] - prev_f[rows])
            d = np.where(np.isfinite(sec) & (sec < -1.0), sec, d)
        prev_f[rows], prev_r[rows] = f[rows], r[rows]
        f[rows] = np.maximum(0.0, f[rows] - r[rows] / d)
    # The rest of the step, linearly: within COUPLED_TOL its second-order error is far below
    # the vertices' tolerance.
    out = dX + A * (r / slope)[:, None]
    return [out[v * N:(v + 1) * N] for v in range(V)]


def _stepping_part(tv: TiledVertices, live: NDArray[np.bool_], N: int
                   ) -> tuple[PoseBatch, NDArray[np.int_], NDArray[np.int_]]:
    """The rows of the ``live`` vertices of :class:`TiledVertices` (N points each) that the
    model evaluates: their poses (each distinct row once), the tiled row whose wrench each
    takes (the first of its tiled rows that still steps) and, per tiled row of a live vertex
    in order, its row among them; kept in ``tv.parts`` per set of live vertices."""
    key = live.tobytes()
    if key not in tv.parts:
        stepping = np.repeat(live, N)
        rows = np.flatnonzero(stepping)
        if tv.inverse is None:
            tv.parts[key] = (tv.batch.rows(rows), rows, np.arange(len(rows)))
        else:
            ids, pos = np.unique(tv.inverse[rows], return_inverse=True)
            n = len(tv.inverse)
            at = np.full(len(ids), n)
            np.minimum.at(at, pos, rows)
            tv.parts[key] = (tv.batch.rows(ids), at, pos)
    return tv.parts[key]


def _take_coupling(ax: AxialCoupling, idx: NDArray[np.int_]) -> AxialCoupling:
    return AxialCoupling(ax.force[idx], ax.stiffness[idx], ax.per_newton[idx],
                         ax.compliance[idx], ax.cross[idx])


def coupled_claim(model: ElastostaticModel, task: PlanTask, window: WeldWindow,
                  c: ClaimInput, dW: list[FloatArray], D: list[FloatArray],
                  kind: str = "sample") -> RobustClaim:
    """:func:`robust_claim` with the axial force coupled to the penetration (position control
    with ``[process.coupling]``, ``task.penetration_stiffness`` k_p > 0): the box spreads the
    traverse and lateral forces and the material's axial response by +-u, and the axial force
    at every vertex is the law's answer (:func:`coupled_deflection`).

    The first guess is the closed form of the coupling linearised at u = 0: the deflection
    changes per unit u D_t' = D_t - A k_p (n . D_t) / (1 + k_p c) (the same for D_l) and
    D_n' = D_n / (1 + k_p c) (A the deflection per newton of axial force, c = n . A its axial
    part, D_i from :func:`_component_deflections`). The level is then corrected at the box's
    vertices, each solved with the coupling on the model itself, as :func:`_vertex_level`
    does (the coupled map is not linear in u even for a wrench-linear robot: the vertices are
    a proof where each quantity is monotone in each component, else a check).
    :attr:`RobustClaim.axial_force_control` is the force box's lever (the axial force exact)."""
    ax = _axial_coupling(model, task, c, D)
    den = 1.0 + ax.stiffness * ax.compliance

    def coupled(Di: FloatArray) -> FloatArray:
        return Di - ax.per_newton * (ax.stiffness * np.einsum("ki,ki->k", Di[:, :3], c.n_dir)
                                     / den)[:, None]

    Dc = [coupled(D[0]), coupled(D[1]), D[2] / den[:, None]]
    base = _quantities(c, window, c.deflection)
    gains = [{q: v[0] - base[q][0] for q, v in _quantities(c, window, c.deflection + Di).items()}
             for Di in Dc]
    exact = [{q: v[0] - base[q][0] for q, v in _quantities(c, window, c.deflection + Di).items()}
             for Di in D[:2]]
    limits: dict[str, RobustLimit] = {}
    fc = np.inf
    N = len(c.t)
    lateral = np.zeros(N)
    for q in ROBUST_QUANTITIES:
        value, lo, hi, mask = base[q]
        G = np.sum([np.abs(g[q]) for g in gains], axis=0)
        if q == "lateral":
            lateral = G
        u_k = _levels(value, lo, hi, mask, G)
        k = int(np.argmin(u_k)) if len(u_k) else -1
        u = float(u_k[k]) if k >= 0 else np.inf
        if q != "depth" and len(u_k):
            fc = min(fc, float(np.min(_levels(value, lo, hi, mask, np.abs(exact[0][q])
                                               + np.abs(exact[1][q])))))
        if np.isfinite(u) and u > 0:
            u, k = _coupled_vertex_level(model, task, window, c, ax, dW, q, u_k, u,
                                         [g[q] for g in gains])
        kk = k % N if k >= 0 and np.isfinite(u) else -1
        limits[q] = (RobustLimit(q, u) if kk < 0 else
                     RobustLimit(q, u, kk, float(c.t[kk]), str(c.phase[kk]), float(c.s[kk]),
                                 kind))
    return RobustClaim(limits, fc, False, lateral, task.penetration_stiffness)


def _coupled_vertex_level(model: ElastostaticModel, task: PlanTask, window: WeldWindow,
                          c: ClaimInput, ax: AxialCoupling, dW: list[FloatArray], q: str,
                          u_k: FloatArray, u0: float, gains: list[FloatArray]
                          ) -> tuple[float, int]:
    """:func:`_vertex_level` with every vertex solved with the coupled axial law
    (:func:`coupled_deflection`): the same vertices, secant corrections (down from a failing
    level, and up from a holding one: the coupled change is not linear in u) and halvings,
    then up to :data:`REFINE_STEPS` regula falsi steps between the holding and the failing
    level, at the
    points whose linearised level is within :data:`CANDIDATE_FACTOR` of the smallest for
    every quantity (each vertex costs a few model calls here; the level only falls from
    u0, so a point left out would need its coupled level below 1 / CANDIDATE_FACTOR of its
    linearised one). The level is at most 1 (+-100 %)."""
    N = len(c.t)
    M = len(u_k)
    cand = np.unique(np.flatnonzero(u_k <= CANDIDATE_FACTOR * u0) % N)
    if q == "speed":
        idx = np.unique(np.clip(np.concatenate([cand - 1, cand, cand + 1]), 0, N - 1))
    else:
        idx = cand
    sub = _take(c, idx)
    sub_ax = _take_coupling(ax, idx)
    n = len(idx)
    value, lo, hi, mask = _quantities(sub, window, sub.deflection, q)[q]
    mask = mask & np.tile(np.isin(idx, cand), M // N)
    sets = _vertex_sets(q, gains, idx, N, M // N)
    signs = [sg for sg, _ in sets]
    dWs = [d[idx] for d in dW]
    tiled = tiled_vertices(sub, sub_ax, dWs, signs)

    def vertices(u: float) -> tuple[FloatArray, FloatArray]:
        """Worst margin over the vertices at u, and the secant level through u = 0 of each
        vertex's own change toward its own bound (the two sides differ), per point."""
        margin = np.full(len(value), np.inf)
        level = np.full(len(value), np.inf)
        dXs = coupled_deflections(model, task, sub, sub_ax, dWs, signs, u, tiled)
        for (_sgn, on), dX in zip(sets, dXs, strict=True):
            v = _quantities(sub, window, dX, q)[q][0]
            margin = np.where(on, np.minimum(margin, np.minimum(v - lo, hi - v)), margin)
            d = (v - value) / u
            with np.errstate(divide="ignore", invalid="ignore"):
                lv = np.where(d > 0, (hi - value) / d, np.where(d < 0, (value - lo) / -d,
                                                                np.inf))
            level = np.where(on, np.minimum(level, np.maximum(lv, 0.0)), level)
        return np.where(mask, margin, np.inf), np.where(mask, level, np.inf)

    u = min(u0, 1.0)  # past +-100 % a force changes sign: the claim stops there
    ok: tuple[float, float, int] | None = None
    bad: tuple[float, float] | None = None
    for _ in range(SECANT_STEPS):
        margin, level = vertices(u)
        m = float(np.min(margin))
        if m >= -VERTEX_TOL:
            ok = (u, m, int(idx[int(np.argmin(margin)) % n]))
        else:
            bad = (u, m)
        if ok is not None and bad is not None:
            break
        # The vertices' own change per unit u predicts the level (secant through u = 0): down
        # from a failing level, up from a holding one (the coupled change is not linear in u).
        # Up only to CANDIDATE_FACTOR u0: the points left out have their linearised level
        # above it.
        lv = min(float(np.min(level)), CANDIDATE_FACTOR * u0, 1.0)
        if ok is not None and (lv <= u * (1 + 1e-4) or not np.isfinite(np.min(level))):
            break
        u = lv if ok is not None else min(lv, 0.999 * u)
    if ok is not None:
        u, m, k = ok
        # Regula falsi on the worst margin between the holding and the failing level.
        for _ in range(REFINE_STEPS):
            if bad is None:
                break
            u_try = u + 0.999 * (bad[0] - u) * m / (m - bad[1])
            if not u < u_try < bad[0]:
                break
            margin, _change = vertices(u_try)
            m_try = float(np.min(margin))
            if m_try >= -VERTEX_TOL:
                u, m, k = u_try, m_try, int(idx[int(np.argmin(margin)) % n])
            else:
                bad = (u_try, m_try)
        return u, k
    return _halved(vertices, u, idx)


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
        tolerated_uncertainty: Largest uniform u for which every weld quantity holds at
            every vertex of the force box at every sample it applies to (the
            :class:`RobustClaim`'s; inf if no uncertain force moves any; 0 if one fails at
            u = 0).
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
        claim: The tolerated force uncertainty per weld quantity (:func:`robust_claim`).
        constant_speed: Arc lengths [m] (first, last) of the constant-speed weld samples,
            where the pin speed is judged (None without such samples).
        deflection: The model's process deflection of every sample under its wrench, base
            frame [m, rad], (N, 6): what every check above is computed from
            (``waypoints.csv`` writes it, :func:`~rfsw_plan.planfiles.waypoints.waypoint_table`).
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
    claim: RobustClaim | None = None
    constant_speed: tuple[float, float] | None = None
    deflection: FloatArray | None = field(default=None, compare=False, repr=False)

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
    robust: bool = True,
) -> SampleVerification:
    """Check every sample of a trajectory as it is written, numerically and independently.

    Nothing here uses CasADi or the planner's interpolation: the commanded pose is the
    forward kinematics of the sample's joint values, the deflection the model's process
    deflection (every physical effect, the task's seam reference) under the sample's wrench,
    the derivatives finite differences of the samples in time. Checks:

    * in-material samples (plunge below the plate surface, dwell, accelerate, weld,
      decelerate, stop): the lateral pin error e = l . (FK_p(q) + dX_p(q, F) - p(s)) inside
      [lower + margin, upper - margin];
    * the rest of the weld envelope: the depth along the plate normal within the depth
      window at full depth (dwell to the end stop), work and travel angle within the tilt
      tolerance in the material, the pin's travel speed within the speed tolerance (a share
      of the weld speed) of the commanded speed wherever the seam point moves (the
      acceleration and deceleration included; :func:`_quantities`), and no pin below the
      plate surface before the plunge;
    * every sample: joint limits, and joint velocity, acceleration and jerk limits;
    * the end stop: the predicted pin's lateral error moves by at most
      :data:`~rfsw_plan.process.task.STANDSTILL_MOTION` from the weld's last sample through
      the stop (the forces relax while the tool stands);
    * stationarity (with ``q_waypoints``): the commanded TCP of every plunge sample inside the
      box spanned by the planned plunge waypoints (and the first dwell one), of every dwell
      sample inside the box of the planned dwell waypoints (with the last plunge and the first
      weld waypoint), each widened by ``STATION_TOL``: the TCP moves only as the fake target
      must follow the force ramp, no overshoot between ramp points.

    It also gives the tolerated force uncertainty of every weld quantity
    (:func:`robust_claim`): the largest u for which the lateral error, the depth, the work
    and travel angle and the pin speed hold at every vertex of the force box
    |delta f_i| <= u |f_i| (seam-frame components) at every sample they apply to, on the
    model itself (bare windows, no margin).

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
        robust: Also compute the tolerated force uncertainty (:func:`robust_claim`, the
            costliest part). False leaves ``claim`` None, ``worst_per_unit`` zero and
            ``tolerated_uncertainty`` NaN: the nominal checks alone, e.g. to confirm that a
            model rebuilt from the files reproduces the written samples.

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
    batch, dX = evaluate_poses(model, Q, W, task.reference)
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
    full = np.isin(phase, FULL_DEPTH_PHASES)
    travel = np.isin(phase, TRAVEL_PHASES)
    cin = ClaimInput(t, phase, s, batch, W, dX, p, tt, ll, nn, npl, contact, full, travel, t,
                     _time_per_length(task))
    claim = robust_claim(model, task, window, cin) if robust else None
    # Worst case of the lateral error per unit uncertainty: sum_i |l . D_i| (the box's
    # worst vertex; for a wrench-linear model sum_i |f_i| |l^T C_tt b_i|, seed 000 eq. 11).
    R, tolerated = _claim_terms(claim, contact)

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
    if N >= 3 and travel.sum() >= 3 and task.travel_speed > 0:
        dev = _quantities(cin, window, dX, "speed")["speed"][0]
        speed_ratio[travel] = 1.0 + dev[travel]
        first(travel & (np.abs(dev) > window.speed_tol + SPEED_TOL), "pin_speed",
              dev * 100, window.speed_tol * 100, "%")
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
    # The end stop: the tool stands at the seam end while the forces relax, and the pin does
    # not move sideways (the start standstill's limit), from the weld's last sample on.
    bad, val = _stop_motion(e, phase)
    first(bad, "stop_standstill", val, STANDSTILL_MOTION * 1e3, "mm")
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
    steady = s[phase == "weld"]
    return SampleVerification(not fails, contact, e, dist, R, tolerated, ratios, excess,
                              tuple(fails), derr, tilt_err, speed_ratio, height, claim,
                              (float(steady[0]), float(steady[-1])) if len(steady) else None,
                              dX)


def _time_per_length(task: PlanTask) -> float:
    """1 / weld speed [s/m] (0 without a travel speed): the pin speed's scale on time."""
    return 1.0 / task.travel_speed if task.travel_speed > 0 else 0.0


def _claim_terms(claim: RobustClaim | None, contact: NDArray[np.bool_]
                 ) -> tuple[FloatArray, float]:
    """The worst lateral change per unit uncertainty at the in-material samples [m] and the
    tolerated level (zeros and NaN without a claim: :func:`verify_samples` ``robust=False``)."""
    if claim is None:
        return np.zeros(len(contact)), float("nan")
    return np.where(contact, claim.lateral_per_unit, 0.0), claim.tolerated


def _stop_motion(e: FloatArray, phase: NDArray[np.str_]
                 ) -> tuple[NDArray[np.bool_], FloatArray]:
    """The end stop's sideways motion of the pin (:func:`verify_samples`): per sample, the
    lateral error's change from the weld's last sample through the stop [mm], and the sample
    to name (the largest) when the stop's spread exceeds
    :data:`~rfsw_plan.process.task.STANDSTILL_MOTION` (none without a stop)."""
    n = len(e)
    bad, val = np.zeros(n, dtype=bool), np.zeros(n)
    stop = np.flatnonzero(phase == "stop")
    if not len(stop):
        return bad, val
    rows = np.concatenate([stop[:1] - 1, stop]) if stop[0] > 0 else stop
    val[rows] = np.abs(e[rows] - e[rows[0]]) * 1e3
    bad[rows] = np.ptp(e[rows]) > STANDSTILL_MOTION + WINDOW_TOL
    return bad & (val >= np.max(val) - 1e-12), val


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
