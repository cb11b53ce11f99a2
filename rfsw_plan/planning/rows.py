"""The planning NLP's constraint rows, each family declared once, by name.

As crocoddyl's ``ConstraintModelManager.addConstraint(name, constraint)`` assembles per-node
residuals and their bounds from named parts, the NLP (:mod:`rfsw_plan.planning.nlp`) is
assembled from the declarations in :data:`POINT_ROWS` and :data:`LINK_ROWS`, in their order.
A declaration gives everything about its rows:

* its **expression**: a CasADi expression of one waypoint's quantities (:class:`PointRows`;
  with ``link_sum``, two terms whose sum over the ends of a link is bounded, one row per
  link), or the change of one variable between neighbouring waypoints (:class:`LinkRows`; the
  rows are linear, their block of the constant link Jacobian is +-1 on that variable's
  columns);
* its **bounds**, by row name, in NLP units (mm, rad, 1);
* its **independent numeric check**: the name of a check in
  :data:`rfsw_plan.planning.verify.ROW_CHECKS`, which :func:`~rfsw_plan.planning.verify.verify_plan`
  runs with the numeric model (no CasADi), or, for rows that only serve the objective (an
  epigraph, a slack), the reason there is nothing to check. ``verify.py`` refuses to import if
  a declared check does not exist;
* its **fine-projection check**: the coarse-to-fine solve (:mod:`rfsw_plan.planning.coarse`)
  checks every declared row at IPOPT's tolerance, and interpolates the offsets inside the
  per-link allowance of the link rows declared on ``offsets``.

Nothing else indexes a row by position. Link rows that bound the same variable share its rows
in the NLP: the bound on each link is the tightest declared one (the same feasible set without
duplicate, linearly dependent rows; a bound that never binds leaves the NLP as it was). Each is
still checked on its own in ``verify``.

A new row family is one declaration here, its check in ``verify.py`` and its test (see
``docs/dev/nlp-rows.md``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rfsw_plan.planning.layout import OFFSET_LABELS, FloatArray, Layout
from rfsw_plan.process.plan_options import PlanOptions

if TYPE_CHECKING:
    import casadi as ca
else:
    class _CasadiOnUse:
        """CasADi, imported when a row expression is first built: the declarations (names,
        bounds, checks) are read by the verification of a written plan (``export``,
        ``check``), which never needs CasADi."""

        def __getattr__(self, name: str) -> Any:
            import casadi

            return getattr(casadi, name)

    ca = _CasadiOnUse()

INF = float("inf")
#: The NLP keeps the pin at the plunge start at least this far above the surface [mm], so that
#: the outer correction's residual (``outer_tol``, 1e-6 m) cannot put it below (the check
#: requires >= 0).
SURFACE_LIFT = 0.005


@dataclass(frozen=True)
class PointSymbols:
    """What a per-waypoint row is written in: one waypoint's CasADi (SX) quantities, NLP units.

    With p the nominal target, (t, l, n) the seam frame, F the wrench (base frame), C the
    Cartesian compliance of the symbolic model (seed 000 eq. 11, seed 002 eq. 2) and
    c = (c_lat, c_norm, c_along) the outer correction:

    Attributes:
        v: The waypoint's variables by name (:func:`~rfsw_plan.planning.layout.variable_layout`):
            ``q`` [rad] (n,), ``offsets`` [mm] (3,), ``sigma`` [mm], ``tolerated`` (rho) [1].
        par: The waypoint's parameters by name (:func:`~rfsw_plan.planning.layout.point_layout`).
        position: Commanded TCP position FK_p(q) - (p + o_lat l + o_norm n + o_along t) [mm],
            base frame, (3,).
        axis: The TCP z axis R(q) e_z, base frame, (3,).
        error: Lateral pin error e = l . (FK_p + [C F]_p - p) + c_lat [mm].
        normal_error: n . (FK_p + [C F]_p - p) + c_norm [mm].
        along_error: t_p . (FK_p + [C F]_p - p) + c_along [mm], t_p the seam tangent in
            the plate's plane (:func:`~rfsw_plan.planning.verify.along_tangents`).
        pin: The predicted pin against the target, FK_p + [C F]_p - p + c_lat l + c_norm n
            + c_along t_p [mm], base frame, (3,).
        worst: Worst case over the force box, r = sum_i u |f_i| |l^T C_tt b_i| (smooth |.|)
            [mm].
        compliance: Lateral compliance l^T C_tt l [mm/kN].
    """

    v: dict[str, Any]
    par: dict[str, Any]
    position: Any
    axis: Any
    error: Any
    normal_error: Any
    along_error: Any
    pin: Any
    worst: Any
    compliance: Any


@dataclass(frozen=True)
class PointBounds:
    """What the bounds of per-waypoint rows depend on, NLP units.

    Attributes:
        lower, upper: Weld window bounds [mm].
        margin: Margin of the nominal error to the window bounds [mm].
        depth_lower, depth_upper: Bounds of the normal pin error (positive: shallower than
            planned) with the margin [mm] (the weld window's depth_deep and depth_shallow).
        tilt: sin of the tilt tolerance [1].
        along: Half the pin's travel speed band on the shortest weld link h_min [mm]:
            speed_tol x h_min / 2 (the ``travel_speed`` link sums, scaled to h_min): the other
            half is for the pin's motion between the waypoints, which the timing interpolates
            (kr600_forming_contour: the link at s = 62 mm, +4.13 % on average, reached
            +5.08 % at a sample).
        stand: Half the pin's lateral motion allowed while the tool stands in the plate,
            less a 20 % share for the motion between waypoints [mm].
        stand_depth: Largest normal pin error while the tool stands at full depth, less a
            60 % share for the NLP model's residual and the motion between waypoints [mm].
    """

    lower: float
    upper: float
    margin: float
    depth_lower: float = -INF
    depth_upper: float = INF
    tilt: float = 1.0
    along: float = INF
    stand: float = INF
    stand_depth: float = INF


@dataclass(frozen=True)
class LinkContext:
    """What the allowance of link rows depends on (SI).

    Attributes:
        travel: Travel along the seam of each link [m], (K - 1,) (0 while stationary).
        time: Time of each link in the schedule [s], (K - 1,).
        options: The planner options.
    """

    travel: FloatArray
    time: FloatArray
    options: PlanOptions

    @property
    def stationary(self) -> Any:
        """Links without travel (plunge and dwell), (K - 1,) bool."""
        return self.travel <= 1e-12


@dataclass(frozen=True)
class PointRows:
    """A family of rows at every waypoint.

    Attributes:
        name: Family name (unique among all rows).
        labels: Name of each row, in order (``position_x``...); a row of waypoint k is named
            ``label[k]`` in :meth:`~rfsw_plan.planning.nlp.PlanNLP.constraint_names`.
        expression: ``PointSymbols -> SX`` of shape (len(labels),).
        bounds: ``PointBounds -> ((lower, upper), ...)``, one pair per label (NLP units).
        check: Name of the independent check in :data:`rfsw_plan.planning.verify.ROW_CHECKS`.
        unchecked: Instead of ``check``: why these rows need no check of the plan (they only
            define an auxiliary variable of the objective).
        epigraph: The global variable c_max (last entry of x) is subtracted from these rows:
            row = expression - c_max.
        link_sum: For a quantity of a link that is a sum of one term of each of its
            waypoints: ``PointBounds -> (lower, upper)`` of (first row at k + 1) + (second
            row at k) on every link k -> k + 1 (NLP units), one row per link named after the
            family (``travel_speed[k]``, after the link rows). The family has two rows, which
            are not bounded at a waypoint (``bounds`` gives them (-inf, inf)).
    """

    name: str
    labels: tuple[str, ...]
    expression: Callable[[PointSymbols], Any]
    bounds: Callable[[PointBounds], tuple[tuple[float, float], ...]]
    check: str | None = None
    unchecked: str = ""
    epigraph: bool = False
    link_sum: Callable[[PointBounds], tuple[float, float]] | None = None

    def __post_init__(self) -> None:
        _check_or_reason(self.name, self.check, self.unchecked)
        if self.link_sum is not None and len(self.labels) != 2:
            raise TypeError(f"row family {self.name!r}: a link sum needs two rows (the terms "
                            f"of the link's end and start), not {self.labels}")


@dataclass(frozen=True)
class LinkRows:
    """A family of rows on every link k -> k + 1: |w_{k+1} - w_k - centre_k| <= bound_k per
    component of one variable (NLP units), with

        bound_k = scale * allowance_k + slack + load step_k,

    scale the variable's NLP scale (1e3 for offsets), the load step the offset change the load
    itself demands (the mirror baseline's; offsets only, see
    :func:`~rfsw_plan.planning.nlp.build_plan_nlp`), centre_k 0 (or the reference offsets'
    change for the coarse NLP).

    Attributes:
        name: Family name (unique among all rows).
        variable: The field of :func:`~rfsw_plan.planning.layout.variable_layout` it bounds.
        labels: ``n -> row names``, one per component of the variable (n: joints).
        allowance: ``LinkContext -> allowance`` in SI units of the variable (rad, m, 1), shape
            (K - 1,) or (K - 1, width); inf where the family does not bound a link.
        slack: Added to the bound in NLP units (mm for offsets), so that a warm start exactly
            on the bound is strictly feasible.
        check: Name of the independent check in :data:`rfsw_plan.planning.verify.ROW_CHECKS`.
        unchecked: Instead of ``check``: why these rows need no check of the plan.
    """

    name: str
    variable: str
    labels: Callable[[int], tuple[str, ...]]
    allowance: Callable[[LinkContext], FloatArray]
    slack: float = 0.0
    check: str | None = None
    unchecked: str = ""

    def __post_init__(self) -> None:
        _check_or_reason(self.name, self.check, self.unchecked)


def _check_or_reason(name: str, check: str | None, unchecked: str) -> None:
    if (check is None) == (not unchecked):
        raise TypeError(f"row family {name!r}: give exactly one of check (the name of its "
                        "independent check in verify.ROW_CHECKS) and unchecked (why it needs "
                        "none)")


def _offset_labels(prefix: str) -> Callable[[int], tuple[str, ...]]:
    return lambda n: tuple(f"{prefix}_{c}" for c in OFFSET_LABELS)


def _offset_rate(ctx: LinkContext) -> FloatArray:
    """Offset change per travel, and per time while stationary [m], (K - 1,)."""
    o = ctx.options
    return np.asarray(o.offset_rate * ctx.travel
                      + np.where(ctx.stationary, o.offset_speed_stationary * ctx.time, 0.0))


def _offset_speed(ctx: LinkContext) -> FloatArray:
    """Offset change per time while moving [m], (K - 1,) (inf on stationary links)."""
    return np.where(ctx.stationary, INF, ctx.options.offset_speed * ctx.time)


def _sym(*rows: Any) -> Any:
    return ca.vertcat(*rows)


#: The per-waypoint row families, in the order of the rows of every waypoint.
POINT_ROWS: tuple[PointRows, ...] = (
    PointRows(
        "position", ("position_x", "position_y", "position_z"),
        lambda s: s.position, lambda b: ((0.0, 0.0),) * 3, check="pose"),
    # The tool axis -n: perpendicular to t and l, and the TCP z axis against n.
    PointRows(
        "tool_axis", ("axis_t", "axis_l", "axis_n"),
        lambda s: _sym(*(ca.dot(s.axis, s.par[b]) for b in ("t", "l", "n"))),
        lambda b: ((0.0, 0.0), (0.0, 0.0), (-1.5, -0.5)), check="tool_axis"),
    PointRows(
        "window", ("window",), lambda s: s.error,
        lambda b: ((b.lower + b.margin, b.upper - b.margin),), check="window"),
    # e -+ r (worst case) inside the window up to the exact-penalty slack sigma.
    PointRows(
        "robust", ("robust_lower", "robust_upper"),
        lambda s: _sym(s.error - s.worst + s.v["sigma"], s.error + s.worst - s.v["sigma"]),
        lambda b: ((b.lower, INF), (-INF, b.upper)), check="robust_window"),
    PointRows(
        "along_track", ("along_track",), lambda s: s.along_error,
        lambda b: ((0.0, 0.0),), check="along_track"),
    # The weld envelope (issue 32). Depth: the normal pin error (along the tool axis; along
    # the plate normal it is cos(tilt) times this) inside the depth window with the margin,
    # wherever the pin is in the plate (gated by depth_on: every waypoint but the plunge
    # start). Under axial force control it is the force loop's equilibrium (the pin at the
    # planned depth under the set force) that the plan's poses model.
    PointRows(
        "depth", ("depth",), lambda s: s.par["depth_on"] * s.normal_error,
        lambda b: ((b.depth_lower, b.depth_upper),), check="depth"),
    # At the plunge start (zero force): the pin on the plate surface, not below it (so the
    # normal offset enters with the force, not before) and not above it by more than the depth
    # window's shallow side.
    PointRows(
        "surface", ("surface",),
        lambda s: s.par["surface_on"] * (s.normal_error - SURFACE_LIFT),
        lambda b: ((0.0, b.depth_upper - SURFACE_LIFT),), check="surface"),
    # While the tool stands with the pin in the plate (plunge, dwell, weld start) the pin does
    # not move sideways: every standing waypoint's lateral error within half the standstill
    # motion of one value, the window centre (the dwell's lateral force builds while the tool
    # stands; without these rows the offsets followed it only roughly and the pin slid
    # 0.72 mm sideways during the dwell of zk500_table6_seam).
    PointRows(
        "standstill", ("standstill",),
        lambda s: s.par["standing"] * (s.error - s.par["stand_at"]),
        lambda b: ((-b.stand, b.stand),), check="standstill"),
    # ... and at full depth (the plunge's end, the dwell, the weld start) the pin is at the
    # planned depth: the plunge ends there (before these rows it ended 0.40 mm short on
    # zk500_table6_seam with the full axial force on, and the pin sank during the dwell).
    PointRows(
        "standing_depth", ("standing_depth",),
        lambda s: s.par["standing_full"] * s.normal_error,
        lambda b: ((-b.stand_depth, b.stand_depth),), check="standing_depth"),
    # Work angle (about t) and travel angle (about l) of the tool axis within the tolerance
    # of the planned tilt: the TCP z axis against n, its components along l and t.
    PointRows(
        "tilt", ("work_angle", "travel_angle"),
        lambda s: _sym(ca.dot(s.axis, s.par["l"]), ca.dot(s.axis, s.par["t"])),
        lambda b: ((-b.tilt, b.tilt), (-b.tilt, b.tilt)), check="tilt"),
    # The pin's travel over each weld link k -> k + 1 along the seam chord u_k (the direction
    # the seam point moves, on which the sample check projects the pin's velocity) within
    # half the speed tolerance of the seam's travel h_k (the other half for the motion between
    # the waypoints), the chord's turn included (on a corner of radius R a pin e inside the
    # seam travels (1 - e / R) h):
    #     |(q_{k+1} - q_k) . u_k + |p_{k+1} - p_k| - h_k| <= speed_tol h_k / 2,
    # q = pin - p. One link sum per link: travel_in at k + 1 (q . u_k + c_k / 2) plus
    # travel_out at k (-q . u_k + c_k / 2), c = chord - h, both scaled by h_min / h_k to the
    # common bound speed_tol h_min / 2 (:func:`~rfsw_plan.planning.nlp.travel_parameters`; 0 off
    # the weld links). A part of q common to both ends (the depth along the tilted tool axis)
    # cancels, as it does in the pin's velocity.
    PointRows(
        "travel_speed", ("travel_speed_in", "travel_speed_out"),
        lambda s: _sym(ca.dot(s.pin, s.par["travel_in"]) + s.par["travel_at"][0],
                       ca.dot(s.pin, s.par["travel_out"]) + s.par["travel_at"][1]),
        lambda b: ((-INF, INF),) * 2, check="travel_speed",
        link_sum=lambda b: (-b.along, b.along)),
    # sign det J_n linearised at q_lin above its floor: the smooth stand-in for kappa_f.
    PointRows(
        "singularity", ("singularity",),
        lambda s: s.par["det_sign"] * (s.par["det_value"] + ca.dot(
            s.par["det_grad"], s.v["q"] - s.par["q_lin"])) - s.par["det_floor"],
        lambda b: ((0.0, INF),), check="singularity"),
    PointRows(
        "stiffness_cap", ("stiffness_cap",), lambda s: s.par["weld"] * s.compliance,
        lambda b: ((-INF, 0.0),), epigraph=True,
        unchecked="epigraph: c_max >= the weld waypoints' lateral compliance defines the "
                  "objective's weakest-waypoint term; c_max is not part of the plan"),
    PointRows(
        "tolerated", ("tolerated_lower", "tolerated_upper"),
        lambda s: _sym(s.error - s.v["tolerated"] * s.worst,
                       s.error + s.v["tolerated"] * s.worst),
        lambda b: ((b.lower, INF), (-INF, b.upper)),
        unchecked="defines rho, the share of the requested force uncertainty held, which the "
                  "objective maximises; the plan's tolerated uncertainty is computed "
                  "independently (verify.tolerated_uncertainty) and reported, not required"),
)

#: The link row families. Their rows on a link follow the order in which their variables
#: first appear here; families on the same variable share its rows (the tightest bound).
LINK_ROWS: tuple[LinkRows, ...] = (
    LinkRows("joint_step", "q", lambda n: tuple(f"joint_step_q{j + 1}" for j in range(n)),
             lambda c: np.full(len(c.travel), c.options.joint_step), check="joint_step"),
    # |delta o| <= offset_rate * travel (+ offset_speed_stationary * time while stationary).
    LinkRows("offset_rate", "offsets", _offset_labels("offset_rate"), _offset_rate,
             slack=1e-6, check="offset_rate"),
    LinkRows("tolerated_link", "tolerated", lambda n: ("tolerated_link",),
             lambda c: np.zeros(len(c.travel)),
             unchecked="keeps rho, one value for the whole plan, equal at every waypoint"),
    # |delta o| <= offset_speed * time while moving.
    LinkRows("offset_speed", "offsets", _offset_labels("offset_speed"), _offset_speed,
             slack=1e-6, check="offset_speed"),
)


def _unique_names() -> None:
    names = [f.name for f in POINT_ROWS] + [f.name for f in LINK_ROWS]
    dup = {x for x in names if names.count(x) > 1}
    if dup:
        raise TypeError(f"row families declared twice: {sorted(dup)}")


_unique_names()


# The functions below read the declarations when called (a test may add one).


def point_row_count() -> int:
    """Rows per waypoint."""
    return sum(len(f.labels) for f in POINT_ROWS)


def point_labels() -> tuple[str, ...]:
    """Names of the per-waypoint rows, in order."""
    return tuple(label for f in POINT_ROWS for label in f.labels)


def point_row_layout() -> Layout:
    """The per-waypoint rows by family: ``point_row_layout().split(g)["along_track"]``."""
    return Layout(tuple((f.name, len(f.labels)) for f in POINT_ROWS))


def epigraph_rows() -> FloatArray:
    """1 at the per-waypoint rows that - c_max joins (declared ``epigraph``), else 0."""
    return np.concatenate([np.full(len(f.labels), 1.0 if f.epigraph else 0.0)
                           for f in POINT_ROWS])


def link_sum_families() -> tuple[PointRows, ...]:
    """The point row families bounded as link sums (declared ``link_sum``), in order."""
    return tuple(f for f in POINT_ROWS if f.link_sum is not None)


def link_sum_rows() -> tuple[tuple[int, int], ...]:
    """Per link-sum family, the positions among a waypoint's rows of its two rows (the term
    of the link's end, taken at k + 1, and of its start, taken at k)."""
    layout = point_row_layout()
    return tuple((layout[f.name].start, layout[f.name].start + 1) for f in link_sum_families())


def link_variables() -> tuple[str, ...]:
    """The variables the link rows bound, in the order of their rows on a link."""
    return tuple(dict.fromkeys(f.variable for f in LINK_ROWS))


def link_families(variable: str) -> tuple[LinkRows, ...]:
    """The link row families on one variable, in declaration order."""
    return tuple(f for f in LINK_ROWS if f.variable == variable)


def checks() -> dict[str, str]:
    """Family name -> the name of its independent check in ``verify`` (checked ones only)."""
    families: tuple[PointRows | LinkRows, ...] = (*POINT_ROWS, *LINK_ROWS)
    return {f.name: f.check for f in families if f.check is not None}


__all__ = ["LINK_ROWS", "POINT_ROWS", "LinkContext", "LinkRows", "PointBounds", "PointRows",
           "PointSymbols", "checks", "epigraph_rows", "link_families", "link_sum_families",
           "link_sum_rows", "link_variables", "point_labels", "point_row_count",
           "point_row_layout"]
