"""Baselines the NLP is compared with, and the taught path that seeds it.

1. ``none``: the robot is taught to the seam (IK along the waypoints at a fixed tool rotation)
   and nothing is compensated.
2. ``mirror``: what an engineer does by hand. At every waypoint, shift the target by minus the
   predicted pin error in all three seam directions (lateral, normal and along the track: the
   pin then sits on the seam point whose force it feels), re-teach the point (IK on the same
   branch and tool rotation) and repeat until the shift stops changing: the fixed point
   o = -(e_lat, e_norm, e_along)(q(p + o_lat l + o_norm n + o_along t), F).

Both only use the numeric model (:func:`rfsw_plan.planning.verify.predict`, the process
deflection with the task's seam reference).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import UnreachableError
from rfsw_plan.planning.verify import (
    Prediction,
    RobustClaim,
    SampleVerification,
    evaluate_poses,
    predict,
    waypoint_claim,
)
from rfsw_plan.process.frames import tcp_orientation
from rfsw_plan.process.task import PlanTask, offsets3
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.robot.ik import solve_ik
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]


def commanded_poses(task: PlanTask, offsets: FloatArray, rotation: float) -> FloatArray:
    """Commanded TCP poses p + o_lat l + o_norm n + o_along t with the TCP z axis -n,
    (K, 4, 4); offsets (lateral, normal[, along-track]) [m], (K, 3) or (K, 2)."""
    R = tcp_orientation(task.frames, rotation)
    T = np.tile(np.eye(4), (len(task), 1, 1))
    T[:, :3, :3] = R
    o = offsets3(offsets)
    fr = task.frames
    T[:, :3, 3] = task.target + o[:, :1] * fr.l + o[:, 1:2] * fr.n + o[:, 2:3] * fr.t
    return T


def ik_path(
    robot: Robot, poses: FloatArray, q_seed: FloatArray, q_warm: FloatArray | None = None,
    tol: float = 1e-7, s: FloatArray | None = None,
) -> FloatArray:
    """Joint values along poses (K, 4, 4) by IK continuation from ``q_seed`` [rad], (K, n).

    ``s`` [m] (K,) is the arc length reported in the error message.

    Raises:
        UnreachableError: Names the first waypoint IK cannot reach and by how far.
    """
    K = len(poses)
    Q = np.zeros((K, robot.nq))
    q = np.asarray(q_seed, dtype=float)
    for k in range(K):
        seed = q if q_warm is None else q_warm[k]
        res = solve_ik(robot, poses[k], seed, tol_pos=tol, tol_rot=tol,
                       max_iter=400 if k == 0 else 100)
        if not res.converged:
            res2 = solve_ik(robot, poses[k], q, tol_pos=tol, tol_rot=tol, max_iter=400)
            res = res2 if res2.position_error + res2.rotation_error < \
                res.position_error + res.rotation_error else res
        if not res.converged:
            s_k = float(s[k]) * 1e3 if s is not None else _s(poses, k)
            raise UnreachableError(
                f"seam waypoint {k} (s = {s_k:.1f} mm) is unreachable: "
                f"the closest pose within the joint limits misses it by "
                f"{res.position_error * 1e3:.2f} mm and {np.rad2deg(res.rotation_error):.2f} deg"
            )
        q = res.q
        Q[k] = q
    return Q


def ik_paths(
    robot: Robot, poses: FloatArray, q_seeds: FloatArray, tol: float = 1e-7,
    s: FloatArray | None = None, max_jump: float = 0.5,
) -> list[FloatArray | UnreachableError]:
    """:func:`ik_path` for several starts at once: poses (S, K, 4, 4), seeds (S, n) [rad].

    The same damped least-squares iteration as :func:`~rfsw_plan.robot.ik.solve_ik` (step
    capped at 0.3 rad, joint limits clipped, same tolerance), batched:

    1. the first waypoint of every start from its seed;
    2. every other waypoint of every start from that start's first solution, all at once;
    3. a start whose path does not converge everywhere or jumps between neighbours by more
       than ``max_jump`` [rad] (it left the branch) is redone by continuation along the
       waypoints like :func:`ik_path` (each step batched over those starts).

    Returns:
        Per start the joint values (K, n), or the :class:`UnreachableError` naming the first
        waypoint it cannot reach.
    """
    S, K = poses.shape[:2]
    n = robot.nq
    seeds = np.array(q_seeds, dtype=float).reshape(S, n)
    q0, ok0, ep0, er0 = _batch_ik(robot, poses[:, 0], seeds, tol, 400)
    out = np.repeat(q0[:, None], K, axis=1)
    errors: dict[int, UnreachableError] = {}
    for i in np.flatnonzero(~ok0):
        errors[int(i)] = _unreachable(poses[i], s, 0, ep0[i], er0[i])
    good = np.flatnonzero(ok0)
    redo: list[int] = []
    if K > 1 and len(good):
        flat = poses[good, 1:].reshape(-1, 4, 4)
        qa, oka, _, _ = _batch_ik(robot, flat, np.repeat(q0[good], K - 1, axis=0), tol, 200)
        out[good, 1:] = qa.reshape(len(good), K - 1, n)
        oka = oka.reshape(len(good), K - 1)
        for j, g in enumerate(good):
            jump = float(np.max(np.abs(np.diff(out[g], axis=0))))
            if not np.all(oka[j]) or jump > max_jump:
                redo.append(int(g))
    if redo:  # continuation, batched over the starts that need it
        act = np.array(redo)
        alive = np.ones(len(act), dtype=bool)
        for k in range(1, K):
            live = act[alive]
            if not len(live):
                break
            qk, okk, ep, er = _batch_ik(robot, poses[live, k], out[live, k - 1], tol, 400)
            out[live, k] = qk
            for jj in np.flatnonzero(~okk):
                errors[int(live[jj])] = _unreachable(poses[live[jj]], s, k, ep[jj], er[jj])
            alive[np.flatnonzero(alive)[~okk]] = False
    return [errors.get(i, out[i]) for i in range(S)]


def _unreachable(poses: FloatArray, s: FloatArray | None, k: int, ep: float, er: float
                 ) -> UnreachableError:
    s_k = float(s[k]) * 1e3 if s is not None else _s(poses, k)
    return UnreachableError(
        f"seam waypoint {k} (s = {s_k:.1f} mm) is unreachable: "
        f"the closest pose within the joint limits misses it by "
        f"{ep * 1e3:.2f} mm and {np.rad2deg(er):.2f} deg")


#: Change of a pose's position plus rotation error [m + rad] in one damped least-squares
#: step below which :func:`_batch_ik` stops it as stuck (zk500_table6_seam's two shoulder
#: branches, which cannot reach the seam's first pose, stop after 225 and 64 of their 400
#: steps; the miss they report changes by less than 1e-9 m and rad, tests/test_baselines.py).
IK_STALL = 1e-12


def _batch_ik(robot: Robot, poses: FloatArray, Q: FloatArray, tol: float, max_iter: int,
              damping: float = 1e-6) -> tuple[FloatArray, NDArray[np.bool_], FloatArray,
                                              FloatArray]:
    """Damped least-squares IK of poses (m, 4, 4) from Q (m, n), as
    :func:`~rfsw_plan.robot.ik.solve_ik`, all at once. Returns q, converged, position and
    rotation errors [m, rad].

    A pose whose errors no longer change (by :data:`IK_STALL` [m + rad] in one step: the
    iteration is stuck against the joint limits, a branch that cannot reach it) stops
    there, unconverged, with the errors it reached."""
    lo, hi = robot.description.lower, robot.description.upper
    q = np.array(Q, dtype=float)
    m = len(q)
    run = np.ones(m, dtype=bool)
    converged = np.zeros(m, dtype=bool)
    ep = np.full(m, np.inf)
    er = np.full(m, np.inf)
    eye = damping * np.eye(6)
    for _ in range(max_iter):
        idx = np.flatnonzero(run)
        T, J = robot.batch_fk_jacobian(q[idx])[:2]
        target = poses[idx]
        e_p = target[:, :3, 3] - T[:, :3, 3]
        e_r = _rotation_log(target[:, :3, :3] @ np.transpose(T[:, :3, :3], (0, 2, 1)))
        ep_new, er_new = np.linalg.norm(e_p, axis=1), np.linalg.norm(e_r, axis=1)
        stalled = np.abs(ep_new - ep[idx]) + np.abs(er_new - er[idx]) < IK_STALL
        ep[idx], er[idx] = ep_new, er_new
        done = (ep_new < tol) & (er_new < tol)
        converged[idx[done]] = True
        done |= stalled
        run[idx[done]] = False
        if not np.any(run):
            break
        keep = ~done
        Jk = J[keep]
        b = np.hstack([e_p, e_r])[keep][:, :, None]
        dq = (np.transpose(Jk, (0, 2, 1))
              @ np.linalg.solve(Jk @ np.transpose(Jk, (0, 2, 1)) + eye, b))[:, :, 0]
        step = np.max(np.abs(dq), axis=1)
        dq *= np.minimum(1.0, 0.3 / np.maximum(step, 1e-300))[:, None]
        moving = idx[keep]
        q[moving] = np.clip(q[moving] + dq, lo, hi)
    return q, converged, ep, er


def _rotation_log(R: FloatArray) -> FloatArray:
    """Rotation vectors of rotation matrices (m, 3, 3), shape (m, 3) [rad].

    From the skew part (theta / sin theta (R - R^T)^v / 2) where the angle is below 2.5 rad;
    SciPy's quaternion route for larger angles, where the skew part loses precision."""
    v = 0.5 * np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0],
                        R[:, 1, 0] - R[:, 0, 1]], axis=1)
    sin = np.linalg.norm(v, axis=1)
    cos = 0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0)
    theta = np.arctan2(sin, cos)
    small = sin < 1e-12
    scale = np.where(small, 1.0, theta / np.where(small, 1.0, sin))
    out = v * scale[:, None]
    big = theta > 2.5
    if np.any(big):
        from scipy.spatial.transform import Rotation

        out[big] = Rotation.from_matrix(R[big]).as_rotvec()
    return np.asarray(out)


def refine_path(
    robot: Robot, poses: FloatArray, q_near: FloatArray, tol: float = 1e-7,
    s: FloatArray | None = None, max_iter: int = 8,
) -> FloatArray:
    """Joint values at poses (K, 4, 4) near a nearby path q_near (K, n) [rad]: Newton steps
    dq = J^-1 (dp, log(R_target R^T)) on all waypoints at once (6-joint arms; J the base-frame
    TCP Jacobian), the same tolerance as :func:`ik_path`, which is the fallback (other arms,
    a step that does not converge or leaves the joint limits).

    Raises:
        UnreachableError: As :func:`ik_path`.
    """
    Q = np.array(q_near, dtype=float)
    lo, hi = robot.description.lower, robot.description.upper
    if robot.nq == 6:
        for _ in range(max_iter):
            T, J = robot.batch_fk_jacobian(Q)[:2]
            err = np.hstack([poses[:, :3, 3] - T[:, :3, 3],
                             _rotation_log(poses[:, :3, :3] @ np.transpose(T[:, :3, :3],
                                                                          (0, 2, 1)))])
            if (np.max(np.linalg.norm(err[:, :3], axis=1)) < tol
                    and np.max(np.linalg.norm(err[:, 3:], axis=1)) < tol):
                if np.all((Q - lo >= 0) & (hi - Q >= 0)):
                    return Q
                break
            try:
                dq = np.linalg.solve(J, err[:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                break
            if not np.all(np.isfinite(dq)) or np.max(np.abs(dq)) > 0.1:
                break  # not a small correction: leave it to the damped IK
            Q = Q + dq
    return ik_path(robot, poses, q_near[0], q_warm=q_near, tol=tol, s=s)


def _s(poses: FloatArray, k: int) -> float:
    p = poses[: k + 1, :3, 3]
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)) * 1e3) if k else 0.0


def branch_seeds(robot: Robot, q_seed: FloatArray) -> list[tuple[str, FloatArray]]:
    """Seeds for the configuration branches of a 6R arm with a spherical wrist [rad].

    The seed itself, the wrist flip (q4 + pi, -q5, q6 + pi), an elbow flip (q3 mirrored about
    the stretched arm, q2 compensating), and combinations; then the two shoulder flips of
    :func:`shoulder_flip_seeds` (the arm reaching over its head to the same TCP, each elbow).
    Every seed is within the joint limits (whole turns, then clipped). IK from each seed
    decides where it really lands; duplicates are removed by the caller.
    """
    q = np.asarray(q_seed, dtype=float)
    out = [("seed", q.copy())]
    if robot.nq != 6:
        return out
    wrist = q + np.array([0, 0, 0, np.pi, -2 * q[4], np.pi])
    elbow = q + np.array([0, q[2] * 0.8, -2 * q[2] - 0.3, 0, 0, 0])
    out += [("wrist_flip", _into_limits(robot, wrist)), ("elbow_flip", _into_limits(robot, elbow)),
            ("elbow_wrist_flip", _into_limits(robot, elbow + (wrist - q)))]
    return out + shoulder_flip_seeds(robot, q)


def _into_limits(robot: Robot, x: FloatArray) -> FloatArray:
    """x [rad] shifted by whole turns into the joint limits where it fits, then clipped (a seed
    outside the limits that already solves the pose would be returned by the IK as is)."""
    lo, hi = robot.description.lower, robot.description.upper
    y = np.array(x, dtype=float)
    turn = 2 * np.pi
    y = np.where(y > hi, y - turn * np.ceil((y - hi) / turn), y)
    y = np.where(y < lo, y + turn * np.ceil((lo - y) / turn), y)
    return np.clip(y, lo, hi)


def _signed_angle(a: FloatArray, b: FloatArray, axis: FloatArray) -> float:
    """Angle [rad] that turns a onto b about the unit axis (both projected on its plane)."""
    a = a - axis * (a @ axis)
    b = b - axis * (b @ axis)
    return float(np.arctan2(axis @ np.cross(a, b), a @ b))


def _arm_geometry(robot: Robot, theta: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Joint axes (6, 3) and joint origins (6, 3) in the base frame [m], and the wrist centre
    (3,) (joint 5's origin), at chain angles theta (6,) [rad]. Axes by a finite rotation of
    each joint, so any description (modified DH or URDF) works."""
    Gi = np.linalg.inv(robot.coupling)
    F = robot.joint_frames(Gi @ theta)
    axes = np.zeros((6, 3))
    eps = 1e-3
    for j in range(6):
        Fj = robot.joint_frames(Gi @ (theta + eps * np.eye(6)[j]))[j]
        R = Fj[:3, :3] @ F[j][:3, :3].T
        w = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
        axes[j] = w / np.linalg.norm(w)
    return axes, F[:, :3, 3], F[4][:3, 3]


def shoulder_flip_seeds(robot: Robot, q: FloatArray, iters: int = 40
                        ) -> list[tuple[str, FloatArray]]:
    """Seeds on the flipped shoulder (q1 + pi) that put the TCP where ``q`` puts it [rad].

    In the chain angles theta = G q (so FANUC's coupled J2/J3 and KUKA's A2 = theta - 90 deg
    need no case of their own): theta1 + pi, and the upper arm mirrored about axis 1,
    theta2 -> 2 theta2_v - theta2 with theta2_v the angle that makes the upper arm (joint 2 ->
    joint 3) parallel to axis 1 (on the KUKA KR600 controller values A2 -> -180 deg - A2, not
    -A2). Two elbow starts: the forearm mirrored about the stretched arm (theta3 -> 2 theta3_s
    - theta3, the arm's mirror image) and theta3 kept. From each, Gauss-Newton on theta2,
    theta3 puts the wrist centre back where it was (a shoulder offset a1 makes the mirror
    image miss it by 2 a1), then on q4..q6 the tool orientation. Measured on 80 random
    reachable poses per robot (report of the cleanup session): these two seeds found the
    flipped shoulder wherever a 100-seed multi-start did (KR600 5/5, S-900iB 16/16, ZK-500
    30/30); the former seed q + (pi, -2 q2, 0, 0, 0, 0) found 1/5, 3/16 and 14/30.

    Returns:
        ``[("shoulder_flip", ...), ("shoulder_elbow_flip", ...)]``, each (6,) inside the
        joint limits.
    """
    q = np.asarray(q, dtype=float)
    G = robot.coupling
    Gi = np.linalg.inv(G)
    theta = G @ q
    target = robot.fk(q)
    wc = robot.joint_frames(q)[4][:3, 3]
    ref_axes, ref_origin, ref_wc = _arm_geometry(robot, np.zeros(6))
    upper = ref_origin[2] - ref_origin[1]
    theta2_v = _signed_angle(upper, ref_axes[0], ref_axes[1])
    theta3_s = _signed_angle(ref_wc - ref_origin[2], upper, ref_axes[2])
    out: list[tuple[str, FloatArray]] = []
    for name, mirror_elbow in (("shoulder_flip", True), ("shoulder_elbow_flip", False)):
        t = theta.copy()
        t[0] += np.pi
        t[1] = 2 * theta2_v - theta[1]
        if mirror_elbow:
            t[2] = 2 * theta3_s - theta[2]
        for _ in range(iters):  # wrist centre: theta2, theta3
            ax, org, w = _arm_geometry(robot, t)
            e = wc - w
            if np.linalg.norm(e) < 1e-9:
                break
            J = np.column_stack([np.cross(ax[j], w - org[j]) for j in (1, 2)])
            d = np.linalg.lstsq(J, e, rcond=None)[0]
            t[1:3] += d * min(1.0, 0.3 / max(float(np.max(np.abs(d))), 1e-300))
        qs = Gi @ t
        for _ in range(iters):  # tool orientation: q4..q6
            T, Jq = robot.fk_jacobian(qs)
            e = _rotation_log((target[:3, :3] @ T[:3, :3].T)[None])[0]
            if np.linalg.norm(e) < 1e-10:
                break
            d = np.linalg.lstsq(Jq[3:, 3:], e, rcond=None)[0]
            qs[3:] += d * min(1.0, 0.3 / max(float(np.max(np.abs(d))), 1e-300))
        out.append((name, _into_limits(robot, qs)))
    return out


@dataclass(frozen=True)
class BaselineMetrics:
    """Figures of one strategy on the same problem: every in-material waypoint (plunge, dwell
    and weld), and for the plan also every written in-material sample, so the table, the
    verdict, ``plan.json`` and the plots all quote these numbers.

    Attributes:
        name: ``none``, ``mirror`` or ``nlp``.
        max_abs_lateral: max |e_lat| [m].
        rms_lateral: RMS of e_lat over the waypoints [m].
        worst_case: max of the worst-case |e_lat| under the requested force uncertainty
            (the farthest point of e +- r from 0) [m].
        min_lateral_stiffness: min over waypoints of 1 / (l^T C_tt l) [N/m].
        inside_fraction: Fraction of weld waypoints with e_lat inside the window.
        robust_margin: min distance of the worst case e +- r to the nearest window bound [m]
            (negative: the worst case leaves the window by that much). Unlike ``worst_case``
            it accounts for the asymmetric window.
        tolerated: The largest uniform relative force uncertainty u for which every weld
            quantity (lateral error, depth, work and travel angle, pin speed) holds at every
            vertex of the force box at every point (:func:`~rfsw_plan.planning.verify.
            robust_claim`; inf if no uncertain force moves any, 0 if one fails nominally).
        samples: The figures include the written samples (the plan, and a baseline that was
            written to be compared with it).
        claim: The tolerated level per quantity behind ``tolerated``.
        unwritten: Why this baseline cannot be written ('' if it can, or was not tried): the
            first check its verified, timed and sampled path fails, as the plan's would be
            refused. Its ``tolerated`` is then 0: what cannot run holds no force uncertainty,
            whatever its waypoints alone hold (``claim``, the waypoints' levels).
    """

    name: str
    max_abs_lateral: float
    rms_lateral: float
    worst_case: float
    min_lateral_stiffness: float
    inside_fraction: float
    robust_margin: float = float("nan")
    tolerated: float = float("nan")
    samples: bool = False
    claim: RobustClaim | None = None
    unwritten: str = ""

    def to_dict(self) -> dict[str, float | str | bool | dict[str, float] | None]:
        """File units: mm, N/mm and percent (the tolerated force uncertainty)."""
        return {
            "strategy": self.name,
            "max_abs_lateral_mm": self.max_abs_lateral * 1e3,
            "rms_lateral_mm": self.rms_lateral * 1e3,
            "worst_case_lateral_mm": self.worst_case * 1e3,
            "min_lateral_stiffness_N_mm": self.min_lateral_stiffness * 1e-3,
            "inside_window_fraction": self.inside_fraction,
            "worst_case_window_margin_mm": self.robust_margin * 1e3,
            "tolerated_force_uncertainty_pct": self.tolerated * 100,
            "tolerated_force_uncertainty_by_quantity_pct":
                None if self.claim is None or self.unwritten else {
                    q: u * 100 for q, u in self.claim.levels.items()},
            "includes_written_samples": self.samples,
            **({} if not self.unwritten else {
                "cannot_be_written": self.unwritten,
                "tolerated_at_waypoints_pct":
                    None if self.claim is None else self.claim.tolerated * 100}),
        }


def metrics(
    name: str, model: ElastostaticModel, task: PlanTask, q: FloatArray, window: WeldWindow,
    uncertainty: float, samples: SampleVerification | None = None,
    constant_speed: tuple[float, float] | None = None,
) -> BaselineMetrics:
    """:func:`metrics_and_prediction` without the prediction."""
    return metrics_and_prediction(name, model, task, q, window, uncertainty, samples,
                                  constant_speed)[0]


def metrics_and_prediction(
    name: str, model: ElastostaticModel, task: PlanTask, q: FloatArray, window: WeldWindow,
    uncertainty: float, samples: SampleVerification | None = None,
    constant_speed: tuple[float, float] | None = None,
) -> tuple[BaselineMetrics, Prediction]:
    """Metrics of joint values q (K, n) [rad] at the task's waypoints (all in the material),
    and with ``samples`` (the plan's :func:`~rfsw_plan.planning.verify.verify_samples`) at
    every written in-material sample too.

    At each point e is the lateral pin error and R the worst case per unit force uncertainty,
    R = sum_i |f_i| |l^T C_tt b_i| (seed 000 eq. 11); the worst case at the requested u is
    e +- u R. The tolerated uncertainty is the whole envelope's
    (:func:`~rfsw_plan.planning.verify.robust_claim` at the waypoints, and at the samples),
    the pin speed judged within ``constant_speed`` (first, last arc length [m] of the
    constant-speed weld samples; by default the samples' own).

    Returns the metrics and the numeric prediction of q at unit force uncertainty
    (:func:`~rfsw_plan.planning.verify.predict`; its pin errors are those of any
    uncertainty). The prediction's poses and deflection are the claim's too (one model call
    and one set of pose caches for both; inside a
    :func:`~rfsw_plan.planning.verify.shared_evaluations` scope, those of q's earlier
    evaluation).
    """
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    batch, dX = evaluate_poses(model, Q, task.wrench_base, task.reference)
    pred = predict(model, task, Q, 1.0, batch=batch, deflection=dX)
    e, R = pred.e_lat, pred.worst
    if samples is not None and samples.contact.any():
        c = samples.contact
        e_all, R_all = np.concatenate([e, samples.e_lat[c]]), np.concatenate(
            [R, samples.worst_per_unit[c]])
    else:
        e_all, R_all = e, R
    r = uncertainty * R_all
    worst = np.maximum(np.abs(e_all + r), np.abs(e_all - r))
    sl = task.weld
    inside = (e[sl] >= window.lower) & (e[sl] <= window.upper)
    robust = np.minimum(e_all - r - window.lower, window.upper - (e_all + r))
    if samples is not None and constant_speed is None:
        constant_speed = samples.constant_speed
    claim = waypoint_claim(model, task, window, q, constant_speed, (batch, pred.dX))
    if samples is not None and samples.claim is not None:
        claim = samples.claim.combined(claim)
    return BaselineMetrics(name, float(np.max(np.abs(e_all))), float(np.sqrt(np.mean(e ** 2))),
                           float(np.max(worst)), float(np.min(pred.lateral_stiffness)),
                           float(np.mean(inside)), float(np.min(robust)), claim.tolerated,
                           samples is not None, claim), pred


@dataclass(frozen=True)
class BaselinePlan:
    """Joint values and offsets of a baseline.

    Attributes:
        name: ``none`` or ``mirror``.
        q: Joint values [rad], (K, n).
        offsets: Offsets (lateral, normal, along-track) [m], (K, 3).
        iterations: Fixed-point iterations (mirror).
        converged: The fixed point converged (mirror).
    """

    name: str
    q: FloatArray
    offsets: FloatArray
    iterations: int = 0
    converged: bool = True


def no_compensation(robot: Robot, task: PlanTask, q_seed: FloatArray,
                    rotation: float = 0.0, q_near: FloatArray | None = None) -> BaselinePlan:
    """Baseline 1: taught to the seam, no offsets.

    With ``q_near`` (K, n) [rad], a nearby path on the wanted branch (e.g. a coarse taught
    path interpolated), the path is found by batched Newton steps from it
    (:func:`refine_path`), else by batched IK from ``q_seed`` (:func:`ik_paths`)."""
    off = np.zeros((len(task), 3))
    poses = commanded_poses(task, off, rotation)
    if q_near is not None:
        return BaselinePlan("none", refine_path(robot, poses, q_near, s=task.s), off)
    (q,) = ik_paths(robot, poses[None], np.asarray(q_seed, dtype=float)[None], s=task.s)
    if isinstance(q, UnreachableError):
        raise q
    return BaselinePlan("none", q, off)


def mirror_compensation(
    model: ElastostaticModel, task: PlanTask, q_taught: FloatArray, rotation: float = 0.0,
    max_iter: int = 20, tol: float = 1e-7,
) -> BaselinePlan:
    """Baseline 2: per-waypoint fixed-point 'mirror' fake targets at the taught configuration.

    o^{j+1} = o^j - (e_lat, e_norm, e_along)(q^j), q^j = IK(p + o^j) on the taught branch and
    tool rotation, until the change is below tol [m].
    """
    robot = model.robot
    off = np.zeros((len(task), 3))
    q = np.asarray(q_taught, dtype=float)
    converged = False
    it = 0
    while it < max_iter:
        it += 1
        pred = predict(model, task, q, 0.0)
        err = np.column_stack([pred.e_lat, pred.e_norm, pred.e_along])
        step = -err
        off = off + step
        q = refine_path(robot, commanded_poses(task, off, rotation), q, s=task.s)
        if np.max(np.abs(step)) < tol:
            converged = True
            break
    return BaselinePlan("mirror", q, off, it, converged)
