"""Planner options: weights, limits and solver settings (the problem file's ``[planning]`` table).

The options are part of a problem (:attr:`rfsw_plan.process.problem.Problem.planning`), so they
live beside it in ``process/``, with the planner's check that they make a well-posed NLP
(:func:`check_well_posed`): the one module of the planner's options. The ``[planning]``
table and ``plan --set KEY=VALUE`` are read by one function, :func:`options_from_table`, with
the keys and valid ranges of :data:`OPTION_KEYS` (file units, the unit in the key name).

Weights of the NLP objective (all terms are averaged over waypoints or links, so a weight means
the same thing for 100 and for 4000 waypoints):

``w_stiffness``
    Lateral compliance l^T C_tt(q) l, divided by its mean on the warm start: a share
    ``min_stiffness_share`` on the largest value over the weld waypoints (the weakest waypoint,
    an epigraph variable c_max >= l^T C_tt l), the rest on the mean. Buys stiffness along the
    seam's lateral axis through the tool-axis rotation and the branch.
``w_worst``
    Worst-case deviation of the lateral error under the force uncertainty, r_k, divided by the
    window half width.
``w_robust``
    Exact (L1) penalty on the part of the worst case that leaves the window, sigma_k / half
    width, plus 1 - rho, rho the share of the requested force uncertainty that the window holds
    at every waypoint (rho <= 1). Large: the robust window holds wherever it can, and where the
    requested uncertainty cannot be held everywhere, the plan maximises the uncertainty it
    tolerates.
``w_centre``
    ((e_k - centre) / half width)^2: keeps the nominal error in the middle of the window.
``w_depth``
    (predicted normal pin error / 1 mm)^2: the normal offset compensates the axial deflection.
``w_smooth_q``
    |dq/dh|^2 [(rad/m)^2], h the travel (or the distance a stationary step stands for).
``w_smooth_o``
    |do/dh|^2 [(m/m)^2], the offset rate.
``w_proximity``
    |q - q_warm|^2 [rad^2]: stay near the warm start (taught/mirror path) unless it pays; keeps
    directions the objective does not see (a tool rotation that changes nothing) where they are,
    and convexifies the curved null space of an offset head (on kr600_curved_seam 0.1 instead of
    1e-3 cut IPOPT's iterations from about 160 to 50 at the same stiffness).

Priorities. The nominal window (with ``margin``) is a hard constraint. Then, by the size of the
weights: the robust window (``w_robust``, an exact penalty: wherever the worst case can be kept
inside the window, it is), then stiffness (``w_stiffness``), then the worst case inside the
window and centring (``w_worst``, ``w_centre``), then smoothness and proximity. The multi-start
over branches and tool rotations ranks its candidates by the same priorities
(:func:`rfsw_plan.planning.api.start_objective`), so the local NLP starts in the right basin.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.exceptions import InputError
from rfsw_plan.tomlreader import Table


@dataclass(frozen=True)
class PlanOptions:
    """Options of :func:`rfsw_plan.planning.api.plan` (SI units).

    Attributes:
        force_uncertainty: Relative force uncertainty per seam-frame component, the box
            |delta f_i| <= u |f_i| (default 0.2 = +-20 %).
        margin: Margin of the nominal lateral error to the window bounds [m].
        robust_hard: Make the worst-case window a hard constraint (else an exact penalty).
        robust_first: Maximise the force uncertainty the plan tolerates before stiffness (the
            NLP pursues the robust window up to ``ROBUST_CEILING`` whatever the request; the
            request decides the verdict). False trades robustness for stiffness: the NLP
            holds only the requested uncertainty and spends the rest of the window on
            stiffness, so the plan may tolerate less than the mirror baseline.
        offset_rate: Bound on the offset change per travel [m/m].
        offset_speed_stationary: Bound on the offset change per time while stationary [m/s].
        offset_speed: Bound on the offset change per time while moving [m/s], beyond the
            change the load itself demands (the mirror baseline's). Default 10 mm/s, the same
            speed as ``offset_speed_stationary``: how fast the fake target may move against the
            seam, stationary or not. It binds only where offset_rate x travel speed is faster
            (on the bundled problems at most 0.2 x 20 mm/s = 4 mm/s, so it does not).
        joint_step: Bound on the joint change between neighbouring waypoints [rad].
        kappa_max: Largest allowed kinetostatic index kappa_f (seed 000 eq. 5) on the plan.
        det_fraction: The NLP keeps |det J_n| above this fraction of its warm-start value (a
            smooth stand-in for the kappa_f bound).
        length_scale: Length that makes J's rows homogeneous for kappa_f and det [m].
        q_seed: Seed configuration of the main branch [rad], shape (n,), or None.
        tool_rotation: Initial tool rotation about its axis [rad] (the NLP frees it).
        branches: Try the configuration branches (elbow, wrist, shoulder flips).
        rotation_starts: Number of tool rotations about the tool axis, evenly spaced from
            ``tool_rotation``, tried as warm starts on every branch when ``w_stiffness > 0``
            (1 = only ``tool_rotation``). The NLP is local; this multi-start is what lets the
            stiffness objective choose the rotation globally.
        max_start_waypoints: Stationary waypoints planned over plunge and dwell.
        max_outer: Outer correction iterations for effects the NLP does not model symbolically.
        outer_tol: Convergence of the outer correction [m].
        tol: IPOPT tolerance.
        max_iter: IPOPT iteration cap.
        solver: ``coarse`` (default): the NLP on ``coarse_waypoints`` evenly spread weld
            waypoints, then every waypoint projected exactly onto the fine NLP's equality rows
            and checked against all its rows (the full NLP if any row fails); ``full``: the
            NLP on every waypoint (:mod:`rfsw_plan.planning.coarse`).
        coarse_waypoints: Weld waypoints of the coarse NLP (``solver = "coarse"``).
        min_stiffness_share: Share of ``w_stiffness`` on the weakest weld waypoint (0..1).
        w_stiffness, w_worst, w_robust, w_centre, w_depth, w_smooth_q, w_smooth_o, w_proximity:
            Objective
            weights (see the module docstring).
        clearance: Safe height of the pin tip above the plate surface [m]: the approach
            starts and the retract ends there, by a linear move along the tool axis (default
            50 mm, ASSUMED: above the clamps of a butt-weld fixture; no seed states one). The
            problem's ``[process] approach_height_mm``, when > 0, replaces it.
        spindle_clearance: Height of the pin tip above the plate surface where the approach
            ends, the spindle-start hook runs and the plunge begins [m] (default 2 mm,
            ASSUMED): the spindle is at speed before the pin touches the plate.
        approach_speed: Speed of the approach and of the retract once the pin has left the
            plate [m/s] (in the plate the retract runs at the process retract speed).
        sample_dt: Sample time of the timed trajectory [s].
    """

    force_uncertainty: float = 0.2
    margin: float = 0.1e-3
    robust_hard: bool = False
    robust_first: bool = True
    offset_rate: float = 0.2
    offset_speed_stationary: float = 10e-3
    offset_speed: float = 10e-3
    joint_step: float = float(np.deg2rad(20.0))
    kappa_max: float = 200.0
    det_fraction: float = 0.2
    length_scale: float = 1.0
    q_seed: tuple[float, ...] | None = None
    tool_rotation: float = 0.0
    branches: bool = True
    rotation_starts: int = 8
    max_start_waypoints: int = 12
    max_outer: int = 5
    outer_tol: float = 1e-6
    tol: float = 1e-8
    max_iter: int = 300
    solver: str = "coarse"
    coarse_waypoints: int = 60
    min_stiffness_share: float = 0.5
    w_stiffness: float = 1.0
    w_worst: float = 0.1
    w_robust: float = 100.0
    w_centre: float = 0.1
    w_depth: float = 0.1
    w_smooth_q: float = 1e-3
    w_smooth_o: float = 1.0
    w_proximity: float = 0.1
    clearance: float = 50e-3
    spindle_clearance: float = 2e-3
    approach_speed: float = 20e-3
    sample_dt: float = 0.01

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, float) and not np.isfinite(v):
                raise InputError("planning", f.name, f"got {v}", "a finite number")
            if f.name.startswith("w_") and v < 0:
                raise InputError("planning", f.name, f"got {v}", ">= 0")
        for name in ("margin", "force_uncertainty"):
            if getattr(self, name) < 0:
                raise InputError("planning", name, f"got {getattr(self, name)}", ">= 0")
        for name in ("offset_rate", "offset_speed_stationary", "offset_speed", "joint_step",
                     "length_scale", "clearance", "spindle_clearance", "approach_speed",
                     "sample_dt", "tol"):
            if getattr(self, name) <= 0:
                raise InputError("planning", name, f"got {getattr(self, name)}", "> 0")
        if not 0.0 <= self.min_stiffness_share <= 1.0:
            raise InputError("planning", "min_stiffness_share",
                             f"got {self.min_stiffness_share}", "a number in [0, 1]")
        if self.kappa_max <= 1:
            raise InputError("planning", "kappa_max", f"got {self.kappa_max}", "> 1")
        if self.rotation_starts < 1:
            raise InputError("planning", "rotation_starts", f"got {self.rotation_starts}", ">= 1")
        if self.solver not in SOLVERS:
            raise InputError("planning", "solver", f"got {self.solver!r}", " or ".join(SOLVERS))
        if self.coarse_waypoints < 2:
            raise InputError("planning", "coarse_waypoints", f"got {self.coarse_waypoints}",
                             ">= 2")
        if self.max_start_waypoints < 0 or self.max_outer < 1 or self.max_iter < 1:
            raise InputError("planning", "max_start_waypoints/max_outer/max_iter",
                             "out of range", "max_start_waypoints >= 0, the others >= 1")

    @property
    def weights(self) -> dict[str, float]:
        """The objective weights by name."""
        return {f.name: float(getattr(self, f.name)) for f in fields(self)
                if f.name.startswith("w_")}


@dataclass(frozen=True)
class OptionKey:
    """One key of the ``[planning]`` table (file units) and the field it sets.

    Attributes:
        field: :class:`PlanOptions` field name.
        factor: File unit to SI factor (1 for unitless keys).
        ge, gt, le: Valid range in file units (None = open).
        choices: The allowed names of a string key.
    """

    field: str
    factor: float = 1.0
    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    choices: tuple[str, ...] | None = None
    #: A relative amount: the number is a fraction in [ge, le], or a string "N %"; a number
    #: above ``le`` is refused with "did you mean N %?" (:meth:`Table.fraction`).
    fraction: bool = False
    #: Largest percentage a "N %" string may give (default 100 * le).
    le_percent: float | None = None


#: Values of ``solver``: the coarse-to-fine solve or the NLP on every waypoint.
SOLVERS = ("coarse", "full")

_DEG = float(np.pi / 180)

#: Keys of the ``[planning]`` table and of ``plan --set``, with their valid ranges (file units).
OPTION_KEYS: dict[str, OptionKey] = {
    "force_uncertainty": OptionKey("force_uncertainty", ge=0.0, le=1.0, fraction=True,
                                   le_percent=1000.0),
    "margin_mm": OptionKey("margin", 1e-3, ge=0.0, le=100.0),
    "robust_hard": OptionKey("robust_hard"),
    "robust_first": OptionKey("robust_first"),
    "offset_rate_mm_per_mm": OptionKey("offset_rate", ge=1e-6, le=10.0),
    "offset_speed_stationary_mm_s": OptionKey("offset_speed_stationary", 1e-3, ge=1e-3,
                                                      le=1e4),
    "offset_speed_mm_s": OptionKey("offset_speed", 1e-3, ge=1e-3, le=1e4),
    "joint_step_deg": OptionKey("joint_step", _DEG, ge=1e-3, le=360.0),
    "kappa_max": OptionKey("kappa_max", gt=1.0, le=1e12),
    "det_fraction": OptionKey("det_fraction", ge=0.0, le=1.0, fraction=True),
    "length_scale_mm": OptionKey("length_scale", 1e-3, ge=1.0, le=1e5),
    "q_seed_deg": OptionKey("q_seed", _DEG, ge=-720.0, le=720.0),
    "tool_rotation_deg": OptionKey("tool_rotation", _DEG, ge=-720.0, le=720.0),
    "branches": OptionKey("branches"),
    "rotation_starts": OptionKey("rotation_starts", ge=1, le=360),
    "max_start_waypoints": OptionKey("max_start_waypoints", ge=0, le=10000),
    "max_outer": OptionKey("max_outer", ge=1, le=1000),
    "outer_tol": OptionKey("outer_tol", ge=1e-15, le=1.0),
    "tol": OptionKey("tol", ge=1e-15, le=1.0),
    "max_iter": OptionKey("max_iter", ge=1, le=1000000),
    "solver": OptionKey("solver", choices=SOLVERS),
    "coarse_waypoints": OptionKey("coarse_waypoints", ge=2, le=100000),
    "min_stiffness_share": OptionKey("min_stiffness_share", ge=0.0, le=1.0, fraction=True),
    **{w: OptionKey(w, ge=0.0, le=1e9) for w in (
        "w_stiffness", "w_worst", "w_robust", "w_centre", "w_depth", "w_smooth_q", "w_smooth_o",
        "w_proximity")},
    "clearance_mm": OptionKey("clearance", 1e-3, ge=0.01, le=1e4),
    "spindle_clearance_mm": OptionKey("spindle_clearance", 1e-3, ge=0.01, le=1e3),
    "approach_speed_mm_s": OptionKey("approach_speed", 1e-3, ge=0.01, le=1e4),
    "sample_dt_s": OptionKey("sample_dt", ge=1e-4, le=1.0),
}


def options_from_table(table: Mapping[str, Any], source: str | Path = "planning",
                       base: PlanOptions | None = None, *, prefix: str = "planning.",
                       what: str = "key") -> PlanOptions:
    """Options from a ``[planning]`` table in file units (``margin_mm``, ``q_seed_deg``...).

    Args:
        table: Key -> value in file units (every key of :data:`OPTION_KEYS` is optional).
        source: File or option the table came from, for messages.
        base: Options the table overrides (default: :class:`PlanOptions` defaults).
        prefix: Dotted prefix of the keys in messages (``""`` for ``--set``).
        what: Word for a key in messages (``"option"`` for ``--set``).

    Raises:
        InputError: Unknown key (with a "did you mean"), wrong type, non-finite or out of
            range; one line naming the source and the key.
    """
    tab = Table(source, dict(table), OPTION_KEYS, prefix, what)
    defaults = base or PlanOptions()
    kw: dict[str, Any] = {}
    for key, spec in OPTION_KEYS.items():
        if not tab.has(key):
            continue
        default = getattr(PlanOptions, spec.field)
        if spec.fraction:
            kw[spec.field] = tab.fraction(key, le=spec.le if spec.le is not None else 1.0,
                                          le_percent=spec.le_percent)
        elif key == "q_seed_deg":
            kw["q_seed"] = tuple(float(x) * spec.factor for x in tab.vec(
                key, None, ge=spec.ge, le=spec.le))
        elif isinstance(default, bool):
            kw[spec.field] = tab.bool_(key)
        elif isinstance(default, str):
            kw[spec.field] = tab.str_(key, choices=spec.choices)
        elif isinstance(default, int):
            kw[spec.field] = tab.int_(key, ge=None if spec.ge is None else int(spec.ge),
                                      le=None if spec.le is None else int(spec.le))
        else:
            kw[spec.field] = tab.num(key, ge=spec.ge, gt=spec.gt, le=spec.le) * spec.factor
    return replace(defaults, **kw)


def check_well_posed(options: PlanOptions, window: Any, source: str = "planning") -> None:
    """Reject option combinations that make the planning NLP ill-posed, before any solver runs.

    The nominal lateral error must lie in [lower + margin, upper - margin], which is empty
    unless 2 margin < upper - lower (IPOPT then fails with "Ill-posed problem detected:
    LBG <= UBG" deep inside CasADi).

    Args:
        options: The planner options.
        window: The weld window (``lower``, ``upper`` [m]).
        source: Where the options came from, for the message.

    Raises:
        InputError: one line naming the options and the valid range (exit 2).
    """
    lo, hi = float(window.lower), float(window.upper)
    if not (np.isfinite(lo) and np.isfinite(hi)) or not lo < hi:
        raise InputError(source, "window", f"lower {lo * 1e3:g} mm, upper {hi * 1e3:g} mm",
                         "finite bounds with lower < upper")
    half = 0.5 * (hi - lo)
    if not options.margin < half:
        raise InputError(
            source, "margin_mm",
            f"margin {options.margin * 1e3:g} mm leaves no room in the window "
            f"[{lo * 1e3:g}, {hi * 1e3:+g}] mm (width {2 * half * 1e3:g} mm)",
            f"0 <= margin_mm < {half * 1e3:g} (half the window width), or a wider window")


__all__ = ["OPTION_KEYS", "OptionKey", "PlanOptions", "check_well_posed", "options_from_table"]
