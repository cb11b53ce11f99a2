"""Planner options: weights, limits and solver settings (the problem file's ``[planning]`` table).

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
    width. Large: the robust window holds wherever it can.
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
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from rfsw_plan.exceptions import InputError


@dataclass(frozen=True)
class PlanOptions:
    """Options of :func:`rfsw_plan.planning.api.plan` (SI units).

    Attributes:
        force_uncertainty: Relative force uncertainty per seam-frame component, the box
            |delta f_i| <= u |f_i| (default 0.2 = +-20 %).
        margin: Margin of the nominal lateral error to the window bounds [m].
        robust_hard: Make the worst-case window a hard constraint (else an exact penalty).
        offset_rate: Bound on the offset change per travel [m/m].
        offset_speed_stationary: Bound on the offset change per time while stationary [m/s].
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
        min_stiffness_share: Share of ``w_stiffness`` on the weakest weld waypoint (0..1).
        w_stiffness, w_worst, w_robust, w_centre, w_depth, w_smooth_q, w_smooth_o, w_proximity:
            Objective
            weights (see the module docstring).
        clearance: Approach and retract distance along the tool axis [m].
        approach_speed: Speed of the approach and retract [m/s].
        sample_dt: Sample time of the timed trajectory [s].
    """

    force_uncertainty: float = 0.2
    margin: float = 0.1e-3
    robust_hard: bool = False
    offset_rate: float = 0.2
    offset_speed_stationary: float = 10e-3
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
    min_stiffness_share: float = 0.5
    w_stiffness: float = 1.0
    w_worst: float = 0.1
    w_robust: float = 100.0
    w_centre: float = 0.1
    w_depth: float = 0.1
    w_smooth_q: float = 1e-3
    w_smooth_o: float = 1.0
    w_proximity: float = 0.1
    clearance: float = 20e-3
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
        for name in ("offset_rate", "offset_speed_stationary", "joint_step", "length_scale",
                     "clearance", "approach_speed", "sample_dt", "tol"):
            if getattr(self, name) <= 0:
                raise InputError("planning", name, f"got {getattr(self, name)}", "> 0")
        if not 0.0 <= self.min_stiffness_share <= 1.0:
            raise InputError("planning", "min_stiffness_share",
                             f"got {self.min_stiffness_share}", "a number in [0, 1]")
        if self.kappa_max <= 1:
            raise InputError("planning", "kappa_max", f"got {self.kappa_max}", "> 1")
        if self.rotation_starts < 1:
            raise InputError("planning", "rotation_starts", f"got {self.rotation_starts}", ">= 1")
        if self.max_start_waypoints < 0 or self.max_outer < 1 or self.max_iter < 1:
            raise InputError("planning", "max_start_waypoints/max_outer/max_iter",
                             "out of range", "max_start_waypoints >= 0, the others >= 1")

    @property
    def weights(self) -> dict[str, float]:
        """The objective weights by name."""
        return {f.name: float(getattr(self, f.name)) for f in fields(self)
                if f.name.startswith("w_")}


# Keys of the problem file's [planning] table that are given in file units, with the factor to SI.
_FILE_KEYS: dict[str, tuple[str, float]] = {
    "margin_mm": ("margin", 1e-3),
    "offset_rate_mm_per_mm": ("offset_rate", 1.0),
    "offset_speed_stationary_mm_s": ("offset_speed_stationary", 1e-3),
    "joint_step_deg": ("joint_step", float(np.pi / 180)),
    "length_scale_mm": ("length_scale", 1e-3),
    "tool_rotation_deg": ("tool_rotation", float(np.pi / 180)),
    "clearance_mm": ("clearance", 1e-3),
    "approach_speed_mm_s": ("approach_speed", 1e-3),
    "sample_dt_s": ("sample_dt", 1.0),
}


def options_from_table(table: Mapping[str, Any], source: str = "planning") -> PlanOptions:
    """Options from a ``[planning]`` table in file units (``margin_mm``, ``q_seed_deg``...).

    SI field names (``force_uncertainty``, ``w_stiffness``...) are accepted as they are; unknown
    keys raise :class:`InputError` listing the known ones.
    """
    si_names = {f.name for f in fields(PlanOptions)}
    known = sorted(set(_FILE_KEYS) | (si_names - {v[0] for v in _FILE_KEYS.values()})
                   | {"q_seed_deg"} - {"q_seed"})
    kw: dict[str, Any] = {}
    for key, value in table.items():
        if key == "q_seed_deg":
            if value is None:
                continue
            try:
                kw["q_seed"] = tuple(float(np.deg2rad(float(v))) for v in value)
            except (TypeError, ValueError) as exc:
                raise InputError(source, key, f"got {value!r}", "a list of angles [deg]") from exc
        elif key in _FILE_KEYS:
            name, factor = _FILE_KEYS[key]
            kw[name] = _number(source, key, value) * factor
        elif key in si_names and key != "q_seed":
            default = getattr(PlanOptions, key)
            if isinstance(default, bool):
                if not isinstance(value, bool):
                    raise InputError(source, key, f"got {value!r}", "true or false")
                kw[key] = value
            elif isinstance(default, int):
                kw[key] = int(_number(source, key, value))
            else:
                kw[key] = _number(source, key, value)
        else:
            raise InputError(source, key, "unknown planning option", ", ".join(known))
    return PlanOptions(**kw)


def _number(source: str, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(source, key, f"got {value!r}", "a number")
    return float(value)


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
