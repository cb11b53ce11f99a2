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
* joint limits, joint steps between neighbours, kappa_f (seed 000 eq. 5) below its bound.

:func:`pin_track` evaluates the timed trajectory the same way at every sample.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.compliance import dexterity
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InfeasibleError
from rfsw_plan.process.task import PlanTask, offsets3
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.timing.trajectory import TimedTrajectory

FloatArray = NDArray[np.float64]

#: Tolerance of the commanded position [m] and tool-axis direction [rad].
POSE_TOL = 1e-5
AXIS_TOL = 1e-4
#: Tolerance of the predicted pin's along-track error [m].
ALONG_TOL = 1e-5


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
    worst = uncertainty * np.sum(np.abs(task.force_seam) * np.abs(proj), axis=1)
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
            ``singularity``).
        binding_margin: Its margin (negative = violated) [m for window/pose, rad for joints,
            1 for kappa].
        messages: One line per violated check.
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

    def raise_if_infeasible(self) -> None:
        """Raise :class:`InfeasibleError` naming the waypoint, margin and constraint."""
        if not self.feasible:
            raise InfeasibleError(self.messages[0], self.worst_waypoint, self.binding,
                                  self.binding_margin)


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
) -> Verification:
    """Re-evaluate a plan numerically and check every waypoint.

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
    """
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    pred = predict(model, task, Q, uncertainty, length_scale)
    fr = task.frames
    o = offsets3(offsets)
    cmd = task.target + o[:, :1] * fr.l + o[:, 1:2] * fr.n + o[:, 2:3] * fr.t
    pose_err = np.linalg.norm(pred.T[:, :3, 3] - cmd, axis=1)
    cosang = np.clip(-np.einsum("ki,ki->k", pred.T[:, :3, 2], fr.n), -1.0, 1.0)
    axis_err = np.arccos(cosang)
    e = pred.e_lat
    margin = np.minimum(e - window.lower, window.upper - e)
    rmargin = np.minimum(e - pred.worst - window.lower, window.upper - e - pred.worst)

    checks: list[tuple[str, FloatArray, str]] = [
        *([("robust_window", rmargin, "m")] if robust_hard else []),
        ("window", margin, "m"),
        ("pose", POSE_TOL - pose_err, "m"),
        ("along_track", ALONG_TOL - np.abs(pred.e_along), "m"),
        ("tool_axis", AXIS_TOL - axis_err, "rad"),
        ("singularity", kappa_max - pred.kappa, ""),
    ]
    d = model.robot.description
    for j in range(Q.shape[1]):
        # 1e-7 rad: IPOPT may touch a bound within its bound relaxation.
        checks.append((f"joint_limit_q{j + 1}", np.minimum(Q[:, j] - d.lower[j],
                                                          d.upper[j] - Q[:, j]) + 1e-7, "rad"))
    if joint_step is not None and len(Q) > 1:
        step = np.abs(np.diff(Q, axis=0))
        for j in range(Q.shape[1]):
            checks.append((f"joint_step_q{j + 1}",
                           np.append(joint_step - step[:, j], np.inf), "rad"))

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
    return Verification(not messages, pred, margin, rmargin, pose_err, pred.e_along, axis_err,
                        worst_k,
                        worst_name, worst_m, tuple(messages))


def _message(task: PlanTask, k: int, name: str, m: float, unit: str, e: FloatArray,
             pred: Prediction) -> str:
    where = f"waypoint {k} ({task.phase[k]}, s = {task.s[k] * 1e3:.2f} mm)"
    if name in ("window", "robust_window"):
        extra = f"; e_lat = {e[k] * 1e3:+.3f} mm, worst case +-{pred.worst[k] * 1e3:.3f} mm"
        return (f"plan infeasible at {where}: {name} violated by {-m * 1e3:.3f} mm{extra}")
    if name == "along_track":
        return (f"plan infeasible at {where}: the predicted pin is "
                f"{pred.e_along[k] * 1e3:+.4f} mm along the track from its seam point "
                f"(tolerance {ALONG_TOL * 1e3:g} mm)")
    if unit == "m":
        return f"plan infeasible at {where}: {name} off by {-m * 1e3:.4f} mm"
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
