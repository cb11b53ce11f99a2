"""The planning NLP: joint values and fake-target offsets along the seam (CasADi + IPOPT).

Decision variables per waypoint k (one column of W, shape (n + 5, K)):

* ``q_k`` [rad] (n): the robot configuration. The TCP position is fixed by the constraints,
  and of the orientation only the tool axis: the rotation of the axisymmetric tool about its
  axis is free and the solver uses it.
* ``o_k`` [mm] (3): the fake-target offset, lateral (along l), normal (along n) and
  along-track (along t).
* ``sigma_k`` [mm]: how far the worst case leaves the window (exact L1 penalty; fixed to 0 with
  ``robust_hard``).
* ``rho_k``: the share of the requested force uncertainty the window holds (all equal).

Per waypoint, with p_k the nominal target, F_k the wrench (base frame) and C_X the Cartesian
compliance of the symbolic model (joint and tilting compliance; seed 000 eq. 11, seed 002 eq. 2):

* FK_p(q_k) = p_k + o_lat l_k + o_norm n_k + o_along t_k and R(q_k) e_z . t_k =
  R(q_k) e_z . l_k = 0, R(q_k) e_z . n_k <= -1/2 (the TCP z axis is -n_k);
* along the track the predicted pin is on the seam point: t_p,k . (FK_p(q_k) + [C_X(q_k) F_k]_p
  - p_k) + c_t,k = 0, t_p the seam tangent in the plate's plane
  (:func:`~rfsw_plan.planning.verify.along_tangents`: the pin stays on its seam point in the
  plate whatever its depth along the tilted tool axis). The process model gives F_k for the pin
  at s_k (the traverse force ramps up over the first millimetre of *pin* travel); with this
  row the pin is there, the lag of the pin behind the TCP (several mm while the ramp winds it
  up) is in o_along, and the weld is timed on s_k directly (:mod:`rfsw_plan.timing.trajectory`);
* the pin's travel over each weld link along the seam chord u_k within half the speed
  tolerance of the seam's travel h_k, the chord's turn included (:func:`travel_parameters`:
  one row per link, the sum of a term of each end, scaled by h_min / h_k to the bound
  speed_tol h_min / 2);
* e_k = l_k . (FK_p(q_k) + [C_X(q_k) F_k]_p - p_k) + c_k (c_k: outer correction for effects
  the symbolic model lacks), lower + margin <= e_k <= upper - margin;
* robust window: the box |delta f_i| <= u |f_i| moves e_k by at most
  r_k = sum_i u |f_ik| |l_k^T C_tt(q_k) b_ik| (b = t, l, n; deflection is linear in F), so
  e_k - r_k + sigma_k >= lower and e_k + r_k - sigma_k <= upper. |x| is the smooth
  sqrt(x^2 + eps^2) with eps = ``ABS_EPS`` = 0.01 mm: conservative, over-estimating r by at
  most 3 eps. (With eps = 1e-4 mm the kink where a cross compliance l^T C b changes sign
  under a tool rotation made IPOPT hit its iteration cap on kr600_curved_seam; auxiliary
  variables with +-x <= a were exact too but their degenerate rows at zero force slowed
  IPOPT down several times);
* tolerated uncertainty: e_k - rho r_k >= lower and e_k + rho r_k <= upper, rho in [0, 1] the
  share of the requested uncertainty u that the window holds at every waypoint (one value for
  the plan: a copy per waypoint, kept equal by link rows, so the KKT matrix stays banded);
  rho u is the tolerated force uncertainty of the plan in the NLP's model;
* sign_k det(J_n(q_k)) >= floor_k (J_n: J with its translational rows divided by a length
  scale), a smooth stand-in for the kappa_f bound of seed 000 eq. 5;
* at weld waypoints l^T C_tt(q_k) l <= c_max: c_max is one global epigraph variable (the last
  entry of x, one dense Jacobian column), the compliance of the weakest waypoint.

Between neighbours: |q_{k+1} - q_k| <= joint step; the offsets' change beyond the change the
load itself demands (m_k: the mirror baseline's offsets, ``offset_reference``),
|(o_{k+1} - m_{k+1}) - (o_k - m_k)| <= offset rate * travel (+ offset speed * time while
stationary), and <= offset speed * time while moving, per offset component (the offsets follow
the force ramps as the mirror does; the along-track component follows the traverse-force
ramp). The planner uses this form in the coarse and in the full NLP: with the looser
``load_steps`` form, |o_{k+1} - o_k| <= allowance + |m_{k+1} - m_k|, the full NLP followed the
travel-start ramp only in part (fanuc_laser_1400mm_yplus: 0.16 mm of pin error over the first
0.625 mm link, five times the offset rate) where the coarse NLP could not, and the two plans
were 0.08-0.13 mm apart there (issue 38).

Every row family above is declared once, by name, in :mod:`rfsw_plan.planning.rows` (its
expression, bounds, independent check); the variables and parameters are named by the layouts
of :mod:`rfsw_plan.planning.layout`. Per waypoint there are
:func:`~rfsw_plan.planning.rows.point_row_count` rows (22) and n + 5 variables; per link n + 4
rows; x has K (n + 5) + 1 entries.

Objective (weights and priorities in :mod:`rfsw_plan.process.plan_options`):
w_stiffness share c_max / ref plus the mean over waypoints of
w_stiffness (1 - share) l^T C_tt l / ref + w_worst r_k / hw
+ w_robust (sigma_k / hw + 1 - rho)
+ w_centre ((e_k - centre) / hw)^2 + w_depth ((normal error - d_k) / 1 mm)^2
(d_k = 0, the planned depth; under the coupled axial law the depth window's centre, with the
weight w_depth x w_robust: :func:`depth_targets`)
+ w_proximity |q_k - q_warm,k|^2 (keeps the null space, e.g. an unused tool rotation, at the
warm start), plus mean over links of
w_smooth_q |dq / h|^2 + w_smooth_o |do_lat,norm / h|^2 (the along-track offset is fixed by the
pin's along-track row, so it is not smoothed).

The NLP is one ``nlpsol`` over the stacked vector; the per-waypoint part is one SX function
``map``-ped over the waypoints, so the KKT matrix is banded and the build cost does not grow
with K. Built solvers are cached by (model, K).
"""

from __future__ import annotations

import logging
import time
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from rfsw_plan import files
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.planning import rows
from rfsw_plan.planning.casadi_ import (
    compile_functions,
    compile_in_background,
    library_path,
    single_thread_blas,
)
from rfsw_plan.planning.layout import (
    ERROR_TERMS,
    GLOBALS,
    N_GLOB,
    OFFSETS,
    SMOOTHED_OFFSETS,
    TERMS,
    VARIABLE_SCALE,
    Layout,
    columns,
    n_par,
    point_layout,
    problem_layout,
    variable_layout,
)
from rfsw_plan.planning.rows import (
    LinkContext,
    PointBounds,
    PointSymbols,
    epigraph_rows,
    link_families,
    link_sum_families,
    link_sum_rows,
    link_variables,
    point_labels,
    point_row_count,
    point_row_layout,
)
from rfsw_plan.planning.symbolic import symbolic_cartesian_compliance, symbolic_chain
from rfsw_plan.planning.verify import along_tangents
from rfsw_plan.process.plan_options import PlanOptions
from rfsw_plan.process.task import (
    STANDING_DEPTH_TOL,
    STANDSTILL_MOTION,
    PlanTask,
    offsets3,
)
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]
log = logging.getLogger(__name__)

#: Names of the per-waypoint constraint rows, in order, as declared in
#: :data:`~rfsw_plan.planning.rows.POINT_ROWS` (:func:`~rfsw_plan.planning.rows.point_labels`).
POINT_CONSTRAINTS = point_labels()
#: Smoothing of |x| in the worst case [mm]: sqrt(x^2 + eps^2) over-estimates |x| by at most eps.
ABS_EPS = 1e-2


def x_layout(n: int, K: int) -> Layout:
    """The NLP's variable vector x: K waypoints' variables (:func:`variable_layout`,
    waypoint-major) and c_max, the largest lateral compliance of the weld waypoints
    [mm/kN] (the epigraph variable)."""
    return Layout((("points", variable_layout(n).size * K), ("c_max", 1)))


def g_layout(n: int, K: int) -> Layout:
    """The NLP's constraint vector g: the per-waypoint rows of K waypoints (waypoint-major,
    :data:`POINT_CONSTRAINTS` each), then the link rows of K - 1 links (link-major, see
    :class:`LinkBounds`), then the link sums of K - 1 links (link-major, one per family
    declared with ``link_sum``)."""
    per_link = sum(variable_layout(n).width(v) for v in link_variables())
    return Layout((("points", point_row_count() * K), ("links", per_link * max(K - 1, 0)),
                   ("sums", len(link_sum_families()) * max(K - 1, 0))))


def _model_key(model: ElastostaticModel) -> tuple[object, ...]:
    d = model.robot.description
    return (d.name, d.tool.tobytes(), model.robot.geometry.placements.tobytes(),
            model.robot.coupling.tobytes(),
            tuple((e.label, e.params.tobytes()) for e in model.effects))


@dataclass(frozen=True)
class PointFunctions:
    """Per-waypoint CasADi functions (SX, optionally compiled to C).

    With n_g = :func:`~rfsw_plan.planning.rows.point_row_count` rows per waypoint (22, named
    by :data:`POINT_CONSTRAINTS`), n_w = n + 5 variables per waypoint
    (:func:`~rfsw_plan.planning.layout.variable_layout`) and the terms of
    :data:`~rfsw_plan.planning.layout.TERMS` (6):

    Attributes:
        info: ``(w, par) -> (g (22,), terms (6,), dX (6,))``.
        fg: ``(w, par, glob) -> (phi, g)``, phi the waypoint's objective share.
        grad: ``(w, par, glob) -> grad phi (n + 5,)``.
        jac: ``(w, par) -> dg/dw`` dense (22, n + 5).
        hess: ``(w, par, glob, lam_f, lam_g) -> triu of the Hessian of lam_f phi + lam_g . g``
            dense upper triangle (n + 5, n + 5).
        skipped: Effects the symbolic model lacks.
        compiled: True if the functions run as compiled C.
        fg_vm: ``fg`` in the CasADi virtual machine (differentiable by CasADi).
        fg_nlp: ``fg`` for the NLP definition: ``fg_vm``, or, compiled, ``fg`` with finite
            differences enabled (``nlpsol`` asks for derivative functions of its definition
            when it is built; IPOPT's derivatives all come from ``grad``, ``jac`` and
            ``hess``, so the finite differences are never evaluated in a solve).
    """

    info: ca.Function
    fg: ca.Function
    grad: ca.Function
    jac: ca.Function
    hess: ca.Function
    skipped: tuple[str, ...]
    compiled: bool
    fg_vm: ca.Function
    fg_nlp: ca.Function

    @property
    def library(self) -> list[ca.Function]:
        """The functions one compiled library holds, in its order (``info, fg, grad, jac,
        hess``): of the virtual machine's functions, what
        :func:`~rfsw_plan.planning.casadi_.library_path` hashes."""
        return [self.info, self.fg, self.grad, self.jac, self.hess]


_POINT_CACHE: OrderedDict[tuple[object, ...], PointFunctions] = OrderedDict()
_SOLVER_CACHE: OrderedDict[tuple[object, ...], ca.Function] = OrderedDict()
_EVAL_CACHE: OrderedDict[tuple[object, ...], ca.Function] = OrderedDict()
#: Where the optimised library of the point functions is kept, by structure (hashing the
#: functions costs 20-100 ms: once per process; whether it is there yet is asked every plan).
_OPTIMISED: dict[tuple[object, ...], Path] = {}


def _point_symbols(model: ElastostaticModel, v: dict[str, Any], pp: dict[str, Any]
                   ) -> tuple[PointSymbols, Any, tuple[str, ...]]:
    """One waypoint's quantities (:class:`~rfsw_plan.planning.rows.PointSymbols`) from its
    variables v and parameters pp (SX, NLP units), the TCP deflection C F [m, rad] (6,) and
    the effects the symbolic model lacks."""
    q, o = v["q"], OFFSETS.split(v["offsets"])
    target, t, l, nn = pp["target"], pp["t"], pp["l"], pp["n"]
    F, uf, corr = pp["wrench"], pp["force_spread"], OFFSETS.split(pp["correction"])
    ch = symbolic_chain(model.robot, q)
    C, skipped = symbolic_cartesian_compliance(model, ch)
    dX = C @ F
    pos = 1e3 * (ch.p - target) - o["lateral"] * l - o["normal"] * nn - o["along"] * t
    pin_err = ch.p + dX[:3] - target
    lC = C[:3, :3] @ l
    proj = ca.vertcat(*(1e3 * uf[i] * ca.dot(lC, b) for i, b in enumerate((t, l, nn))))
    cll = 1e6 * ca.dot(l, lC)  # lateral compliance [mm/kN]
    sym = PointSymbols(
        v=v, par=pp, position=pos, axis=ch.R[:, 2],
        error=1e3 * ca.dot(l, pin_err) + corr["lateral"],
        normal_error=1e3 * ca.dot(nn, pin_err) + corr["normal"],
        along_error=1e3 * ca.dot(pp["t_along"], pin_err) + corr["along"],
        pin=(1e3 * pin_err + corr["lateral"] * l + corr["normal"] * nn
             + corr["along"] * pp["t_along"]),
        worst=ca.sum1(ca.sqrt(proj ** 2 + ABS_EPS ** 2)), compliance=cll)
    return sym, dX, tuple(skipped)


def _family_expression(family: Any, sym: PointSymbols) -> Any:
    """A point row family's expression, checked against its declared row count."""
    g = family.expression(sym)
    if g.shape != (len(family.labels), 1):
        raise TypeError(f"row family {family.name!r}: expression of shape {g.shape}, declared "
                        f"{len(family.labels)} rows {family.labels}")
    return g


def point_functions(model: ElastostaticModel, compile_c: bool | str = False,
                    coupled: bool = False) -> PointFunctions:
    """The per-waypoint functions of the NLP (see :class:`PointFunctions`).

    Args:
        model: Elastostatic model; its joint and tilting compliance enter symbolically.
        compile_c: Compile them to C with the system compiler, at a level of
            :data:`COMPILE_LEVELS` (True: ``O1``; False or "": CasADi's virtual machine),
            cached on disk (:func:`~rfsw_plan.planning.casadi_.compile_functions`); falls
            back to the virtual machine if that fails.
        coupled: The objective plans with the coupled axial law (:func:`plans_coupled`): the
            depth centred on ``depth_at`` (:func:`depth_targets`) instead of 0; a problem
            without it gets the functions without that parameter.
    """
    level = "O1" if compile_c is True else compile_c or ""
    key = (*_model_key(model), level, coupled)
    if key in _POINT_CACHE:
        return _POINT_CACHE[key]
    robot = model.robot
    n = robot.nq
    vl, pl = variable_layout(n), point_layout(n)
    w = ca.SX.sym("w", vl.size)
    par = ca.SX.sym("par", pl.size)
    glob = ca.SX.sym("glob", N_GLOB)
    v, pp, gl = vl.split(w), pl.split(par), GLOBALS.split(glob)
    sym, dX, skipped = _point_symbols(model, v, pp)
    cll = sym.compliance
    g = ca.vertcat(*(_family_expression(f, sym) for f in rows.POINT_ROWS))
    terms = ca.vertcat(*(
        {"lateral_compliance": cll, "worst_case": sym.worst, "robust_excess": v["sigma"],
         "error": sym.error, "normal_error": sym.normal_error,
         "along_error": sym.along_error}[name] for name in TERMS.names))
    e, r, dep, q, rho = sym.error, sym.worst, sym.normal_error, v["q"], v["tolerated"]
    cref, centre, hw = gl["compliance_ref"], gl["centre"], gl["half_width"]
    phi = gl["inv_k"] * (gl["w_stiffness"] * gl["mean_share"] * cll / cref
                         + gl["w_worst"] * r / hw
                         + gl["w_robust"] * (v["sigma"] / hw + (1 - rho))
                         + gl["w_centre"] * ((e - centre) / hw) ** 2
                         + gl["w_depth"] * (dep - pp["depth_at"] if coupled else dep) ** 2
                         + gl["w_proximity"] * ca.sumsqr(q - pp["q_lin"]))
    lam_f = ca.SX.sym("lam_f")
    lam_g = ca.SX.sym("lam_g", point_row_count())
    H = ca.hessian(lam_f * phi + ca.dot(lam_g, g), w)[0]
    fns = [
        ca.Function("rfsw_pt_info", [w, par], [g, terms, dX]),
        ca.Function("rfsw_pt_fg", [w, par, glob], [phi, g]),
        ca.Function("rfsw_pt_grad", [w, par, glob], [ca.densify(ca.gradient(phi, w))]),
        ca.Function("rfsw_pt_jac", [w, par], [ca.densify(ca.jacobian(g, w))]),
        ca.Function("rfsw_pt_hess", [w, par, glob, lam_f, lam_g], [ca.triu(ca.densify(H))]),
    ]
    compiled = False
    fg_vm = fg_nlp = fns[1]
    if level:
        prefix, flag = COMPILE_LEVELS[level]
        loaded = compile_functions(fns, prefix, fd_index=1, optimise=flag)
        if loaded is not None:
            fns, compiled = loaded[:-1], True
            fg_nlp = loaded[-1]
    info, fg, grad, jac, hess = fns
    pf = PointFunctions(info, fg, grad, jac, hess, tuple(skipped), compiled, fg_vm, fg_nlp)
    _POINT_CACHE[key] = pf
    while len(_POINT_CACHE) > 8:
        _POINT_CACHE.popitem(last=False)
    return pf


#: Waypoints from which a plan waits for the point functions compiled with the compiler's
#: optimisation (``-O1``: kr600_curved_seam's 7.7-15 s of gcc, once per robot, for a Hessian
#: 4x faster than CasADi's virtual machine); below, a plan without that library on disk runs
#: at ``-O0`` (1.4-2.7 s of gcc, 2.7x faster) while it is built (:func:`compile_level`).
COMPILE_MIN_WAYPOINTS = 200
#: The compiled libraries by level: (file name prefix, compiler flag).
COMPILE_LEVELS = {"O1": ("rfsw_point", "-O1"), "O0": ("rfsw_point_O0", "-O0")}


def compile_level(model: ElastostaticModel, K: int, coupled: bool) -> str:
    """How a plan on K waypoints runs the point functions: ``O1`` (compiled with the
    optimisation) from :data:`COMPILE_MIN_WAYPOINTS` on or wherever such a library is already
    compiled (in this process or on disk, :func:`~rfsw_plan.planning.casadi_.library_path`),
    else ``O0``, while the ``O1`` library is built in the background for the plans after this
    one (:func:`~rfsw_plan.planning.casadi_.compile_in_background`, started once per process
    and structure; IPOPT runs on one core, the compiler on another).

    A first plan thus waits only for the quick compile, and the plans after it run optimised.
    Measured on this project's 2-core machine, idle (29 Nov 2026), ``plan()`` warm with each
    library on disk: kr600_curved_seam 2.04 s at ``O0``, 1.64 s at ``O1`` (gcc: 1.4 s at
    ``O0``, 7.7 s at ``O1``); kr600_forming_contour 3.94 s and 3.35 s; zk500_table6_seam 0.574 s
    and 0.526 s; fanuc_butt_1700mm 0.522 s and 0.483 s. Every level gives the same plan bit
    for bit (``tests/test_plan_cache.py``)."""
    key = (*_model_key(model), coupled)
    if K >= COMPILE_MIN_WAYPOINTS or (*key[:-1], "O1", coupled) in _POINT_CACHE:
        return "O1"
    if key not in _OPTIMISED:
        vm = point_functions(model, "", coupled)
        _OPTIMISED[key] = library_path(vm.library, COMPILE_LEVELS["O1"][0])
        if not _OPTIMISED[key].exists():
            compile_in_background(vm.library, *COMPILE_LEVELS["O1"])
    return "O1" if _OPTIMISED[key].exists() else "O0"


@dataclass(frozen=True)
class PlanNLP:
    """A built, unsolved planning NLP; everything needed to inspect or solve it.

    The IPOPT solver itself (:attr:`solver`) is built on first use: a plan that only
    evaluates the NLP (the fine level of the coarse-to-fine solve) never pays for it.

    Attributes:
        cache_key: Key of the built solver (model, K, tolerances).
        nlp_function: ``(x, p) -> (f, g)`` for numeric inspection.
        point: The per-waypoint functions.
        robot: The robot.
        task: The task it plans.
        options: The options it was built with.
        n_joints: n.
        x0: Initial guess, shape (K (n + 5) + 1,) (:func:`x_layout`: the last entry is c_max,
            the largest lateral compliance of the weld waypoints [mm/kN]).
        lbx, ubx: Variable bounds, same shape.
        lbg, ubg: Constraint bounds, shape (22 K + (n + 4)(K - 1) + (K - 1),): the rows of
            :data:`~rfsw_plan.planning.rows.POINT_ROWS` at every waypoint, then the link
            rows of :data:`~rfsw_plan.planning.rows.LINK_ROWS` on every link, then the link
            sums (``travel_speed``) of every link.
        p: Parameter vector.
        links: The link rows' bounds by variable (which family binds, the allowance).
    """

    cache_key: tuple[object, ...]
    nlp_function: ca.Function
    point: PointFunctions
    robot: Robot
    task: PlanTask
    options: PlanOptions
    n_joints: int
    x0: FloatArray
    lbx: FloatArray
    ubx: FloatArray
    lbg: FloatArray
    ubg: FloatArray
    p: FloatArray
    links: LinkBounds

    @property
    def skipped(self) -> tuple[str, ...]:
        """Effects the symbolic model lacks (handled by the outer correction)."""
        return self.point.skipped

    @property
    def n_waypoints(self) -> int:
        """K."""
        return len(self.task)

    @property
    def n_w(self) -> int:
        """Variables per waypoint, n + 5 (:func:`variable_layout`)."""
        return variable_layout(self.n_joints).size

    @property
    def layout(self) -> Layout:
        """Layout of the parameter vector ``p`` (see :func:`problem_layout`)."""
        return problem_layout(self.n_joints, self.n_waypoints)

    @property
    def par(self) -> FloatArray:
        """Per-waypoint parameters, shape (K, n_par) (columns: :func:`point_layout`)."""
        K = self.n_waypoints
        return self.p[self.layout["points"]].reshape(K, n_par(self.n_joints))

    def point_parameter(self, name: str) -> FloatArray:
        """One per-waypoint parameter by name (:func:`point_layout`), shape (K, width)."""
        return self.par[:, point_layout(self.n_joints)[name]]

    @property
    def solver(self) -> ca.Function:
        """The CasADi ``nlpsol`` (IPOPT, exact Hessian, MUMPS); built on first use and cached
        by (model, K, tolerances)."""
        key = self.cache_key
        if key not in _SOLVER_CACHE:
            _SOLVER_CACHE[key] = _build_solver(self.point, self.n_waypoints, self.n_joints,
                                               self.options)
            while len(_SOLVER_CACHE) > 6:
                _SOLVER_CACHE.popitem(last=False)
        return _SOLVER_CACHE[key]

    def constraint_names(self) -> list[str]:
        """Name of every constraint row, e.g. ``window[12]`` or ``joint_step_q3[4]``: the
        declared label and the waypoint (or, for link rows, the link's first waypoint); a link
        row shared by several families on one variable is named by the one that binds there."""
        K = self.n_waypoints
        labels = point_labels()
        names = [f"{c}[{k}]" for k in range(K) for c in labels]
        sums = [f"{f.name}[{k}]" for k in range(K - 1) for f in link_sum_families()]
        return names + self.links.names(self.n_joints) + sums

    def variables(self, x: FloatArray) -> dict[str, FloatArray]:
        """The per-waypoint variables of x by name, NLP units (K, width) (:func:`variable_layout`),
        and ``c_max`` (1,)."""
        x = np.asarray(x, dtype=float)
        xs = x_layout(self.n_joints, self.n_waypoints).split(x)
        W = xs["points"].reshape(self.n_waypoints, self.n_w)
        return {**variable_layout(self.n_joints).split(W), "c_max": xs["c_max"]}

    def unpack(self, x: FloatArray) -> dict[str, FloatArray]:
        """Split a variable vector: q (K, n) [rad], offsets (lateral, normal, along) (K, 3)
        [m], sigma (K,) [mm], tolerated (rho) (K,), c_max [mm/kN] (1,)."""
        v = self.variables(x)
        return {"q": v["q"], "offsets": v["offsets"] * (1.0 / VARIABLE_SCALE["offsets"]),
                "sigma": v["sigma"][:, 0], "tolerated": v["tolerated"][:, 0],
                "c_max": v["c_max"]}

    def stack(self, values: dict[str, Any], c_max: float = 0.0) -> FloatArray:
        """A variable vector x from the per-waypoint variables by name (NLP units, each
        broadcast to (K, width), see :func:`variable_layout`) and c_max [mm/kN]."""
        W = variable_layout(self.n_joints).pack(self.n_waypoints, values)
        return np.append(W.reshape(-1), c_max)

    def point_values(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Per-waypoint (g (K, 22), terms (K, 6), dX (K, 6)) at x (the NLP's own model); the
        columns of g are :data:`POINT_CONSTRAINTS` (by family: the rows' layout), of
        terms :data:`~rfsw_plan.planning.layout.TERMS`."""
        K = self.n_waypoints
        W = x_layout(self.n_joints, K).split(np.asarray(x, dtype=float))["points"]
        g, t, dx = call_dense(_info_map(self.point, K), W.reshape(K, self.n_w), self.par)
        return g, t, dx

    def point_rows(self, x: FloatArray) -> tuple[dict[str, FloatArray], dict[str, FloatArray]]:
        """The per-waypoint rows by family (K, rows) and the terms by name (K, 1) at x."""
        g, terms, _ = self.point_values(x)
        return point_row_layout().split(g), TERMS.split(terms)

    def pack(self, q: FloatArray, offsets: FloatArray) -> FloatArray:
        """A variable vector from q (K, n) [rad] and offsets (K, 3) or (K, 2) [m]; sigma and
        c_max get their tightest feasible values."""
        values: dict[str, Any] = {"q": q, "offsets": offsets3(offsets) * VARIABLE_SCALE["offsets"],
                                  "sigma": 0.0, "tolerated": 0.0}
        _, terms = self.point_rows(self.stack(values))
        e, r = terms["error"][:, 0], terms["worst_case"][:, 0]
        lo, hi = self.p[self.layout["lower"]][0], self.p[self.layout["upper"]][0]  # [mm]
        values["sigma"] = np.maximum(np.maximum(lo - (e - r), (e + r) - hi), 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            rho_k = np.minimum((e - lo) / r, (hi - e) / r)  # r >= ABS_EPS > 0
        values["tolerated"] = float(np.clip(np.min(rho_k), 0.0, 1.0))
        c_max = float(np.max(terms["lateral_compliance"][:, 0]
                             * self.point_parameter("weld")[:, 0]))
        return self.stack(values, c_max)

    def evaluate(self, x: FloatArray) -> tuple[float, FloatArray]:
        """Objective and constraint values at x."""
        f, g = call_dense(self.nlp_function, np.asarray(x, dtype=float), self.p)
        return float(f.ravel()[0]), g.ravel()

    def violations(self, x: FloatArray, tol: float = 1e-6) -> list[tuple[str, float]]:
        """Constraint rows violated by more than tol at x, with the violation (NLP units:
        mm, rad, 1)."""
        _, g = self.evaluate(x)
        v = np.maximum(self.lbg - g, g - self.ubg)
        bad = np.flatnonzero(v > tol)
        if not len(bad):  # the names (one string per row) only for a violated row
            return []
        names = self.constraint_names()
        return [(names[i], float(v[i])) for i in bad]


_INFO_MAPS: OrderedDict[tuple[int, int], ca.Function] = OrderedDict()


def _info_map(pf: PointFunctions, K: int) -> ca.Function:
    """``pf.info`` mapped over K waypoints (cached: building a map costs a few ms)."""
    key = (id(pf), K)
    if key not in _INFO_MAPS:
        _INFO_MAPS[key] = pf.info.map(K)
        while len(_INFO_MAPS) > 16:
            _INFO_MAPS.popitem(last=False)
    return _INFO_MAPS[key]


_BUFFERS: OrderedDict[int, tuple[ca.Function, Any, Any]] = OrderedDict()


def call_dense(fn: ca.Function, *args: FloatArray) -> list[FloatArray]:
    """``fn`` on dense inputs, transposed: each arg (cols, rows) [C order] is CasADi's
    (rows, cols) input, each output comes back as (cols, rows), ``np.asarray(out).T``.

    The same numbers as ``fn(*[a.T for a in args])`` (the same compiled or virtual-machine
    code runs), through CasADi's buffer interface: no conversion to and from ``DM``, which
    on a thousand waypoints costs ten times the evaluation itself (issue 41). Falls back to
    the plain call where CasADi has no buffers or an output is sparse.
    """
    dense = all(fn.sparsity_out(i).is_dense() for i in range(fn.n_out()))
    if not dense or not hasattr(fn, "buffer"):
        return [np.asarray(o).T for o in fn.call([np.asarray(a).T for a in args])]
    key = id(fn)
    if key not in _BUFFERS or _BUFFERS[key][0] is not fn:
        _BUFFERS[key] = (fn, *fn.buffer())
        while len(_BUFFERS) > 16:
            _BUFFERS.popitem(last=False)
    _, buf, evaluate = _BUFFERS[key]
    ins = [np.ascontiguousarray(a, dtype=float) for a in args]
    for i, a in enumerate(ins):
        if a.size != fn.numel_in(i):
            raise ValueError(f"{fn.name()}: input {i} has {a.size} numbers, not "
                             f"{fn.numel_in(i)}")
        buf.set_arg(i, a.data)
    outs = [np.empty((fn.size2_out(i), fn.size1_out(i))) for i in range(fn.n_out())]
    for i, o in enumerate(outs):
        buf.set_res(i, o.data)
    evaluate()
    return outs


@dataclass(frozen=True)
class _Expressions:
    """The NLP's MX graph, shared by the evaluation function and the solver."""

    X: ca.MX
    P: ca.MX
    W: ca.MX
    PAR: ca.MX
    GLOB: ca.MX
    glob: ca.MX
    c_max: ca.MX
    f: ca.MX
    g: ca.MX
    fs: ca.MX


def _mapped(f: ca.Function, K: int) -> ca.Function:
    return f.map(K, "thread", 2) if K >= 256 else f.map(K)


def _expressions(pf: PointFunctions, K: int, n: int) -> _Expressions:
    vl, npar = variable_layout(n), n_par(n)
    nw = vl.size
    xl = x_layout(n, K)
    X = ca.MX.sym("x", xl.size)
    W = ca.reshape(X[xl["points"]], nw, K)
    c_max = X[xl["c_max"]]  # epigraph of the weld waypoints' lateral compliance [mm/kN]
    lay = problem_layout(n, K)
    P = ca.MX.sym("p", lay.size)
    pv = lay.split(P)
    PAR = ca.reshape(pv["points"], npar, K)
    hinv = pv["inv_link"].T
    glob = pv["globals"]
    gl = GLOBALS.split(glob)
    wq, wo = pv["w_smooth_q"], pv["w_smooth_o"]
    GLOB = ca.repmat(glob, 1, K)
    phi, G = _mapped(pf.fg_nlp, K)(W, PAR, GLOB)
    # The weakest waypoint's share of the stiffness term: w_stiffness (1 - share) c_max / cref.
    f = ca.sum2(phi) + gl["w_stiffness"] * (1 - gl["mean_share"]) * c_max / gl["compliance_ref"]
    g_parts = [ca.vec(G) - ca.repmat(ca.DM(epigraph_rows()), K, 1) * c_max]
    fs = ca.MX(0)
    if K > 1:
        dW = W[:, 1:] - W[:, :-1]
        dq = dW[vl["q"], :]
        smooth = slice(OFFSETS[SMOOTHED_OFFSETS[0]].start, OFFSETS[SMOOTHED_OFFSETS[-1]].stop)
        do = dW[vl["offsets"], :][smooth, :]
        fs = (wq * ca.sumsqr(dq * ca.repmat(hinv, n, 1))
              + wo * ca.sumsqr(1e-3 * do * ca.repmat(hinv, do.shape[0], 1))) / (K - 1)
        g_parts.append(ca.vec(ca.vertcat(*(dW[vl[var], :] for var in link_variables()))))
        if link_sum_rows():
            g_parts.append(ca.vec(ca.vertcat(*(G[i_end, 1:] + G[i_start, :-1]
                                               for i_end, i_start in link_sum_rows()))))
    return _Expressions(X, P, W, PAR, GLOB, glob, c_max, f + fs, ca.vertcat(*g_parts), fs)


def _build_eval(pf: PointFunctions, K: int, n: int) -> ca.Function:
    e = _expressions(pf, K, n)
    return ca.Function("plan_eval", [e.X, e.P], [e.f, e.g])


#: IPOPT's MUMPS settings: AMD ordering (``mumps_pivot_order`` 0) and the monotone barrier
#: strategy. On the banded KKT matrix of zk500_table6_seam at 1000 weld waypoints they took the
#: solve from 2.8 s to 1.2 s (minimum of 3, same run, same 18 iterations; METIS, the default
#: ordering, spends its time in the analysis of a matrix whose band AMD already finds).
MUMPS_OPTIONS: dict[str, Any] = {"ipopt.mumps_pivot_order": 0, "ipopt.mu_strategy": "monotone"}


#: How IPOPT starts from x0 (the mirror baseline, or the previous outer iteration's solution):
#: IPOPT's own start, not its warm start. The primal point x0 is used either way; the warm
#: start (``warm_start_init_point``, zero multipliers, x0 pushed 1e-6 off its bounds) begins
#: with the slack, sigma and c_max variables 1e-6 from their bounds while the mirror baseline
#: violates the standstill and depth rows by up to 0.9 mm: the first ~30 steps were 1e-7..1e-4
#: of the Newton step. IPOPT's start (bound_push 0.01, least-squares multipliers) took the
#: coarse solves of zk500_table6_seam at 1000 weld waypoints from 80 + 27 (+ 26) to 29 + 24
#: (+ 18) iterations, to the same objective (10 digits); the written plans moved by at most
#: 0.1 um (the solves end within IPOPT's tolerance elsewhere). The full NLP's first solve at
#: 1000 weld waypoints: 102 -> 25 iterations.
START_OPTIONS: dict[str, Any] = {"ipopt.warm_start_init_point": "no", "ipopt.mu_init": 1e-4}


def _build_solver(pf: PointFunctions, K: int, n: int, opts: PlanOptions) -> ca.Function:
    nw, ng = variable_layout(n).size, point_row_count()
    ex = _expressions(pf, K, n)
    X, P, W, PAR, GLOB, glob = ex.X, ex.P, ex.W, ex.PAR, ex.GLOB, ex.glob
    gl = GLOBALS.split(glob)
    f, g, fs = ex.f, ex.g, ex.fs
    cap_rows = np.flatnonzero(np.tile(epigraph_rows(), K)).tolist()
    cap_col = ca.DM(ca.Sparsity.triplet(ng * K, 1, cap_rows, [0] * len(cap_rows)), -1.0)

    def mapped(fn: ca.Function) -> ca.Function:
        return _mapped(fn, K)

    # Exact derivatives, assembled from the per-waypoint blocks (block diagonal: the map's
    # horizontally stacked dense blocks have the same nonzero order as the block diagonal).
    grad = ca.vertcat(ca.vec(mapped(pf.grad)(W, PAR, GLOB)),
                      gl["w_stiffness"] * (1 - gl["mean_share"]) / gl["compliance_ref"]
                      ) + ca.gradient(fs, X)
    Jb = mapped(pf.jac)(W, PAR)
    J_pts = ca.horzcat(ca.sparsity_cast(Jb, _blockdiag(K, np.ones((ng, nw), bool))), cap_col)
    gl_ = g_layout(n, K)
    S = _link_sum_matrix(K, ng)
    if K > 1:
        J_link = _link_jacobian(K, columns(variable_layout(n), link_variables()), nw,
                                x_layout(n, K).size)
        J = ca.vertcat(J_pts, J_link, *([ca.mtimes(S, J_pts)] if S.shape[0] else []))
    else:
        J = J_pts
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", g.shape[0])
    # A link sum's multiplier acts on the point rows it adds (g_sums = S g_points).
    lam_pts = lam_g[gl_["points"]]
    if S.shape[0]:
        lam_pts = lam_pts + ca.mtimes(S.T, lam_g[gl_["sums"]])
    LG = ca.reshape(lam_pts, ng, K)
    Hb = mapped(pf.hess)(W, PAR, GLOB, ca.repmat(lam_f, 1, K), LG)
    H = ca.diagcat(ca.sparsity_cast(Hb, _blockdiag(K, np.triu(np.ones((nw, nw), bool)))),
                   ca.MX(1, 1))
    if K > 1:
        H = H + lam_f * ca.triu(ca.hessian(fs, X)[0])
    grad_f = ca.Function("grad_f", [X, P], [f, grad], ["x", "p"], ["f", "grad_f_x"])
    jac_g = ca.Function("jac_g", [X, P], [g, J], ["x", "p"], ["g", "jac_g_x"])
    hess = ca.Function("hess_lag", [X, P, lam_f, lam_g], [H],
                       ["x", "p", "lam_f", "lam_g"], ["hess_gamma_x_x"])
    ipopt: dict[str, Any] = {
        "ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
        "ipopt.tol": opts.tol, "ipopt.constr_viol_tol": 1e-7, "ipopt.max_iter": opts.max_iter,
        "ipopt.linear_solver": "mumps", "ipopt.hessian_approximation": "exact",
        **MUMPS_OPTIONS, **START_OPTIONS,
        "grad_f": grad_f, "jac_g": jac_g, "hess_lag": hess, "calc_lam_p": False,
    }
    nlp_dict: dict[str, Any] = {"x": X, "p": P, "f": f, "g": g}
    return ca.nlpsol("plan", "ipopt", nlp_dict, ipopt)


def _link_jacobian(K: int, cols_w: NDArray[np.int_], nw: int, n_x: int) -> ca.DM:
    """The constant Jacobian of the link rows (w_{k+1} - w_k)[cols_w] with respect to x (n_x
    entries, the waypoints' nw variables first): the link row families' blocks (+-1 on the
    columns of the variables they bound, in the order of
    :func:`~rfsw_plan.planning.rows.link_variables`)."""
    m = len(cols_w)
    row = np.arange(m * (K - 1))
    cols = (row // m) * nw + cols_w[row % m]
    r = np.concatenate([row, row]).tolist()
    c = np.concatenate([cols, cols + nw]).tolist()
    v = np.concatenate([-np.ones(row.size), np.ones(row.size)])
    return ca.DM.triplet(r, c, ca.DM(v), m * (K - 1), n_x)


def _link_sum_matrix(K: int, ng: int) -> ca.DM:
    """The constant matrix S with g_sums = S g_points (K - 1 links, ng rows per waypoint): on
    link k, per link-sum family, +1 on its end row at k + 1 and its start row at k."""
    pairs = link_sum_rows()
    m = len(pairs)
    if K < 2 or not m:
        return ca.DM(0, ng * K)
    link = np.repeat(np.arange(K - 1), m)
    fam = np.tile(np.arange(m), K - 1)
    row = link * m + fam
    end = np.array([p[0] for p in pairs])[fam] + (link + 1) * ng
    start = np.array([p[1] for p in pairs])[fam] + link * ng
    return ca.DM.triplet(np.concatenate([row, row]).tolist(),
                         np.concatenate([end, start]).tolist(),
                         ca.DM(np.ones(2 * row.size)), m * (K - 1), ng * K)


def _blockdiag(K: int, block: NDArray[np.bool_]) -> ca.Sparsity:
    """Block-diagonal sparsity of K copies of a block pattern."""
    br, bc = block.shape
    r = np.nonzero(block.T)[1]  # rows in the column-major order of the nonzeros
    rows = (r[None, :] + br * np.arange(K)[:, None]).ravel()
    counts = np.tile(np.count_nonzero(block, axis=0), K)
    colind = np.concatenate([[0], np.cumsum(counts)])
    return ca.Sparsity(br * K, bc * K, colind.tolist(), rows.tolist())


def _det_linearisation(robot: Robot, Q: FloatArray, length_scale: float
                       ) -> tuple[FloatArray, FloatArray]:
    """det J_n at Q (K, n) and its gradient dq (K, n) by central differences (h = 1e-6)."""
    def det(Qx: FloatArray) -> FloatArray:
        _, J = robot.batch_fk_jacobian(Qx)[:2]
        Jn = J.copy()
        Jn[:, :3] /= length_scale
        return np.linalg.det(Jn)

    Q = np.atleast_2d(Q)
    d0 = det(Q)
    grad = np.zeros_like(Q)
    h = 1e-6
    for j in range(Q.shape[1]):
        dQ = np.zeros_like(Q)
        dQ[:, j] = h
        grad[:, j] = (det(Q + dQ) - det(Q - dQ)) / (2 * h)
    return d0, grad


def build_plan_nlp(
    model: ElastostaticModel,
    task: PlanTask,
    window: WeldWindow,
    q_init: FloatArray,
    offsets_init: FloatArray,
    options: PlanOptions | None = None,
    correction: FloatArray | None = None,
    compile_c: bool | None = None,
    load_steps: FloatArray | None = None,
    offset_reference: FloatArray | None = None,
) -> PlanNLP:
    """Build the planning NLP (no solve).

    Args:
        model: Elastostatic model (its robot gives kinematics and limits).
        task: Waypoints, frames and wrenches.
        window: Weld window [m].
        q_init: Warm start [rad], shape (K, n) (taught path or mirror baseline); also where
            the singularity constraint is linearised.
        offsets_init: Warm-start offsets (lateral, normal, along-track) [m], shape (K, 3) (or
            (K, 2)).
        options: Planner options.
        correction: Outer-loop correction of the lateral, normal and along-track error [m],
            shape (K, 3).
        compile_c: Compile the point functions to C (None or True: at :func:`compile_level`'s
            level for K waypoints; False: CasADi's virtual machine).
        load_steps: Offset change the load itself demands on each link (lateral, normal,
            along-track) [m], shape (K - 1, 3), e.g. the mirror baseline's steps; added to the
            bound of every link row family on the offsets (offset rate, offset speed) so the
            bound limits only the *extra* offset change (the force ramps at the weld start
            need offsets that follow them). None: zero.
        offset_reference: Instead of ``load_steps``: offsets (K, 3) [m] (the mirror
            baseline's) whose change the offset link rows follow, |delta (o - o_ref)| <=
            allowance (offset rate * travel...). Tighter than ``load_steps``
            (|delta o| <= allowance + |delta o_ref|); the planner uses it in the coarse and
            the full NLP, so that both solve the same problem (and the coarse solution,
            interpolated as a departure from the mirror offsets, meets the fine NLP's offset
            rows; :func:`~rfsw_plan.planning.verify.verify_plan` checks this form).

    Returns:
        The inspectable :class:`PlanNLP`.
    """
    opts = options or PlanOptions()
    model = model.physical()  # the wrench is modelled: sensor-only effects do not apply
    robot = model.robot
    n, K = robot.nq, len(task)
    coupled = plans_coupled(task)
    level = compile_level(model, K, coupled) if compile_c in (None, True) else ""
    pf = point_functions(model, level, coupled)
    skey = (*_model_key(model), level if pf.compiled else "", coupled, K, opts.tol,
            opts.max_iter)
    ekey = skey[:-2]
    if ekey not in _EVAL_CACHE:
        _EVAL_CACHE[ekey] = _build_eval(pf, K, n)
        while len(_EVAL_CACHE) > 6:
            _EVAL_CACHE.popitem(last=False)
    nlp_fn = _EVAL_CACHE[ekey]

    q_init = np.asarray(q_init, dtype=float)
    p = _parameters(model, task, window, q_init, opts, correction)
    lbx, ubx = _variable_bounds(robot, K, opts)
    lbg, ubg = _point_bounds(window, opts, K, task)
    links = _link_bounds(task, opts, n, load_steps, offset_reference)
    lbs, ubs = _link_sum_bounds(window, opts, K, task)
    nlp = PlanNLP(skey, nlp_fn, pf, robot, task, opts, n, np.zeros(x_layout(n, K).size),
                  lbx, ubx, np.concatenate([lbg, links.lower, lbs]),
                  np.concatenate([ubg, links.upper, ubs]), p, links)
    return replace(nlp, x0=nlp.pack(q_init, np.asarray(offsets_init, dtype=float)))


def plans_coupled(task: PlanTask) -> bool:
    """Whether the NLP plans with the coupled axial law: position control where the problem
    couples the axial force to the penetration (``[process.coupling]``,
    ``task.penetration_stiffness`` k_p > 0), as the robust claim judges it
    (:func:`rfsw_plan.planning.verify.coupled_claim`)."""
    return task.penetration_stiffness > 0 and task.axial_control != "force"


def depth_targets(task: PlanTask, window: WeldWindow) -> FloatArray:
    """The normal pin error the objective centres each waypoint's depth on [m], (K,).

    Without the coupled axial law (:func:`plans_coupled`): 0, the planned depth. With it the
    depth's spread over the force box is symmetric about the nominal depth, +- u r_n with
    r_n = sum_i |f_i| |n^T C_tt b_i| / (1 + k_p n^T C_tt n) (b = t, l, n; the coupled claim's
    linearisation, :func:`rfsw_plan.planning.verify.coupled_claim`: a deeper pin raises the
    force, which lifts the robot back), so the nominal depth that holds the most
    uncertainty is the depth window's centre, (depth_shallow - depth_deep) / 2: there on the
    weld waypoints; on the standing ones at full depth (the plunge's end, the dwell, the weld
    start, where the pin stands at the planned depth, the ``standing_depth`` rows) the point of
    their band nearest to it; 0 elsewhere (the plunge, on its way down)."""
    z = np.zeros(len(task))
    if not plans_coupled(task):
        return z
    centre = 0.5 * (window.depth_shallow - window.depth_deep)
    band = 0.4 * STANDING_DEPTH_TOL
    z[task.phase == "weld"] = centre
    z[task.standing_full] = float(np.clip(centre, -band, band))
    return z


def shortest_weld_link(task: PlanTask) -> float:
    """h_min, the shortest weld link with travel [m] (0 if there is none)."""
    travel = task.link_travel()[task.n_start:]
    travel = travel[travel > 1e-12]
    return float(np.min(travel)) if len(travel) else 0.0


def travel_parameters(task: PlanTask) -> dict[str, FloatArray]:
    """The parameters of the ``travel_speed`` rows (:data:`~rfsw_plan.planning.rows.POINT_ROWS`)
    per waypoint.

    On each weld link k -> k + 1 with travel h_k = s_{k+1} - s_k > 0 the seam point moves along
    the chord u_k = (p_{k+1} - p_k) / |p_{k+1} - p_k| (what the sample check projects the pin's
    velocity on, :func:`~rfsw_plan.planning.verify.seam_direction`), by c_k + h_k with
    c_k = |p_{k+1} - p_k| - h_k. With q = pin - p and w_k = h_min / h_k (h_min:
    :func:`shortest_weld_link`):

    * ``travel_in`` at k + 1: u_k w_k, ``travel_at[0]`` = c_k / 2 w_k [mm];
    * ``travel_out`` at k: -u_k w_k, ``travel_at[1]`` = c_k / 2 w_k [mm];

    so the link sum of link k, ``travel_in`` row at k + 1 plus ``travel_out`` row at k, is
    ((q_{k+1} - q_k) . u_k + c_k) w_k, the pin's travel along u_k less the seam's travel h_k,
    scaled by w_k; 0 where a waypoint has no such link.

    Returns:
        ``travel_in``, ``travel_out`` (K, 3) [1] and ``travel_at`` (K, 2) [mm].
    """
    K, m = len(task), task.n_start
    out = {"travel_in": np.zeros((K, 3)), "travel_out": np.zeros((K, 3)),
           "travel_at": np.zeros((K, 2))}
    h_min = shortest_weld_link(task)
    if K - m < 2 or h_min <= 0:
        return out
    p = task.frames.p[m:]
    h = np.diff(task.frames.s[m:])
    dp = np.diff(p, axis=0)
    chord = np.linalg.norm(dp, axis=1)
    moving = (h > 1e-12) & (chord > 1e-12)
    w = np.where(moving, h_min / np.where(moving, h, 1.0), 0.0)
    u = dp / np.where(moving, chord, 1.0)[:, None] * w[:, None]
    half = np.where(moving, 0.5 * (chord - h), 0.0) * w * 1e3
    out["travel_in"][m + 1:] = u
    out["travel_out"][m:-1] = -u
    out["travel_at"][m + 1:, 0] = half
    out["travel_at"][m:-1, 1] = half
    return out


def _parameters(model: ElastostaticModel, task: PlanTask, window: WeldWindow, q_init: FloatArray,
                opts: PlanOptions, correction: FloatArray | None) -> FloatArray:
    """The parameter vector p (:func:`problem_layout`) of a task, warm start q_init (K, n)
    [rad] and outer correction (K, 3) [m]."""
    n, K = model.robot.nq, len(task)
    fr = task.frames
    corr = np.zeros((K, OFFSETS.size)) if correction is None else np.asarray(correction, float)
    det = _det_parameters(model.robot, q_init, opts)
    PAR = point_layout(n).pack(K, {
        "target": task.target, "t": fr.t, "l": fr.l, "n": fr.n, "wrench": task.wrench_base,
        "force_spread": opts.force_uncertainty * np.abs(task.force_seam) * task.spread_weights,
        "correction": corr * 1e3, **det, "weld": (task.phase == "weld").astype(float),
        "depth_on": (~task.at_surface).astype(float),
        "surface_on": task.at_surface.astype(float),
        "standing": task.standing.astype(float), "stand_at": window.centre * 1e3,
        "standing_full": task.standing_full.astype(float),
        "depth_at": depth_targets(task, window) * 1e3, **travel_parameters(task),
        "t_along": along_tangents(task),
    })
    cll0 = np.einsum("ki,kij,kj->k", fr.l, model.cartesian_compliance(model.batch(q_init))
                     [:, :3, :3], fr.l) * 1e6
    w = opts.weights
    glob = GLOBALS.pack(1, {
        **{k: w[k] for k in ("w_stiffness", "w_worst", "w_robust", "w_centre", "w_depth",
                             "w_proximity")},
        "compliance_ref": max(float(np.mean(cll0)), 1e-12), "centre": window.centre * 1e3,
        "half_width": window.half_width * 1e3, "inv_k": 1.0 / K,
        "mean_share": 1.0 - opts.min_stiffness_share,
        # Under the coupled axial law the depth's held level is part of the claim the
        # robust-first objective maximises: its centring weighs w_depth x w_robust.
        **({"w_depth": w["w_depth"] * w["w_robust"]} if plans_coupled(task) else {}),
    })
    return problem_layout(n, K).pack(1, {
        "points": PAR.reshape(-1), "inv_link": 1.0 / task.link_lengths(), "globals": glob,
        "w_smooth_q": w["w_smooth_q"], "w_smooth_o": w["w_smooth_o"],
        "lower": window.lower * 1e3, "upper": window.upper * 1e3,
    })[0]


def _variable_bounds(robot: Robot, K: int, opts: PlanOptions) -> tuple[FloatArray, FloatArray]:
    """Bounds of x (:func:`x_layout`): joint limits [rad], free offsets, 0 <= sigma (= 0 with
    ``robust_hard``), 0 <= rho <= 1, c_max >= 0."""
    d, vl = robot.description, variable_layout(robot.nq)
    lbw = vl.pack(1, {"q": d.lower, "offsets": -np.inf, "sigma": 0.0, "tolerated": 0.0})[0]
    ubw = vl.pack(1, {"q": d.upper, "offsets": np.inf,
                      "sigma": 0.0 if opts.robust_hard else np.inf, "tolerated": 1.0})[0]
    xl = x_layout(robot.nq, K)
    return (xl.pack(1, {"points": np.tile(lbw, K), "c_max": 0.0})[0],
            xl.pack(1, {"points": np.tile(ubw, K), "c_max": np.inf})[0])


def _bound_context(window: WeldWindow, opts: PlanOptions, task: PlanTask | None
                   ) -> PointBounds:
    h_min = shortest_weld_link(task) if task is not None else 0.0
    return PointBounds(window.lower * 1e3, window.upper * 1e3, opts.margin * 1e3,
                       (-window.depth_deep + opts.margin) * 1e3,
                       (window.depth_shallow - opts.margin) * 1e3,
                       float(np.sin(window.tilt_tol)), 0.5 * window.speed_tol * h_min * 1e3,
                       0.4 * STANDSTILL_MOTION * 1e3, 0.4 * STANDING_DEPTH_TOL * 1e3)


def _link_sum_bounds(window: WeldWindow, opts: PlanOptions, K: int, task: PlanTask
                     ) -> tuple[FloatArray, FloatArray]:
    """Bounds of the link sums of K - 1 links (link-major), from each declaration's
    ``link_sum`` (NLP units)."""
    ctx = _bound_context(window, opts, task)
    pairs = [f.link_sum(ctx) for f in link_sum_families() if f.link_sum is not None]
    if not pairs or K < 2:
        return np.zeros(0), np.zeros(0)
    lb, ub = np.array(pairs, dtype=float).T
    return np.tile(lb, K - 1), np.tile(ub, K - 1)


def _point_bounds(window: WeldWindow, opts: PlanOptions, K: int, task: PlanTask | None = None
                  ) -> tuple[FloatArray, FloatArray]:
    """Bounds of the per-waypoint rows of K waypoints, from each family's declaration (NLP
    units), shape (rows per waypoint x K,) each."""
    ctx = _bound_context(window, opts, task)
    pairs = []
    for f in rows.POINT_ROWS:
        got = f.bounds(ctx)
        if len(got) != len(f.labels):
            raise TypeError(f"row family {f.name!r}: {len(got)} bound pairs for the rows "
                            f"{f.labels}")
        pairs += list(got)
    lb, ub = np.array(pairs, dtype=float).T
    return np.tile(lb, K), np.tile(ub, K)


@dataclass(frozen=True)
class LinkBounds:
    """The link rows' bounds, assembled from :data:`~rfsw_plan.planning.rows.LINK_ROWS`.

    On link k (waypoint k -> k + 1), per component of each bounded variable (NLP units):
    lower = centre - bound, upper = centre + bound, with bound the tightest declared
    scale * allowance + slack, plus the load step (offsets).

    Attributes:
        lower, upper: Row bounds, shape ((K - 1) (n + 4),) (link-major; within a link the
            variables of :func:`~rfsw_plan.planning.rows.link_variables`).
        binding: Per variable, the index among the families on that variable (declaration
            order) whose bound is the tightest, (K - 1, width).
        allowance: Per variable, that family's allowance [SI: rad, m, 1], (K - 1, width),
            without slack and load step: what the fine projection may use.
    """

    lower: FloatArray
    upper: FloatArray
    binding: dict[str, NDArray[np.int_]] = field(default_factory=dict)
    allowance: dict[str, FloatArray] = field(default_factory=dict)

    def names(self, n: int) -> list[str]:
        """Row names ``label[k]``, in row order, named by the binding family."""
        labels = {}
        for var in self.binding:
            fams = link_families(var)
            labels[var] = np.array([f.labels(n) for f in fams])  # (families, width)
        per_link = [
            labels[var][self.binding[var], np.arange(self.binding[var].shape[1])]
            for var in self.binding]
        if not per_link or not len(per_link[0]):
            return []
        table = np.concatenate(per_link, axis=1)  # (K - 1, rows per link)
        return [f"{c}[{k}]" for k, row in enumerate(table.tolist()) for c in row]


def _link_bounds(task: PlanTask, opts: PlanOptions, n: int, load_steps: FloatArray | None,
                 offset_reference: FloatArray | None) -> LinkBounds:
    """The link rows' bounds from their declarations (see :class:`LinkBounds` and
    :func:`build_plan_nlp` for ``load_steps`` and ``offset_reference``)."""
    K1 = len(task) - 1
    if K1 < 1:
        return LinkBounds(np.zeros(0), np.zeros(0))
    ctx = LinkContext(task.link_travel(), task.link_times(), opts)
    vl = variable_layout(n)
    lower, upper, binding, allowance = [], [], {}, {}
    for var in link_variables():
        width, scale = vl.width(var), VARIABLE_SCALE[var]
        fams = link_families(var)
        allow = np.stack([np.broadcast_to(np.asarray(f.allowance(ctx), dtype=float)
                                          .reshape(K1, -1), (K1, width)) for f in fams])
        bound = np.stack([a * scale + f.slack for a, f in zip(allow, fams, strict=True)])
        pick = np.argmin(bound, axis=0)  # the first of equal bounds
        binding[var] = pick
        allowance[var] = np.take_along_axis(allow, pick[None], 0)[0]
        centre, extra = _link_reference(var, K1, width, load_steps, offset_reference)
        half = np.take_along_axis(bound, pick[None], 0)[0] + extra
        lower.append(centre - half)
        upper.append(centre + half)
    return LinkBounds(np.concatenate(lower, axis=1).reshape(-1),
                      np.concatenate(upper, axis=1).reshape(-1), binding, allowance)


def _link_reference(var: str, K1: int, width: int, load_steps: FloatArray | None,
                    offset_reference: FloatArray | None) -> tuple[FloatArray, FloatArray]:
    """Centre and extra half width of a variable's link rows (NLP units), (K - 1, width): for
    the offsets either the reference offsets' change (centre) or the load steps (extra)."""
    zero = np.zeros((K1, width))
    if var != "offsets":
        return zero, zero
    scale = VARIABLE_SCALE[var]
    if offset_reference is not None:
        return np.diff(offsets3(offset_reference), axis=0) * scale, zero
    if load_steps is not None:
        return zero, np.abs(offsets3(load_steps)) * scale
    return zero, zero


#: The last few det linearisations (robot, Q, length scale, result): the second stage and the
#: coarse-to-fine solve build NLPs linearised at the same warm start (13 batch Jacobians each).
_DET_CACHE: list[tuple[Robot, FloatArray, float, tuple[FloatArray, FloatArray]]] = []


def _det_linearisation_cached(robot: Robot, Q: FloatArray, length_scale: float
                              ) -> tuple[FloatArray, FloatArray]:
    """:func:`_det_linearisation`, reused when the same robot object, Q and scale recur."""
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    for r, q, ls, out in _DET_CACHE:
        if r is robot and ls == length_scale and q.shape == Q.shape and np.array_equal(q, Q):
            return out[0].copy(), out[1].copy()
    out = _det_linearisation(robot, Q, length_scale)
    _DET_CACHE.insert(0, (robot, Q.copy(), length_scale, (out[0].copy(), out[1].copy())))
    del _DET_CACHE[4:]
    return out


def _det_parameters(robot: Robot, Q: FloatArray, opts: PlanOptions) -> dict[str, FloatArray]:
    """The singularity row's parameters linearised at Q (K, n) [rad], by name."""
    d0, dd = _det_linearisation_cached(robot, Q, opts.length_scale)
    return {"det_sign": np.where(d0 >= 0, 1.0, -1.0), "det_floor": opts.det_fraction * np.abs(d0),
            "det_value": d0, "q_lin": np.asarray(Q, dtype=float), "det_grad": dd}


def update_parameters(nlp: PlanNLP, correction: FloatArray | None = None,
                      q_lin: FloatArray | None = None) -> PlanNLP:
    """The same NLP with a new outer correction (lateral, normal, along-track) [m] (K, 3)
    and/or the singularity constraint re-linearised at q_lin (K, n) [rad]."""
    pl = point_layout(nlp.n_joints)
    p = nlp.p.copy()
    PAR = nlp.par.copy()
    if correction is not None:
        PAR[:, pl["correction"]] = np.asarray(correction) * 1e3
    if q_lin is not None:
        det = _det_parameters(nlp.robot, np.asarray(q_lin), nlp.options)
        det.pop("det_floor")  # the floor stays where the warm start put it
        for name, value in det.items():
            PAR[:, pl[name]] = value.reshape(len(PAR), -1)
    p[nlp.layout["points"]] = PAR.reshape(-1)
    return replace(nlp, p=p)


@dataclass(frozen=True)
class NLPSolution:
    """Outcome of one IPOPT solve.

    Attributes:
        x: Solution vector.
        q: Joint values [rad], (K, n).
        offsets: Offsets (lateral, normal, along-track) [m], (K, 3).
        sigma: Worst-case excess over the window [m], (K,).
        success: IPOPT reported success.
        status: IPOPT return status.
        iterations: IPOPT iterations.
        solve_time: Wall time [s].
        objective: Objective value.
    """

    x: FloatArray
    q: FloatArray
    offsets: FloatArray
    sigma: FloatArray
    success: bool
    status: str
    iterations: int
    solve_time: float
    objective: float


def solve_plan_nlp(nlp: PlanNLP, x0: FloatArray | None = None) -> NLPSolution:
    """Solve a built NLP with IPOPT, warm-started from ``x0`` (default ``nlp.x0``)."""
    t0 = time.perf_counter()
    with single_thread_blas():
        res = nlp.solver(x0=nlp.x0 if x0 is None else x0, p=nlp.p, lbx=nlp.lbx, ubx=nlp.ubx,
                         lbg=nlp.lbg, ubg=nlp.ubg)
    dt = time.perf_counter() - t0
    stats = nlp.solver.stats()
    status = str(stats.get("return_status", "unknown"))
    # CasADi catches a Ctrl-C inside IPOPT's callbacks and returns the iterate it had: stop
    # here rather than plan on from a solve the user asked to stop.
    files.check_interrupt()
    if status == "User_Requested_Stop":
        raise KeyboardInterrupt
    x = np.asarray(res["x"]).ravel()
    parts = nlp.unpack(x)
    log.info("NLP K=%d: %s in %d iterations, %.3f s", nlp.n_waypoints, status,
             stats.get("iter_count", -1), dt)
    return NLPSolution(x, parts["q"], parts["offsets"], parts["sigma"] * 1e-3,
                       bool(stats.get("success", False)), status,
                       int(stats.get("iter_count", -1)), dt, float(res["f"]))


def nlp_prediction(nlp: PlanNLP, x: FloatArray) -> FloatArray:
    """The NLP's own predicted (lateral, normal, along-track) pin error [m] at x, without the
    outer correction, shape (K, 3)."""
    return terms_prediction(nlp, nlp.point_rows(x)[1])


def terms_prediction(nlp: PlanNLP, terms: dict[str, FloatArray]) -> FloatArray:
    """:func:`nlp_prediction` from the point function's terms by name (:meth:`PlanNLP.point_rows`),
    [m], shape (K, 3)."""
    own = np.column_stack([terms[name][:, 0] for name in ERROR_TERMS])
    return (own - nlp.point_parameter("correction")) * 1e-3
