"""Stiffness maps of the cell: every index of the seam at every placement of the part.

For a :class:`~rfsw_plan.placement.geometry.PlacementGrid` of placements and the problem's
waypoints (the stationary plunge/dwell waypoints and up to ``max_weld`` weld waypoints, each with
its process wrench), all placements x waypoints are evaluated at once:

1. Taught path: vectorised IK (:func:`~rfsw_plan.placement.ik.solve_poses`) of the commanded
   TCP poses (TCP z = -n, the problem's tool rotation). Seeds come coarse-to-fine over the
   table position and height within each yaw (every 8th, 4th, 2nd node, then all, each seeded
   by its nearest solved coarser node at the same yaw; the coarsest nodes from the neighbouring
   yaw, :func:`seed_schedule`); joint 1 is about the base's vertical axis, so a seed is first
   turned by the change of the anchor's polar angle (exact for a rotation of the whole
   placement about that axis).
2. Checks: reach (IK converged), joint limits, joint steps between neighbours (a branch flip),
   kappa_f (seed 000 eq. 5) against the planner's bound.
3. Indices with the problem's forces: lateral compliance c_k = l^T C_tt l (worst = largest and
   mean over the weld), the uncompensated lateral deviation e_k = l . dX_p (dX_p = C W, seed 000
   eq. 11, plus any effect that is not linear in the wrench), nu_p (seed 000 eq. 9) at the
   first, middle and last weld waypoint.
4. Fast mirror fake targets: :data:`MIRROR_STEPS` fixed-point steps o <- o - (e_lat, e_norm,
   e_along) (each with one IK Newton step to the shifted targets, vectorised), the residual
   e_k^m there, and the tolerated force
   uncertainty of those offsets in closed form. Deflection is linear in F, so under the box
   |delta f_i| <= u |f_i| (seam frame) the worst case is e^m_k +- u rho_k with
   rho_k = sum_i |f_i| |l^T C_tt b_i| (b = t, l, n), and the largest u that keeps it in the
   window [lower, upper] is

       u_mirror = min_k min((upper - e^m_k) / rho_k, (e^m_k - lower) / rho_k)   (>= 0).

   ``u_centred = min_k half_width / rho_k`` is what offsets that centre the nominal error
   would tolerate at the same poses (an estimate of what the planner can reach).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.effects import PoseBatch
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import UnreachableError
from rfsw_plan.placement.geometry import (
    PlacedArrays,
    Placement,
    PlacementGrid,
    place_arrays,
    seam_anchor,
)
from rfsw_plan.placement.ik import rotation_error, solve_poses
from rfsw_plan.planning.api import subsample_task
from rfsw_plan.planning.baselines import no_compensation
from rfsw_plan.planning.verify import dexterity_batch
from rfsw_plan.process.frames import tcp_orientation
from rfsw_plan.process.plan_options import PlanOptions
from rfsw_plan.process.task import PlanTask
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: Status names of a placement, in the order they are checked.
STATUSES = ("ok", "unreachable", "joint_limit", "branch_flip", "singularity")


@dataclass(frozen=True)
class MapInput:
    """What the map needs from a problem (SI, base frame, given placement).

    Attributes:
        name: Problem name.
        model: Elastostatic model.
        task: Waypoints (stationary + at most ``max_weld`` weld ones) at the given placement.
        window: Weld window [m].
        options: Planner options (tool rotation, joint step, kappa bound, uncertainty).
        q_seed: Seed of the taught path at the given placement [rad], (n,).
        step_max: Largest joint step between neighbouring waypoints of ``task`` [rad].
    """

    name: str
    model: ElastostaticModel
    task: PlanTask
    window: WeldWindow
    options: PlanOptions
    q_seed: FloatArray
    step_max: float

    @property
    def anchor(self) -> FloatArray:
        """Seam anchor at the given placement [m], (3,)."""
        return seam_anchor(self.task.frames.__class__(*(getattr(self.task.frames, a)[
            self.task.weld] for a in ("s", "p", "t", "l", "n"))))

    @property
    def given(self) -> Placement:
        """The problem's own placement."""
        a = self.anchor
        return Placement(float(a[0]), float(a[1]), float(a[2]), 0.0)


def map_input(problem: Any, max_weld: int = 50, options: PlanOptions | None = None,
              model: ElastostaticModel | None = None) -> MapInput:
    """The map's view of a problem: its task subsampled to ``max_weld`` weld waypoints."""
    from rfsw_plan.planning.api import options_from_problem
    from rfsw_plan.process.task import task_for
    from rfsw_plan.robot.kinematics import load_robot

    opts = options or options_from_problem(problem)
    model = model or ElastostaticModel(load_robot(problem.robot))
    full = task_for(problem, max_start=opts.max_start_waypoints)
    task, idx = subsample_task(full, max_weld)
    spread = max(float(np.max(np.diff(idx[task.n_start:]))) if len(idx) > task.n_start + 1
                 else 1.0, 1.0)
    step_max = min(opts.joint_step * spread, float(np.deg2rad(90.0)))
    q_seed = np.asarray(opts.q_seed) if opts.q_seed is not None else problem.q_seed()
    return MapInput(problem.name, model, task, problem.window, opts, np.asarray(q_seed, float),
                    step_max)


@dataclass(frozen=True)
class PlacementMap:
    """Indices of every placement of a grid (arrays of shape (P,), C order over grid.shape).

    Attributes:
        name: Problem name.
        grid: The grid.
        placements: (x, y, z, yaw) [m, rad], (P, 4).
        anchor: Seam anchor at the given placement [m], (3,).
        status: One of :data:`STATUSES` per placement.
        joint_limit_margin: Smallest distance of the taught path to a joint limit [rad]
            (negative: violated; NaN: unreachable).
        max_joint_step: Largest joint step between neighbouring waypoints [rad].
        kappa_f: Largest kappa_f along the seam (seed 000 eq. 5).
        nu_p: Largest nu_p at the first, middle and last weld waypoint (seed 000 eq. 9).
        compliance_max: Largest lateral compliance l^T C_tt l over the weld [m/N].
        compliance_mean: Mean lateral compliance over the weld [m/N].
        deviation: Largest uncompensated |e_lat| over all waypoints [m].
        tolerated_mirror: Tolerated force uncertainty of the mirror offsets (relative).
        tolerated_centred: half width / max rho_k (relative).
        worst_waypoint: Waypoint with the largest rho_k (decides the tolerated uncertainty).
        q_start: Taught joint values at the first waypoint [rad], (P, n).
        q_path: Taught joint values at every waypoint [rad], (P, K, n) (NaN: unreachable).
        given: Indices of the given placement (same keys as :meth:`row`).
        seconds: Wall time of the map [s].
        evaluated_poses: Poses evaluated by the IK and the indices.
    """

    name: str
    grid: PlacementGrid
    placements: FloatArray
    anchor: FloatArray
    status: NDArray[np.str_]
    joint_limit_margin: FloatArray
    max_joint_step: FloatArray
    kappa_f: FloatArray
    nu_p: FloatArray
    compliance_max: FloatArray
    compliance_mean: FloatArray
    deviation: FloatArray
    tolerated_mirror: FloatArray
    tolerated_centred: FloatArray
    worst_waypoint: NDArray[np.int_]
    q_start: FloatArray
    q_path: FloatArray
    given: dict[str, Any] = field(default_factory=dict)
    seconds: float = float("nan")
    evaluated_poses: int = 0

    @property
    def feasible(self) -> NDArray[np.bool_]:
        """Placements that pass every check, (P,)."""
        return self.status == "ok"

    @property
    def rate(self) -> float:
        """Placements per second."""
        return len(self.placements) / self.seconds if self.seconds > 0 else float("nan")

    def placement(self, i: int) -> Placement:
        """Placement number i."""
        x, y, z, a = self.placements[i]
        return Placement(float(x), float(y), float(z), float(a))

    def row(self, i: int) -> dict[str, Any]:
        """Indices of placement i in file units (mm, deg, N/mm, mm/kN)."""
        return _row(self, i)

    def ranking(self, requested: float) -> NDArray[np.int_]:
        """Feasible placements best first: the larger tolerated uncertainty (capped at the
        requested one), then the larger smallest lateral stiffness, then grid order."""
        ok = np.flatnonzero(self.feasible)
        u = np.minimum(self.tolerated_centred[ok], requested)
        k = 1.0 / self.compliance_max[ok]
        order = np.lexsort((ok, -np.round(k, 3), -np.round(u, 6)))
        return ok[order]


def _row(m: PlacementMap, i: int) -> dict[str, Any]:
    pl = m.placement(i)
    d: dict[str, Any] = pl.to_dict(m.anchor)
    d.update(_indices_dict(str(m.status[i]), m.joint_limit_margin[i], m.max_joint_step[i],
                           m.kappa_f[i], m.nu_p[i], m.compliance_max[i], m.compliance_mean[i],
                           m.deviation[i], m.tolerated_mirror[i], m.tolerated_centred[i]))
    return d


def _indices_dict(status: str, lim: float, step: float, kappa: float, nu: float, cmax: float,
                  cmean: float, dev: float, umir: float, ucen: float) -> dict[str, Any]:
    return {
        "status": status,
        "joint_limit_margin_deg": float(np.rad2deg(lim)),
        "max_joint_step_deg": float(np.rad2deg(step)),
        "kappa_f_max": float(kappa),
        "nu_p_max": float(nu),
        "lateral_compliance_max_mm_per_kN": float(cmax) * 1e6,
        "lateral_compliance_mean_mm_per_kN": float(cmean) * 1e6,
        "min_lateral_stiffness_N_per_mm": 1e-3 / float(cmax) if cmax > 0 else float("nan"),
        "max_abs_uncompensated_lateral_mm": float(dev) * 1e3,
        "tolerated_uncertainty_mirror": float(umir),
        "tolerated_uncertainty_centred": float(ucen),
    }


# -- kinematic helpers -------------------------------------------------------------------------

def joint1_is_vertical(robot: Robot) -> bool:
    """True if joint 1 turns about the base's z axis through its origin (and drives only
    itself): turning a placement about that axis then only changes q1."""
    g = robot.geometry
    a = np.asarray(g.axes[0], float)
    P0 = g.placements[0]
    axis = P0[:3, :3] @ (a / np.linalg.norm(a))
    G = robot.coupling
    return bool(np.allclose(axis, [0, 0, 1], atol=1e-9) and np.allclose(P0[:2, 3], 0, atol=1e-9)
                and np.allclose(G[0, 1:], 0) and np.allclose(G[1:, 0], 0) and G[0, 0] == 1.0)


def _polar(p: FloatArray) -> FloatArray:
    return np.arctan2(p[..., 1], p[..., 0])


def _turn_seed(robot: Robot, Q: FloatArray, dtheta: FloatArray) -> FloatArray:
    """Seeds (P, K, n) with q1 turned by dtheta (P,), wrapped by 2 pi into the limits."""
    out = np.array(Q, dtype=float)
    lo, hi = robot.description.lower[0], robot.description.upper[0]
    q1 = out[:, :, 0] + dtheta[:, None]
    mid = 0.5 * (lo + hi)
    q1 = q1 - 2 * np.pi * np.round((np.mean(q1, axis=1, keepdims=True) - mid) / (2 * np.pi))
    out[:, :, 0] = q1
    return out


def wrap_into_limits(robot: Robot, Q: FloatArray) -> FloatArray:
    """Joint paths (P, K, n) [rad] with every joint whose range exceeds a full turn shifted by
    -2 pi, 0 or +2 pi (the whole path of a placement at once, so steps stay continuous) to
    the shift with the largest limit margin: the same TCP poses, and a placement's status
    does not depend on the turn the IK seed happened to be on. Only revolute joints that no
    other joint is coupled to (a turn of the joint is a turn of that joint alone)."""
    lo, hi = robot.description.lower, robot.description.upper
    G = robot.coupling
    out = np.array(Q, dtype=float)
    for j in range(Q.shape[2]):
        e = np.zeros(len(lo))
        e[j] = 1.0
        if hi[j] - lo[j] <= 2 * np.pi or robot.geometry.prismatic[j] or \
                not np.allclose(G[:, j], e):
            continue
        shifts = np.array([-2 * np.pi, 0.0, 2 * np.pi])
        qj = out[:, :, j][:, :, None] + shifts  # (P, K, 3)
        with np.errstate(invalid="ignore"):
            margin = np.min(np.minimum(qj - lo[j], hi[j] - qj), axis=1)  # (P, 3)
        best = np.argmax(np.where(np.isfinite(margin), margin, -np.inf) + 1e-12 * (
            shifts == 0.0), axis=1)
        out[:, :, j] += shifts[best][:, None]
    return out


def nu_p_batch(model: ElastostaticModel, Q: FloatArray, W: FloatArray) -> FloatArray:
    """nu_p (seed 000 eq. 9) at joint values Q (m, n) [rad] under wrenches W (m, 6), (m,):
    |dx_Kc - dx| / max(dx, dx_Kc) with dx the translational deflection of Kq and dx_Kc that
    of Kq - Kc, Kc = sum_a (dJ/dq)^T F_a (eq. 6); NaN where Kq - Kc is singular."""
    robot = model.robot
    K = np.diag(model.stiffness)
    _, J = robot.batch_fk_jacobian(Q)
    Kc = np.einsum("mkaj,ma->mjk", robot.batch_jacobian_derivatives(Q), W)
    tau = np.einsum("maj,ma->mj", J, W)
    dq = tau / model.stiffness
    dx = np.linalg.norm(np.einsum("maj,mj->ma", J[:, :3], dq), axis=1)
    try:
        dq_kc = np.linalg.solve(K[None] - Kc, tau[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:
        dq_kc = np.full_like(tau, np.nan)
        for i in range(len(Q)):
            try:
                dq_kc[i] = np.linalg.solve(K - Kc[i], tau[i])
            except np.linalg.LinAlgError:
                continue
    dx_kc = np.linalg.norm(np.einsum("maj,mj->ma", J[:, :3], dq_kc), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.asarray(np.abs(dx_kc - dx) / np.maximum(dx, dx_kc))


def _compliance_and_deflection(
    model: ElastostaticModel, Q: FloatArray, W: FloatArray, reference: str,
    TJ: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Kinematics, Cartesian compliance and process deflection at Q (m, n).

    Args:
        TJ: TCP poses and Jacobians at Q if already known (saves one batch evaluation).

    Returns:
        (T (m, 4, 4), J (m, 6, n), C (m, 6, 6), dX (m, 6) [m, rad]) with dX = C W for the
        effects linear in the wrench plus the rest of
        :meth:`ElastostaticModel.process_deflection_batch`.
    """
    robot = model.robot
    phys = model.physical()
    if phys.is_linear_joint_model():
        T, J = TJ if TJ is not None else robot.batch_fk_jacobian(Q)
        c = phys.joint_compliance.params
        C = np.matmul(J * c, np.transpose(J, (0, 2, 1)))
        return T, J, C, np.matmul(C, W[:, :, None])[:, :, 0]
    batch = PoseBatch.from_q(robot, Q)
    C, nonlinear = phys.linear_compliance(batch)
    if nonlinear or phys.has_load_independent_part():
        dX = model.process_deflection_batch(batch, W, reference)  # type: ignore[arg-type]
    else:
        dX = np.matmul(C, W[:, :, None])[:, :, 0]
    return batch.T, batch.J, C, dX


@dataclass
class _Chunk:
    """Indices of a chunk of placements (filled by :func:`_evaluate`)."""

    status: NDArray[np.str_]
    limit: FloatArray
    step: FloatArray
    kappa: FloatArray
    nu: FloatArray
    cmax: FloatArray
    cmean: FloatArray
    dev: FloatArray
    umir: FloatArray
    ucen: FloatArray
    worst: NDArray[np.int_]
    Q: FloatArray
    poses: int


#: Fixed-point steps of the fast mirror fake targets: 3, as many as the planner's mirror
#: baseline needs on zk500 (the tolerated uncertainty is then within 1e-3 of the converged
#: fixed point, tests/test_placement.py; 1 step is 1.9e-3 off, 2 steps 2.2e-3).
MIRROR_STEPS = 3


def _evaluate(mi: MapInput, arr: PlacedArrays, seeds: FloatArray,
              mirror_steps: int = MIRROR_STEPS) -> _Chunk:
    """IK, checks and indices of P placements from seeds (P, K, n)."""
    model, task = mi.model, mi.task
    robot = model.robot
    P, K, n = seeds.shape
    R = arr.R_tcp.reshape(P * K, 3, 3)
    ik = solve_poses(robot, R, arr.target.reshape(P * K, 3), seeds.reshape(P * K, n), tol=1e-6)
    poses = P * K * ik.iterations
    reach = np.asarray(ik.converged.reshape(P, K).all(axis=1), dtype=bool)
    Q = wrap_into_limits(robot, ik.q.reshape(P, K, n))
    lo, hi = robot.description.lower, robot.description.upper
    limit = np.min(np.minimum(Q - lo, hi - Q), axis=(1, 2))
    sl = task.weld
    step = np.max(np.abs(np.diff(Q, axis=1)), axis=(1, 2)) if K > 1 else np.zeros(P)
    def nan() -> FloatArray:
        return np.full(P, np.nan)

    out = _Chunk(status=np.full(P, "unreachable", dtype="<U12"), limit=nan(), step=step,
                 kappa=nan(), nu=nan(), cmax=nan(), cmean=nan(), dev=nan(), umir=nan(),
                 ucen=nan(), worst=np.zeros(P, dtype=int),
                 Q=np.where(reach[:, None, None], Q, np.nan), poses=poses)
    out.limit[reach] = limit[reach]
    ok = np.flatnonzero(reach)
    if ok.size == 0:
        return out
    Qo, m = Q[ok], len(ok)
    W = arr.wrench[ok].reshape(m * K, 6)
    rows = (ok[:, None] * K + np.arange(K)[None]).ravel()
    T, J, C, dX = _compliance_and_deflection(model, Qo.reshape(m * K, n), W, task.reference,
                                             (ik.T[rows], ik.J[rows]))
    kappa = dexterity_batch(J, mi.options.length_scale).reshape(m, K)
    l, nn, t = arr.l[ok], arr.n[ok], arr.t[ok]
    dXt = dX[:, :3].reshape(m, K, 3)
    e_lat = np.einsum("pki,pki->pk", l, dXt)
    Ctt = C[:, :3, :3].reshape(m, K, 3, 3)
    cll = np.einsum("pki,pkij,pkj->pk", l, Ctt, l)
    # Fast mirror: fixed-point steps o <- o - (e_lat, e_norm, e_along) (the pin error in the
    # seam frame), each followed by one Newton step of the IK to the shifted targets
    # (dq = J^-1 (p* + o - p(q), log(R* R^T))); the indices are evaluated where it stops.
    L, Nn, Tt = l.reshape(-1, 3), nn.reshape(-1, 3), t.reshape(-1, 3)
    tgt = arr.target[ok].reshape(m * K, 3)
    R_t = arr.R_tcp[ok].reshape(m * K, 3, 3)
    q_m = Qo.reshape(m * K, n)
    o = np.zeros((m * K, 3))
    Tm, Jm, Cm, dXm = T, J, C, dX
    finite = np.ones(m * K, dtype=bool)
    for _ in range(mirror_steps):
        d = Tm[:, :3, 3] + dXm[:, :3] - tgt
        o = o - sum(B * np.einsum("ki,ki->k", B, d)[:, None] for B in (L, Nn, Tt))
        err = np.concatenate([tgt + o - Tm[:, :3, 3], rotation_error(R_t, Tm[:, :3, :3])],
                             axis=1)
        try:
            dq = np.linalg.solve(Jm, err[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            dq = np.matmul(np.linalg.pinv(Jm), err[:, :, None])[:, :, 0]
        finite &= np.all(np.isfinite(dq), axis=1)
        q_m = q_m + np.where(np.isfinite(dq), dq, 0.0)
        Tm, Jm, Cm, dXm = _compliance_and_deflection(model, q_m, W, task.reference)
        poses += m * K
    pin = (Tm[:, :3, 3] + dXm[:, :3]).reshape(m, K, 3)
    e_m = np.einsum("pki,pki->pk", l, pin - arr.p[ok])
    lC = np.einsum("pki,pkij->pkj", l, Cm[:, :3, :3].reshape(m, K, 3, 3))
    proj = np.stack([np.einsum("pkj,pkj->pk", lC, b) for b in (t, l, nn)], axis=2)
    rho = np.sum(np.abs(task.force_seam)[None] * np.abs(proj), axis=2)  # (m, K) [m]
    win = mi.window
    with np.errstate(divide="ignore", invalid="ignore"):
        u_k = np.minimum((win.upper - e_m) / rho, (e_m - win.lower) / rho)
        u_k = np.where(rho > 0, u_k, np.inf)
        u_c = np.where(rho > 0, win.half_width / rho, np.inf)
    u_mir = np.maximum(np.min(u_k, axis=1), 0.0)
    u_mir = np.where(finite.reshape(m, K).all(axis=1), u_mir, np.nan)
    # nu_p at the first, middle and last weld waypoint.
    ks = np.unique([sl.start, (sl.start + K - 1) // 2, K - 1])
    nu = nu_p_batch(model, Qo[:, ks].reshape(-1, n), arr.wrench[ok][:, ks].reshape(-1, 6))
    out.kappa[ok] = np.max(kappa, axis=1)
    out.nu[ok] = np.nanmax(nu.reshape(m, len(ks)), axis=1) if np.any(np.isfinite(nu)) else np.nan
    out.cmax[ok] = np.max(cll[:, sl], axis=1)
    out.cmean[ok] = np.mean(cll[:, sl], axis=1)
    out.dev[ok] = np.max(np.abs(e_lat), axis=1)
    out.umir[ok] = u_mir
    out.ucen[ok] = np.min(u_c, axis=1)
    out.worst[ok] = np.argmax(rho, axis=1)
    status = np.full(m, "ok", dtype="<U12")
    status[out.kappa[ok] > mi.options.kappa_max] = "singularity"
    status[step[ok] > mi.step_max] = "branch_flip"
    status[limit[ok] < 0] = "joint_limit"
    out.status[ok] = status
    return out


def taught_given(mi: MapInput) -> FloatArray | None:
    """Taught path at the given placement (IK continuation from the seed) [rad], (K, n), or
    None if the given placement is unreachable."""
    R0 = tcp_orientation(mi.task.frames, mi.options.tool_rotation)
    try:
        return no_compensation(mi.model.robot, mi.task, mi.q_seed, mi.options.tool_rotation).q
    except UnreachableError:
        pass
    ik = solve_poses(mi.model.robot, R0, mi.task.target,
                     np.tile(mi.q_seed, (len(mi.task), 1)), max_iter=80)
    return ik.q if ik.converged.all() else None


def seed_schedule(shape: tuple[int, int, int, int], yaw: FloatArray,
                  max_stride: int = 8) -> list[tuple[NDArray[np.int_], NDArray[np.int_]]]:
    """Order in which the map solves its placements, and the seed of each.

    The grid is C order over (x, y, yaw, z). Seeds go coarse-to-fine over the table position
    and height within each yaw (a neighbour at the same yaw differs by a small translation, so
    the IK needs few Newton steps), never across yaw at the fine levels (a yaw step of 45 deg
    would cost several clipped steps for every placement):

    1. roots: every ``top``-th node in x, y, z (top = the largest power of two <= max_stride
       below the longest spatial axis) at the yaw closest to the given one, seeded from the
       given placement (parent -1);
    2. the roots at the other yaws, one yaw step at a time away from that yaw, each seeded by
       the root at the neighbouring yaw toward it;
    3. every ``stride``-th node in x, y, z (stride = top/2, top/4 ... 1) at every yaw, seeded by
       the nearest node of the coarser level at the same yaw.

    Returns:
        Levels in order, each (placement indices, parent placement indices; -1 = the given
        placement's taught path).
    """
    P = int(np.prod(shape))
    coords = np.stack(np.unravel_index(np.arange(P), shape), axis=1)  # (P, 4) grid indices
    spatial = np.array([0, 1, 3])
    top = 1
    while top * 2 < max(shape[0], shape[1], shape[3]) and top < max_stride:
        top *= 2
    start = int(np.argmin(np.abs(np.asarray(yaw, float))))
    root = np.all(coords[:, spatial] % top == 0, axis=1)
    levels: list[tuple[NDArray[np.int_], NDArray[np.int_]]] = []
    idx = np.flatnonzero(root & (coords[:, 2] == start))
    levels.append((idx, np.full(len(idx), -1)))
    for j in sorted(range(shape[2]), key=lambda j: (abs(j - start), j)):
        if j == start:
            continue
        idx = np.flatnonzero(root & (coords[:, 2] == j))
        pc = coords[idx].copy()
        pc[:, 2] = j + (1 if j < start else -1)
        levels.append((idx, np.ravel_multi_index(tuple(pc.T), shape)))
    solved = root.copy()
    stride = top // 2
    last = (np.array(shape) - 1)
    while stride >= 1:
        on = np.all(coords[:, spatial] % stride == 0, axis=1) & ~solved
        idx = np.flatnonzero(on)
        pc = coords[idx].copy()
        step = 2 * stride
        pc[:, spatial] = np.minimum(np.round(pc[:, spatial] / step).astype(int) * step,
                                    (last[spatial] // step) * step)
        levels.append((idx, np.ravel_multi_index(tuple(pc.T), shape)))
        solved |= on
        stride //= 2
    return levels


def compute_map(mi: MapInput, grid: PlacementGrid, chunk: int = 512,
                progress_desc: str | None = "map") -> PlacementMap:
    """Evaluate every placement of ``grid`` (see the module docstring).

    Args:
        mi: The problem's map input (:func:`map_input`).
        grid: The placements.
        chunk: Placements evaluated per vectorised batch (memory: about chunk x K x 3 kB).
        progress_desc: Label of the progress bar (None: no bar).

    Raises:
        UnreachableError: The given placement is unreachable and so no seed exists.
    """
    from rfsw_plan.progress import Bar

    t0 = time.perf_counter()
    robot = mi.model.robot
    task = mi.task
    anchor = mi.anchor
    R0 = tcp_orientation(task.frames, mi.options.tool_rotation)
    Q0 = taught_given(mi)
    if Q0 is None:
        raise UnreachableError(
            f"{mi.name}: the seam is unreachable at its given placement from the seed "
            f"q_seed_deg = {np.round(np.rad2deg(mi.q_seed), 1).tolist()}; no seed for the map")
    K, n = Q0.shape
    turn = joint1_is_vertical(robot)
    theta0 = float(_polar(anchor))
    PL = grid.placements()
    P = len(PL)
    shape = grid.shape
    chunks: dict[str, Any] = {
        "status": np.full(P, "unreachable", dtype="<U12"),
        **{k: np.full(P, np.nan) for k in ("limit", "step", "kappa", "nu", "cmax", "cmean",
                                             "dev", "umir", "ucen")},
        "worst": np.zeros(P, dtype=int),
    }
    Qall = np.full((P, K, n), np.nan)
    poses = 0
    with Bar(P, progress_desc or "map", unit="placement") as bar:
        for idx_level, parent_level in seed_schedule(shape, grid.yaw):
            parent_level = np.where(parent_level >= 0, parent_level, -1)
            ok_par = parent_level >= 0
            ok_par[ok_par] = np.all(np.isfinite(Qall[parent_level[ok_par], 0]), axis=1)
            parent_level = np.where(ok_par, parent_level, -1)
            for lo in range(0, len(idx_level), chunk):
                sel, par = idx_level[lo:lo + chunk], parent_level[lo:lo + chunk]
                arr = place_arrays(task, anchor, PL[sel], R0)
                seeds = np.where((par >= 0)[:, None, None], Qall[np.maximum(par, 0)], Q0[None])
                theta_par = np.where(par >= 0, _polar(PL[np.maximum(par, 0), :2]), theta0)
                if turn:
                    seeds = _turn_seed(robot, seeds, _polar(PL[sel, :2]) - theta_par)
                res = _evaluate(mi, arr, seeds)
                poses += res.poses
                retry = np.flatnonzero((res.status == "unreachable") & (par >= 0))
                if retry.size:  # a failed neighbour seed: once more from the given placement
                    arr2 = place_arrays(task, anchor, PL[sel[retry]], R0)
                    s2 = np.broadcast_to(Q0, (len(retry), K, n))
                    if turn:
                        s2 = _turn_seed(robot, s2, _polar(PL[sel[retry], :2]) - theta0)
                    res2 = _evaluate(mi, arr2, s2)
                    poses += res2.poses
                    for name in chunks:
                        getattr(res, name)[retry] = getattr(res2, name)
                    res.Q[retry] = res2.Q
                for name in chunks:
                    chunks[name][sel] = getattr(res, name)
                Qall[sel] = res.Q
                bar.update(len(sel))
    given = evaluate_given(mi, Q0)
    return PlacementMap(
        name=mi.name, grid=grid, placements=PL, anchor=anchor, status=chunks["status"],
        joint_limit_margin=chunks["limit"], max_joint_step=chunks["step"],
        kappa_f=chunks["kappa"], nu_p=chunks["nu"], compliance_max=chunks["cmax"],
        compliance_mean=chunks["cmean"], deviation=chunks["dev"],
        tolerated_mirror=chunks["umir"], tolerated_centred=chunks["ucen"],
        worst_waypoint=chunks["worst"], q_start=Qall[:, 0].copy(), q_path=Qall,
        given=given, seconds=time.perf_counter() - t0, evaluated_poses=poses,
    )


def evaluate_given(mi: MapInput, Q0: FloatArray | None = None) -> dict[str, Any]:
    """Indices of the given placement (file units), from its taught path."""
    Q0 = taught_given(mi) if Q0 is None else Q0
    g = mi.given
    pl = g.as_array()[None]
    d: dict[str, Any] = g.to_dict(mi.anchor)
    if Q0 is None:
        d["status"] = "unreachable"
        return d
    R0 = tcp_orientation(mi.task.frames, mi.options.tool_rotation)
    res = _evaluate(mi, place_arrays(mi.task, mi.anchor, pl, R0), Q0[None])
    d.update(_indices_dict(str(res.status[0]), res.limit[0], res.step[0], res.kappa[0],
                           res.nu[0], res.cmax[0], res.cmean[0], res.dev[0], res.umir[0],
                           res.ucen[0]))
    d["worst_waypoint"] = int(res.worst[0])
    return d


def compliance_shares(model: ElastostaticModel, task: PlanTask, q: FloatArray,
                      k: int) -> dict[str, float]:
    """Which joint's compliance makes the worst-case lateral spread rho_k at waypoint k.

    rho_k = sum_i |f_i| |l^T C_tt b_i|; joint j of the joint compliance contributes
    c_j |l . J_t,j| sum_i |f_i| |b_i . J_t,j| (its share of the bound), the rest of the model's
    effects (tilting...) the remainder. Shares sum to 1 (keys ``q1``.. and ``other_effects``).
    """
    fr = task.frames
    Qk = np.asarray(q, float)[k:k + 1]
    _, J, C, _ = _compliance_and_deflection(model, np.vstack([Qk, Qk]), np.zeros((2, 6)),
                                            task.reference)
    Jt = J[0, :3]
    c = model.joint_compliance.params
    l = fr.l[k]
    b = np.stack([fr.t[k], fr.l[k], fr.n[k]])
    f = np.abs(task.force_seam[k])
    joint = c * np.abs(l @ Jt) * (f @ np.abs(b @ Jt))
    total_C = float(np.sum(f * np.abs(b @ (C[0, :3, :3] @ l))))
    Cj = (Jt * c) @ Jt.T
    other = max(total_C - float(np.sum(f * np.abs(b @ (Cj @ l)))), 0.0)
    s = float(np.sum(joint)) + other
    out = {f"q{j + 1}": float(joint[j] / s) for j in range(len(c))}
    out["other_effects"] = other / s
    return out
