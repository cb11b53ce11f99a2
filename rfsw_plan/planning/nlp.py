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
* along the track the predicted pin is on the seam point: t_k . (FK_p(q_k) + [C_X(q_k) F_k]_p
  - p_k) + c_t,k = 0. The process model gives F_k for the pin at s_k (the traverse force ramps
  up over the first millimetre of *pin* travel); with this row the pin is there, the lag of
  the pin behind the TCP (several mm while the ramp winds it up) is in o_along, and the weld is
  timed on s_k directly (:mod:`rfsw_plan.timing.trajectory`);
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

Between neighbours: |q_{k+1} - q_k| <= joint step; |o_{k+1} - o_k| <= offset rate * travel
(+ offset speed * time while stationary) + the step the load change itself demands (the mirror
baseline's step; see ``load_steps``), per offset component (the along-track component follows
the traverse-force ramp, which the load step allows).

Objective (weights and priorities in :mod:`rfsw_plan.planning.options`):
w_stiffness share c_max / ref plus the mean over waypoints of
w_stiffness (1 - share) l^T C_tt l / ref + w_worst r_k / hw
+ w_robust (sigma_k / hw + 1 - rho)
+ w_centre ((e_k - centre) / hw)^2 + w_depth (normal error / 1 mm)^2
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
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.planning.casadi_ import compile_functions, single_thread_blas
from rfsw_plan.planning.options import PlanOptions
from rfsw_plan.planning.symbolic import symbolic_cartesian_compliance, symbolic_chain
from rfsw_plan.process.task import PlanTask, offsets3
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]
log = logging.getLogger(__name__)

#: Names of the per-waypoint constraint rows, in order.
POINT_CONSTRAINTS = (
    "position_x", "position_y", "position_z", "axis_t", "axis_l", "axis_n",
    "window", "robust_lower", "robust_upper", "along_track", "singularity", "stiffness_cap",
    "tolerated_lower", "tolerated_upper",
)
#: Names of the terms returned by the point function, in order.
POINT_TERMS = ("lateral_compliance", "worst_case", "robust_excess", "error", "normal_error",
               "along_error")
#: Offset components per waypoint (lateral, normal, along-track).
N_OFF = 3
_NG = len(POINT_CONSTRAINTS)
_CAP = POINT_CONSTRAINTS.index("stiffness_cap")  # the row that - c_max joins
#: Smoothing of |x| in the worst case [mm]: sqrt(x^2 + eps^2) over-estimates |x| by at most eps.
ABS_EPS = 1e-2


@dataclass(frozen=True)
class Layout:
    """Named, contiguous slices of a flat vector, in order.

    One object describes a vector for both sides: :meth:`split` cuts a CasADi symbol (or a
    numpy row) into named parts, :meth:`pack` assembles numeric rows by name, so the symbolic
    unpack and the numeric pack cannot disagree on positions.

    Attributes:
        fields: ``(name, width)`` pairs in order.
    """

    fields: tuple[tuple[str, int], ...]
    _slices: dict[str, slice] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        sl: dict[str, slice] = {}
        i = 0
        for name, width in self.fields:
            if name in sl or width < 0:
                raise ValueError(f"layout field {name!r} repeated or of negative width")
            sl[name] = slice(i, i + width)
            i += width
        object.__setattr__(self, "_slices", sl)

    @property
    def size(self) -> int:
        """Length of the vector."""
        return sum(w for _, w in self.fields)

    @property
    def names(self) -> tuple[str, ...]:
        """Field names in order."""
        return tuple(name for name, _ in self.fields)

    def __getitem__(self, name: str) -> slice:
        return self._slices[name]

    def split(self, v: Any) -> dict[str, Any]:
        """The named parts of a vector v (CasADi column or numpy array: last axis)."""
        if isinstance(v, np.ndarray):
            return {name: v[..., sl] for name, sl in self._slices.items()}
        return {name: v[sl] for name, sl in self._slices.items()}

    def pack(self, rows: int, values: Mapping[str, Any]) -> FloatArray:
        """Numeric rows (rows, size) from every field by name (broadcast to (rows, width)).

        Raises:
            KeyError: A field is missing or a name is not in the layout.
        """
        unknown = set(values) - set(self._slices)
        missing = set(self._slices) - set(values)
        if unknown or missing:
            raise KeyError(f"layout fields unknown {sorted(unknown)} / missing {sorted(missing)}")
        out = np.empty((rows, self.size))
        for name, sl in self._slices.items():
            width = sl.stop - sl.start
            out[:, sl] = np.broadcast_to(
                np.asarray(values[name], dtype=float).reshape(-1, width)
                if np.ndim(values[name]) else float(values[name]), (rows, width))
        return out


def point_layout(n: int) -> Layout:
    """Per-waypoint parameters: nominal target [m], seam frame t, l, n, wrench (base frame)
    [N, Nm], force spread u |f| per seam component [N], outer correction (lateral, normal,
    along-track) [mm], singularity row (sign, floor, det at q_lin, q_lin [rad], d det / dq),
    weld flag."""
    return Layout((("target", 3), ("t", 3), ("l", 3), ("n", 3), ("wrench", 6),
                   ("force_spread", 3), ("correction", 3), ("det_sign", 1), ("det_floor", 1),
                   ("det_value", 1), ("q_lin", n), ("det_grad", n), ("weld", 1)))


#: Global scalars passed to every waypoint: the objective weights, the lateral compliance
#: reference [mm/kN], window centre and half width [mm], 1 / K and the share of the stiffness
#: weight on the mean (1 - ``min_stiffness_share``).
GLOBALS = Layout((("w_stiffness", 1), ("w_worst", 1), ("w_robust", 1), ("w_centre", 1),
                  ("w_depth", 1), ("compliance_ref", 1), ("centre", 1), ("half_width", 1),
                  ("inv_k", 1), ("w_proximity", 1), ("mean_share", 1)))
N_GLOB = GLOBALS.size


def variable_layout(n: int) -> Layout:
    """Variables per waypoint: q [rad] (n), offsets [mm] (3), sigma [mm], and rho, the share
    of the requested force uncertainty the window holds at every waypoint (one value for the
    whole plan, kept equal by the link rows so the KKT matrix stays banded)."""
    return Layout((("q", n), ("offsets", N_OFF), ("sigma", 1), ("tolerated", 1)))


#: Variables tied between neighbours by the link rows: joint steps, offset rates, rho equal.
LINK_ROWS = ("q", "offsets", "tolerated")


def problem_layout(n: int, K: int) -> Layout:
    """The whole parameter vector: K waypoints' parameters (waypoint-major), 1 / link length
    [1/m] (K - 1), the globals, the smoothing weights and the window bounds [mm]."""
    return Layout((("points", point_layout(n).size * K), ("inv_link", max(K - 1, 0)),
                   ("globals", N_GLOB), ("w_smooth_q", 1), ("w_smooth_o", 1),
                   ("lower", 1), ("upper", 1)))


def n_par(n: int) -> int:
    """Per-waypoint parameters (see :func:`point_layout`)."""
    return point_layout(n).size


def _model_key(model: ElastostaticModel) -> tuple[object, ...]:
    d = model.robot.description
    return (d.name, d.tool.tobytes(), model.robot.geometry.placements.tobytes(),
            model.robot.coupling.tobytes(),
            tuple((e.label, e.params.tobytes()) for e in model.effects))


@dataclass(frozen=True)
class PointFunctions:
    """Per-waypoint CasADi functions (SX, optionally compiled to C).

    Attributes:
        info: ``(w, par) -> (g (12,), terms (6,), dX (6,))``.
        fg: ``(w, par, glob) -> (phi, g)``, phi the waypoint's objective share.
        grad: ``(w, par, glob) -> grad phi (n + 4,)``.
        jac: ``(w, par) -> dg/dw`` dense (12, n + 4).
        hess: ``(w, par, glob, lam_f, lam_g) -> triu of the Hessian of lam_f phi + lam_g . g``
            dense upper triangle (n + 4, n + 4).
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


_POINT_CACHE: OrderedDict[tuple[object, ...], PointFunctions] = OrderedDict()
_SOLVER_CACHE: OrderedDict[tuple[object, ...], ca.Function] = OrderedDict()
_EVAL_CACHE: OrderedDict[tuple[object, ...], ca.Function] = OrderedDict()


def point_functions(model: ElastostaticModel, compile_c: bool = False) -> PointFunctions:
    """The per-waypoint functions of the NLP (see :class:`PointFunctions`).

    Args:
        model: Elastostatic model; its joint and tilting compliance enter symbolically.
        compile_c: Compile them to C with the system compiler (cached on disk, see
            :func:`_compile`); falls back to the CasADi virtual machine if that fails.
    """
    key = (*_model_key(model), compile_c)
    if key in _POINT_CACHE:
        return _POINT_CACHE[key]
    robot = model.robot
    n = robot.nq
    vl, pl = variable_layout(n), point_layout(n)
    w = ca.SX.sym("w", vl.size)
    par = ca.SX.sym("par", pl.size)
    glob = ca.SX.sym("glob", N_GLOB)
    v, pp, gl = vl.split(w), pl.split(par), GLOBALS.split(glob)
    q, o, sigma, rho = v["q"], v["offsets"], v["sigma"], v["tolerated"]
    target, t, l, nn = pp["target"], pp["t"], pp["l"], pp["n"]
    F, uf, corr = pp["wrench"], pp["force_spread"], pp["correction"]
    det_sign, det_floor, det0 = pp["det_sign"], pp["det_floor"], pp["det_value"]
    q_lin, ddet, weld_flag = pp["q_lin"], pp["det_grad"], pp["weld"]
    ch = symbolic_chain(robot, q)
    C, skipped = symbolic_cartesian_compliance(model, ch)
    dX = C @ F
    z = ch.R[:, 2]
    pos = 1e3 * (ch.p - target) - o[0] * l - o[1] * nn - o[2] * t
    pin_err = ch.p + dX[:3] - target
    e = 1e3 * ca.dot(l, pin_err) + corr[0]
    dep = 1e3 * ca.dot(nn, pin_err) + corr[1]
    along = 1e3 * ca.dot(t, pin_err) + corr[2]
    lC = C[:3, :3] @ l
    proj = ca.vertcat(*(1e3 * uf[i] * ca.dot(lC, b) for i, b in enumerate((t, l, nn))))
    r = ca.sum1(ca.sqrt(proj ** 2 + ABS_EPS ** 2))
    cll = 1e6 * ca.dot(l, lC)  # lateral compliance [mm/kN]
    g = ca.vertcat(
        pos, ca.dot(z, t), ca.dot(z, l), ca.dot(z, nn), e,
        e - r + sigma, e + r - sigma, along,
        det_sign * (det0 + ca.dot(ddet, q - q_lin)) - det_floor,
        weld_flag * cll,  # - c_max (the global epigraph variable) is added in the NLP
        e - rho * r, e + rho * r,
    )
    terms = ca.vertcat(cll, r, sigma, e, dep, along)
    cref, centre, hw = gl["compliance_ref"], gl["centre"], gl["half_width"]
    phi = gl["inv_k"] * (gl["w_stiffness"] * gl["mean_share"] * cll / cref
                         + gl["w_worst"] * r / hw
                         + gl["w_robust"] * (sigma / hw + (1 - rho))
                         + gl["w_centre"] * ((e - centre) / hw) ** 2 + gl["w_depth"] * dep ** 2
                         + gl["w_proximity"] * ca.sumsqr(q - q_lin))
    lam_f = ca.SX.sym("lam_f")
    lam_g = ca.SX.sym("lam_g", _NG)
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
    if compile_c:
        loaded = compile_functions(fns, "rfsw_point", fd_index=1)
        if loaded is not None:
            fns, compiled = loaded[:-1], True
            fg_nlp = loaded[-1]
    info, fg, grad, jac, hess = fns
    pf = PointFunctions(info, fg, grad, jac, hess, tuple(skipped), compiled, fg_vm, fg_nlp)
    _POINT_CACHE[key] = pf
    while len(_POINT_CACHE) > 8:
        _POINT_CACHE.popitem(last=False)
    return pf


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
        x0: Initial guess, shape (K (n + 4) + 1,) (the last entry is c_max, the largest
            lateral compliance of the weld waypoints [mm/kN]).
        lbx, ubx: Variable bounds, same shape.
        lbg, ubg: Constraint bounds, shape (12 K + (n + 3)(K - 1),).
        p: Parameter vector.
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
        """Name of every constraint row, e.g. ``window[12]`` or ``joint_step_q3[4]``."""
        K, n = self.n_waypoints, self.n_joints
        names = [f"{c}[{k}]" for k in range(K) for c in POINT_CONSTRAINTS]
        link = [f"joint_step_q{j + 1}" for j in range(n)] + [
            "offset_rate_lat", "offset_rate_norm", "offset_rate_along", "tolerated_link"]
        names += [f"{c}[{k}]" for k in range(K - 1) for c in link]
        return names

    def unpack(self, x: FloatArray) -> dict[str, FloatArray]:
        """Split a variable vector: q (K, n) [rad], offsets (lateral, normal, along) (K, 3)
        [m], sigma (K,) [mm], c_max [mm/kN]."""
        n = self.n_joints
        x = np.asarray(x, dtype=float)
        W = x[:-1].reshape(self.n_waypoints, self.n_w)
        return {"q": W[:, :n], "offsets": W[:, n:n + N_OFF] * 1e-3, "sigma": W[:, n + N_OFF],
                "tolerated": W[:, n + N_OFF + 1], "c_max": x[-1:]}

    def point_values(self, x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Per-waypoint (g (K, 12), terms (K, 6), dX (K, 6)) at x (the NLP's own model)."""
        K = self.n_waypoints
        W = np.asarray(x, dtype=float)[: K * self.n_w].reshape(K, self.n_w)
        g, t, dx = _info_map(self.point, K)(W.T, self.par.T)
        return np.asarray(g).T, np.asarray(t).T, np.asarray(dx).T

    def pack(self, q: FloatArray, offsets: FloatArray) -> FloatArray:
        """A variable vector from q (K, n) [rad] and offsets (K, 3) or (K, 2) [m]; sigma and
        c_max get their tightest feasible values."""
        n = self.n_joints
        W = np.zeros((self.n_waypoints, self.n_w))
        W[:, :n] = q
        W[:, n:n + N_OFF] = offsets3(offsets) * 1e3
        x = np.append(W.reshape(-1), 0.0)
        _, terms, _ = self.point_values(x)
        e, r = terms[:, 3], terms[:, 1]
        lo, hi = self.p[self.layout["lower"]][0], self.p[self.layout["upper"]][0]  # [mm]
        W[:, n + N_OFF] = np.maximum(np.maximum(lo - (e - r), (e + r) - hi), 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            rho_k = np.minimum((e - lo) / r, (hi - e) / r)  # r >= ABS_EPS > 0
        W[:, n + N_OFF + 1] = float(np.clip(np.min(rho_k), 0.0, 1.0))
        c_max = float(np.max(terms[:, 0] * self.point_parameter("weld")[:, 0]))
        return np.append(W.reshape(-1), c_max)

    def evaluate(self, x: FloatArray) -> tuple[float, FloatArray]:
        """Objective and constraint values at x."""
        f, g = self.nlp_function(x, self.p)
        return float(f), np.asarray(g).ravel()

    def violations(self, x: FloatArray, tol: float = 1e-6) -> list[tuple[str, float]]:
        """Constraint rows violated by more than tol at x, with the violation (NLP units:
        mm, rad, 1)."""
        _, g = self.evaluate(x)
        v = np.maximum(self.lbg - g, g - self.ubg)
        names = self.constraint_names()
        return [(names[i], float(v[i])) for i in np.flatnonzero(v > tol)]


_INFO_MAPS: OrderedDict[tuple[int, int], ca.Function] = OrderedDict()


def _info_map(pf: PointFunctions, K: int) -> ca.Function:
    """``pf.info`` mapped over K waypoints (cached: building a map costs a few ms)."""
    key = (id(pf), K)
    if key not in _INFO_MAPS:
        _INFO_MAPS[key] = pf.info.map(K)
        while len(_INFO_MAPS) > 16:
            _INFO_MAPS.popitem(last=False)
    return _INFO_MAPS[key]


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
    nw, npar = variable_layout(n).size, n_par(n)
    X = ca.MX.sym("x", nw * K + 1)
    W = ca.reshape(X[: nw * K], nw, K)
    c_max = X[nw * K]  # epigraph of the weld waypoints' lateral compliance [mm/kN]
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
    cap = np.zeros(_NG)
    cap[_CAP] = 1.0
    g_parts = [ca.vec(G) - ca.repmat(ca.DM(cap), K, 1) * c_max]
    fs = ca.MX(0)
    if K > 1:
        dW = W[:, 1:] - W[:, :-1]
        dq, do, drho = dW[:n, :], dW[n:n + N_OFF, :], dW[n + N_OFF + 1, :]
        fs = (wq * ca.sumsqr(dq * ca.repmat(hinv, n, 1))
              + wo * ca.sumsqr(1e-3 * do[:2, :] * ca.repmat(hinv, 2, 1))) / (K - 1)
        g_parts.append(ca.vec(ca.vertcat(dq, do, drho)))
    return _Expressions(X, P, W, PAR, GLOB, glob, c_max, f + fs, ca.vertcat(*g_parts), fs)


def _build_eval(pf: PointFunctions, K: int, n: int) -> ca.Function:
    e = _expressions(pf, K, n)
    return ca.Function("plan_eval", [e.X, e.P], [e.f, e.g])


#: IPOPT's MUMPS settings: AMD ordering (``mumps_pivot_order`` 0) and the monotone barrier
#: strategy. On the banded KKT matrix of zk500_table6_seam at 1000 weld waypoints they took the
#: solve from 2.8 s to 1.2 s (minimum of 3, same run, same 18 iterations; METIS, the default
#: ordering, spends its time in the analysis of a matrix whose band AMD already finds).
MUMPS_OPTIONS: dict[str, Any] = {"ipopt.mumps_pivot_order": 0, "ipopt.mu_strategy": "monotone"}


def _build_solver(pf: PointFunctions, K: int, n: int, opts: PlanOptions) -> ca.Function:
    nw = variable_layout(n).size
    ex = _expressions(pf, K, n)
    X, P, W, PAR, GLOB, glob = ex.X, ex.P, ex.W, ex.PAR, ex.GLOB, ex.glob
    gl = GLOBALS.split(glob)
    f, g, fs = ex.f, ex.g, ex.fs
    cap_col = ca.DM(ca.Sparsity.triplet(_NG * K, 1, list(range(_CAP, _NG * K, _NG)),
                                        [0] * K), -1.0)

    def mapped(fn: ca.Function) -> ca.Function:
        return _mapped(fn, K)

    # Exact derivatives, assembled from the per-waypoint blocks (block diagonal: the map's
    # horizontally stacked dense blocks have the same nonzero order as the block diagonal).
    grad = ca.vertcat(ca.vec(mapped(pf.grad)(W, PAR, GLOB)),
                      gl["w_stiffness"] * (1 - gl["mean_share"]) / gl["compliance_ref"]
                      ) + ca.gradient(fs, X)
    Jb = mapped(pf.jac)(W, PAR)
    J_pts = ca.horzcat(ca.sparsity_cast(Jb, _blockdiag(K, np.ones((_NG, nw), bool))), cap_col)
    if K > 1:
        J_link = _link_jacobian(K, _link_columns(n), nw)
        J = ca.vertcat(J_pts, J_link)
    else:
        J = J_pts
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", g.shape[0])
    LG = ca.reshape(lam_g[: _NG * K], _NG, K)
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
        **MUMPS_OPTIONS, "ipopt.warm_start_init_point": "yes",
        # Push the warm start 1e-6 off its bounds: at 1e-9 (the warm start's sigma, slack and
        # c_max rows sit exactly on their bounds) the first steps were ~1e-8 long and IPOPT
        # needed about twice the iterations (34 instead of 18 at 1000 waypoints).
        "ipopt.warm_start_bound_push": 1e-6, "ipopt.warm_start_mult_bound_push": 1e-6,
        "ipopt.mu_init": 1e-4,
        "grad_f": grad_f, "jac_g": jac_g, "hess_lag": hess, "calc_lam_p": False,
    }
    nlp_dict: dict[str, Any] = {"x": X, "p": P, "f": f, "g": g}
    return ca.nlpsol("plan", "ipopt", nlp_dict, ipopt)


def _link_columns(n: int) -> NDArray[np.int_]:
    """Positions in a waypoint's variables of the link rows' variables (:data:`LINK_ROWS`)."""
    vl = variable_layout(n)
    return np.concatenate([np.arange(vl[name].start, vl[name].stop) for name in LINK_ROWS])


def _link_jacobian(K: int, cols_w: NDArray[np.int_], nw: int) -> ca.DM:
    """The constant Jacobian of the link rows (w_{k+1} - w_k)[cols_w] with respect to x."""
    m = len(cols_w)
    rows = np.arange(m * (K - 1))
    cols = (rows // m) * nw + cols_w[rows % m]
    r = np.concatenate([rows, rows]).tolist()
    c = np.concatenate([cols, cols + nw]).tolist()
    v = np.concatenate([-np.ones(rows.size), np.ones(rows.size)])
    return ca.DM.triplet(r, c, ca.DM(v), m * (K - 1), nw * K + 1)


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
        compile_c: Compile the point functions to C; None: when K >= 200 or already cached.
        load_steps: Offset change the load itself demands on each link (lateral, normal,
            along-track) [m], shape (K - 1, 3), e.g. the mirror baseline's steps; added to the
            offset-rate bound so the bound limits only the *extra* offset change (the force
            ramps at the weld start need offsets that follow them). None: zero.
        offset_reference: Instead of ``load_steps``: offsets (K, 3) [m] (the mirror
            baseline's) whose change the offset-rate rows follow, |delta (o - o_ref)| <=
            offset rate * travel. Tighter than ``load_steps`` (|delta o| <= rate * travel +
            |delta o_ref|); the coarse NLP uses it so that its solution, interpolated as a
            departure from the mirror offsets, meets the fine NLP's offset-rate rows.

    Returns:
        The inspectable :class:`PlanNLP`.
    """
    opts = options or PlanOptions()
    model = model.physical()  # the wrench is modelled: sensor-only effects do not apply
    robot = model.robot
    n, K = robot.nq, len(task)
    if compile_c is None:
        compile_c = K >= 200 or (*_model_key(model), True) in _POINT_CACHE
    pf = point_functions(model, compile_c)
    skey = (*_model_key(model), pf.compiled, K, opts.tol, opts.max_iter)
    ekey = skey[:-2]
    if ekey not in _EVAL_CACHE:
        _EVAL_CACHE[ekey] = _build_eval(pf, K, n)
        while len(_EVAL_CACHE) > 6:
            _EVAL_CACHE.popitem(last=False)
    nlp_fn = _EVAL_CACHE[ekey]

    q_init = np.asarray(q_init, dtype=float)
    fr = task.frames
    corr = np.zeros((K, N_OFF)) if correction is None else np.asarray(correction, dtype=float)
    pl = point_layout(n)
    det = _det_parameters(robot, q_init, opts)
    PAR = pl.pack(K, {
        "target": task.target, "t": fr.t, "l": fr.l, "n": fr.n, "wrench": task.wrench_base,
        "force_spread": opts.force_uncertainty * np.abs(task.force_seam),
        "correction": corr * 1e3, **det, "weld": (task.phase == "weld").astype(float),
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
    })
    p = problem_layout(n, K).pack(1, {
        "points": PAR.reshape(-1), "inv_link": 1.0 / task.link_lengths(), "globals": glob,
        "w_smooth_q": w["w_smooth_q"], "w_smooth_o": w["w_smooth_o"],
        "lower": window.lower * 1e3, "upper": window.upper * 1e3,
    })[0]

    d = robot.description
    lbw = np.concatenate([d.lower, np.full(N_OFF, -np.inf), [0.0, 0.0]])
    ubw = np.concatenate([d.upper, np.full(N_OFF, np.inf),
                          [0.0 if opts.robust_hard else np.inf, 1.0]])
    lbx, ubx = np.append(np.tile(lbw, K), 0.0), np.append(np.tile(ubw, K), np.inf)
    lo, hi = window.lower * 1e3, window.upper * 1e3
    m = opts.margin * 1e3
    bounds = {  # per-waypoint rows by name (:data:`POINT_CONSTRAINTS`), NLP units
        "position_x": (0.0, 0.0), "position_y": (0.0, 0.0), "position_z": (0.0, 0.0),
        "axis_t": (0.0, 0.0), "axis_l": (0.0, 0.0), "axis_n": (-1.5, -0.5),
        "window": (lo + m, hi - m), "robust_lower": (lo, np.inf), "robust_upper": (-np.inf, hi),
        "along_track": (0.0, 0.0), "singularity": (0.0, np.inf),
        "stiffness_cap": (-np.inf, 0.0),
        "tolerated_lower": (lo, np.inf), "tolerated_upper": (-np.inf, hi),
    }
    lbp = np.array([bounds[c][0] for c in POINT_CONSTRAINTS])
    ubp = np.array([bounds[c][1] for c in POINT_CONSTRAINTS])
    lbg_parts, ubg_parts = [np.tile(lbp, K)], [np.tile(ubp, K)]
    if K > 1:
        ds = task.link_travel()
        dt = task.link_times()
        stationary = ds <= 1e-12
        o_step = (opts.offset_rate * ds + np.where(stationary, opts.offset_speed_stationary
                                                   * dt, 0.0)) * 1e3 + 1e-6
        extra = (np.zeros((K - 1, N_OFF)) if load_steps is None or offset_reference is not None
                 else np.abs(offsets3(load_steps)) * 1e3)
        centre = np.zeros((K - 1, n + N_OFF + 1))
        if offset_reference is not None:
            centre[:, n:n + N_OFF] = np.diff(offsets3(offset_reference), axis=0) * 1e3
        link_hi = np.column_stack([np.full((K - 1, n), opts.joint_step),
                                   o_step[:, None] + extra, np.zeros(K - 1)])
        lbg_parts.append((centre - link_hi).reshape(-1))
        ubg_parts.append((centre + link_hi).reshape(-1))
    nlp = PlanNLP(skey, nlp_fn, pf, robot, task, opts, n,
                  np.zeros(variable_layout(n).size * K + 1),
                  lbx, ubx,
                  np.concatenate(lbg_parts), np.concatenate(ubg_parts), p)
    return replace(nlp, x0=nlp.pack(q_init, np.asarray(offsets_init, dtype=float)))


def _det_parameters(robot: Robot, Q: FloatArray, opts: PlanOptions) -> dict[str, FloatArray]:
    """The singularity row's parameters linearised at Q (K, n) [rad], by name."""
    d0, dd = _det_linearisation(robot, Q, opts.length_scale)
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
    x = np.asarray(res["x"]).ravel()
    parts = nlp.unpack(x)
    status = str(stats.get("return_status", "unknown"))
    log.info("NLP K=%d: %s in %d iterations, %.3f s", nlp.n_waypoints, status,
             stats.get("iter_count", -1), dt)
    return NLPSolution(x, parts["q"], parts["offsets"], parts["sigma"] * 1e-3,
                       bool(stats.get("success", False)), status,
                       int(stats.get("iter_count", -1)), dt, float(res["f"]))


def nlp_prediction(nlp: PlanNLP, x: FloatArray) -> FloatArray:
    """The NLP's own predicted (lateral, normal, along-track) pin error [m] at x, without the
    outer correction, shape (K, 3)."""
    _, terms, _ = nlp.point_values(x)
    return (terms[:, [3, 4, 5]] - nlp.point_parameter("correction")) * 1e-3
