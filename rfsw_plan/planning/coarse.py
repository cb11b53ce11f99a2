"""Coarse-to-fine solve: the NLP on a few waypoints, then every waypoint exactly.

The planning NLP (:mod:`rfsw_plan.planning.nlp`) couples neighbouring waypoints only through
the joint-step and offset-rate rows and the smoothing terms, and its optimum varies smoothly
along the seam. So it is solved on the stationary waypoints plus ``coarse_waypoints`` evenly
spread weld waypoints (:func:`subsample_task`), and the fine plan is obtained per waypoint:

1. the coarse solution's departure from the mirror baseline (joint values, lateral and normal
   offsets, tool rotation) is interpolated linearly in arc length and added to the fine mirror
   baseline (the mirror follows the force ramps exactly, so only the smooth part is
   interpolated);
2. **exact projection onto the fine NLP's equality rows**: batched Newton IK puts the TCP
   exactly on the commanded pose p + o_lat l + o_norm n + o_along t with the tool axis -n at
   the interpolated tool rotation (position and axis rows), and the along-track offset is
   iterated until the along-track row holds (o_along enters that row with slope one; the
   deflection's dependence on q makes it a contraction); the outer correction for effects the
   symbolic model lacks is iterated to ``outer_tol`` as in the full solve;
3. **check of every row of the fine NLP** at the NLP's own tolerance: every row family
   declared in :mod:`rfsw_plan.planning.rows` (window, robust rows with the tightest sigma,
   singularity, stiffness cap with the tightest c_max, joint steps, offset rate and speed...,
   by their declared bounds) and the joint limits. If any row fails, the caller solves the
   full NLP.

The offsets are interpolated inside the fine NLP's own per-link allowance (the tightest of the
link rows declared on the offsets, :attr:`~rfsw_plan.planning.nlp.LinkBounds.allowance`), not
a single rate: a new bound on the offsets' change is kept by the interpolation as soon as it is
declared.

No row or tolerance of the fine problem is relaxed: the result is a feasible point of the
fine NLP whose objective is within a small gap of its optimum (the benchmark prints the gap).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.planning.layout import OFFSETS
from rfsw_plan.planning.nlp import PlanNLP, terms_prediction, update_parameters
from rfsw_plan.planning.verify import predict
from rfsw_plan.process.frames import tcp_orientation
from rfsw_plan.process.task import FloatArray, PlanTask

IntArray = NDArray[np.int_]

log = logging.getLogger(__name__)

#: Tolerance of the fine NLP's rows [NLP units: mm, rad, 1], IPOPT's ``constr_viol_tol``.
ROW_TOL = 1e-7
#: The along-track column of a (K, 3) offset array (lateral, normal, along-track).
ALONG = OFFSETS["along"]
NORMAL = OFFSETS["normal"]


def subsample_task(task: PlanTask, max_weld: int = 60) -> tuple[PlanTask, IntArray]:
    """The stationary waypoints and about ``max_weld`` evenly spread weld waypoints (first and
    last included), and their indices; the task itself if it is that small."""
    m, K = task.n_start, len(task)
    if K - m <= max_weld:
        return task, np.arange(K)
    weld = np.unique(np.round(np.linspace(m, K - 1, max_weld)).astype(int))
    idx = np.concatenate([np.arange(m), weld])
    fr = task.frames
    frames = type(fr)(*(getattr(fr, a)[idx] for a in ("s", "p", "t", "l", "n")))
    sub = PlanTask(frames, task.target[idx], task.force_seam[idx], task.moment_base[idx],
                   task.phase[idx], task.time[idx], task.depth[idx], m, task.travel_speed,
                   task.reference, task.axial_control, task.penetration_stiffness,
                   task.stop_time, task.stop_force_seam)
    return sub, idx


@dataclass(frozen=True)
class FineProjection:
    """A fine plan projected from a coarse one.

    Attributes:
        x: The fine NLP's variable vector.
        q: Joint values [rad], (K, n).
        offsets: Offsets (lateral, normal, along-track) [m], (K, 3).
        correction: Outer correction of the fine NLP [m], (K, 3).
        nlp: The fine NLP with that correction.
        violations: Rows of the fine NLP violated beyond :data:`ROW_TOL` (name, amount);
            empty if the projection is a feasible point.
        objective: The fine NLP's objective at x.
        iterations: Newton/fixed-point iterations.
    """

    x: FloatArray
    q: FloatArray
    offsets: FloatArray
    correction: FloatArray
    nlp: PlanNLP
    violations: tuple[tuple[str, float], ...]
    objective: float
    iterations: int

    @property
    def feasible(self) -> bool:
        """Every row of the fine NLP holds."""
        return not self.violations


def interpolate_coarse(task: PlanTask, idx: IntArray, values: FloatArray) -> FloatArray:
    """Values (len(idx), m) at the coarse waypoints, linearly in arc length to all (K, m).

    Stationary waypoints are all coarse waypoints (taken as they are); weld waypoints are
    interpolated between the coarse weld waypoints by arc length."""
    m, K = task.n_start, len(task)
    out = np.empty((K, values.shape[1]))
    out[:m] = values[:m]
    s_c = task.s[idx[m:]]
    for j in range(values.shape[1]):
        out[m:, j] = np.interp(task.s[m:], s_c, values[m:, j])
    return out


def interpolate_offsets(task: PlanTask, idx: IntArray, o_coarse: FloatArray,
                        o_mirror: FloatArray, allowance: FloatArray) -> FloatArray:
    """Fine offsets (K, 3) [m] from coarse ones (M, 3) that keep the fine link rows on the
    offsets, |o_{k+1} - o_k| <= |m_{k+1} - m_k| + b_k (m the mirror offsets, b_k the fine
    NLP's per-link allowance [m], (K - 1, 3) or (K - 1,):
    :attr:`~rfsw_plan.planning.nlp.LinkBounds.allowance` of ``offsets``).

    On a coarse link a -> b, with B_k = sum_{a <= j < k} b_j the allowance accumulated from a
    and S = B_b, the fine offsets are o_k = o_a + lambda (m_k - m_a) + mu B_k. Each fine link
    then changes by lambda dm_k + mu b_k, within the fine row's |dm_k| + b_k when
    |lambda|, |mu| <= 1; and the pair exists whenever |o_b - o_a| <= |m_b - m_a| + S holds
    (the coarse row, for an allowance proportional to travel: offset_rate x travel).
    lambda = 1 (mu = departure from the mirror over the link / S) interpolates the departure
    from the mirror in proportion to the allowance (in arc length, for a rate per travel); only
    where that departure changes faster, mu = +-1 and lambda takes the rest. (Stationary
    waypoints are all coarse waypoints.)"""
    m, K = task.n_start, len(task)
    out = np.empty((K, o_coarse.shape[1]))
    out[:m] = o_coarse[:m]
    b_k = np.broadcast_to(np.asarray(allowance, dtype=float).reshape(K - 1, -1),
                          (K - 1, o_coarse.shape[1]))
    B = np.vstack([np.zeros((1, b_k.shape[1])), np.cumsum(b_k, axis=0)])
    for a, b in zip(idx[m - 1 if m else 0:-1], idx[m if m else 1:], strict=True):
        k = np.arange(a, b + 1)
        Bk = B[k] - B[a]
        S = Bk[-1]
        dm = o_mirror[b] - o_mirror[a]
        do = o_coarse[np.searchsorted(idx, b)] - o_coarse[np.searchsorted(idx, a)]
        dd = do - dm
        S_safe = np.maximum(S, 1e-300)
        safe = np.where(np.abs(dm) > 1e-300, dm, 1.0)
        # Within the rows' own slack (1e-6 mm) and IPOPT's tolerance, lambda = 1.
        linear = np.abs(dd) <= S + 2e-9
        mu = np.where(linear, dd / S_safe, np.clip(dd / S_safe, -1.0, 1.0))
        lam = np.where(linear, 1.0, (do - mu * S) / safe)
        out[k] = (o_coarse[np.searchsorted(idx, a)] + lam * (o_mirror[k] - o_mirror[a])
                  + mu * Bk)
    return out


def _tool_rotation(task: PlanTask, T: FloatArray) -> FloatArray:
    """Rotation of the TCP x axis about the tool axis relative to rotation 0 [rad], (K,)."""
    R0 = tcp_orientation(task.frames, 0.0)
    x = T[:, :3, 0]
    return np.unwrap(np.arctan2(np.einsum("ki,ki->k", x, R0[:, :, 1]),
                                np.einsum("ki,ki->k", x, R0[:, :, 0])))


#: The last evaluation of :func:`_newton_ik`: (joint values it returned, the orientations R,
#: their TCP poses, Jacobians and rotation errors to R).
NewtonState = tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]


def _newton_ik(model: ElastostaticModel, target: FloatArray, R: FloatArray, Q: FloatArray,
               tol: float = 1e-12, max_iter: int = 12, last: NewtonState | None = None,
               ) -> tuple[FloatArray, bool, NewtonState | None]:
    """Joint values (K, n) with the TCP at positions target (K, 3) [m] and orientations R
    (K, 3, 3), by batched Newton steps from Q; True if every waypoint converged to tol [m, rad]
    (6-joint arms), and the evaluation of the joint values returned.

    ``last``: the evaluation an earlier call returned; when Q holds its joint values (the same
    bytes) and R is its orientations (:func:`project_fine` moves only the targets between
    calls), its poses, Jacobians and rotation errors are taken instead of evaluated again."""
    from scipy.spatial.transform import Rotation

    robot = model.robot
    Q = np.array(Q, dtype=float)
    reuse = last is not None and last[1] is R and last[0].tobytes() == Q.tobytes()
    state: NewtonState | None = None
    for _ in range(max_iter):
        if reuse and last is not None:
            T, J, dr = last[2:]
            reuse = False
        else:
            T, J = robot.batch_fk_jacobian(Q)[:2]
            dr = Rotation.from_matrix(R @ np.transpose(T[:, :3, :3], (0, 2, 1))).as_rotvec()
        dp = target - T[:, :3, 3]
        state = (Q.copy(), R, T, J, dr)
        if max(float(np.max(np.abs(dp))), float(np.max(np.abs(dr)))) < tol:
            return Q, True, state
        try:
            dq = np.linalg.solve(J, np.hstack([dp, dr])[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            return Q, False, state
        if not np.all(np.isfinite(dq)) or np.max(np.abs(dq)) > 0.2:
            return Q, False, state
        Q = Q + dq
    return Q, False, None


def project_fine(
    model: ElastostaticModel, nlp: PlanNLP, idx: IntArray, q_coarse: FloatArray,
    offsets_coarse: FloatArray, q_mirror: FloatArray, offsets_mirror: FloatArray,
    correction_coarse: FloatArray, max_iter: int = 30,
) -> FineProjection:
    """The fine plan from a coarse NLP solution (see the module docstring).

    Args:
        model: The elastostatic model (numeric model for the outer correction).
        nlp: The fine NLP (built on the whole task, mirror warm start).
        idx: Fine indices of the coarse waypoints, (M,).
        q_coarse, offsets_coarse: Coarse solution [rad] (M, n), [m] (M, 3).
        q_mirror, offsets_mirror: Fine mirror baseline [rad] (K, n), [m] (K, 3).
        correction_coarse: The coarse NLP's outer correction [m] (M, 3).
        max_iter: Cap on the projection iterations.
    """
    task = nlp.task
    robot = model.robot
    fr = task.frames
    q = q_mirror + interpolate_coarse(task, idx, q_coarse - q_mirror[idx])
    off = interpolate_offsets(task, idx, offsets_coarse, offsets_mirror,
                              nlp.links.allowance["offsets"])
    # Tool rotation: the coarse plan's departure from the mirror's, interpolated.
    mirror_rot = _tool_rotation(task, robot.batch_fk_jacobian(q_mirror)[0])
    coarse_rot = _tool_rotation_sub(task, idx, robot.batch_fk_jacobian(q_coarse)[0])
    d_rot = (coarse_rot - mirror_rot[idx] + np.pi) % (2 * np.pi) - np.pi
    rot = mirror_rot + interpolate_coarse(task, idx, d_rot[:, None])[:, 0]
    R = tcp_orientation(fr, rot)
    corr = interpolate_coarse(task, idx, correction_coarse)
    fine = update_parameters(nlp, correction=corr)
    ok = robot.nq == 6
    it = 0
    last: NewtonState | None = None
    while ok and it < max_iter:
        it += 1
        o = OFFSETS.split(off)
        target = task.target + o["lateral"] * fr.l + o["normal"] * fr.n + o["along"] * fr.t
        q, ok, last = _newton_ik(model, target, R, q, last=last)
        if not ok:
            break
        # sigma, rho and c_max do not enter the rows used here
        x = fine.stack({"q": q, "offsets": off * 1e3, "sigma": 0.0, "tolerated": 0.0})
        rows, terms = fine.point_rows(x)
        along = rows["along_track"]  # [mm], (K, 1)
        if float(np.max(np.abs(along))) > ROW_TOL * 1e-2:
            off[:, ALONG] -= along * 1e-3
            continue
        # The depth row binds in the dwell (the pin held at its shallow bound); the fine
        # correction differs from the coarse one within outer_tol, so the normal offset takes
        # up what the interpolated plan leaves beyond the bound (1:1 to first order).
        excess = _depth_excess(fine, rows["depth"][:, 0])
        if float(np.max(np.abs(excess))) > ROW_TOL * 1e-2:
            off[:, NORMAL] -= excess[:, None] * 1e-3
            continue
        pred = predict(model, task, q, 0.0)
        full = np.column_stack([pred.e_lat, pred.e_norm, pred.e_along])
        new_corr = full - terms_prediction(fine, terms)
        if float(np.max(np.abs(new_corr - corr))) < nlp.options.outer_tol:
            break
        corr = new_corr
        fine = update_parameters(fine, correction=corr)
    x = fine.pack(q, off)
    if not ok or it >= max_iter:
        viol: tuple[tuple[str, float], ...] = (("projection", float("inf")),)
    else:
        viol = tuple(fine.violations(x, ROW_TOL))
        lo, hi = robot.description.lower, robot.description.upper
        bad = np.flatnonzero(np.any((q < lo) | (q > hi), axis=1))
        viol += tuple((f"joint_limit[{k}]", 0.0) for k in bad[:5])
    f, _ = fine.evaluate(x)
    log.info("fine projection: %d iterations, %d rows violated", it, len(viol))
    return FineProjection(x, q, off, corr, fine, viol, f, it)


def _depth_excess(nlp: PlanNLP, depth: FloatArray) -> FloatArray:
    """How far each waypoint's depth row is beyond its bounds, pushed 1e-6 mm inside [mm],
    (K,) (positive above the upper bound, negative below the lower, 0 inside)."""
    from rfsw_plan.planning.rows import point_labels

    K = len(nlp.task)
    labels = point_labels()
    col = labels.index("depth")
    lo = nlp.lbg[:K * len(labels)].reshape(K, len(labels))[:, col]
    hi = nlp.ubg[:K * len(labels)].reshape(K, len(labels))[:, col]
    inside = 1e-6
    return np.asarray(np.where(depth > hi, depth - hi + inside,
                               np.where(depth < lo, depth - lo - inside, 0.0)))


def _tool_rotation_sub(task: PlanTask, idx: IntArray, T: FloatArray) -> FloatArray:
    """:func:`_tool_rotation` of poses T (M, 4, 4) at the coarse waypoints idx."""
    R0 = tcp_orientation(task.frames, 0.0)[idx]
    x = T[:, :3, 0]
    return np.unwrap(np.arctan2(np.einsum("ki,ki->k", x, R0[:, :, 1]),
                                np.einsum("ki,ki->k", x, R0[:, :, 0])))
