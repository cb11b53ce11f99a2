"""Named layouts of the planning NLP's flat vectors: variables, parameters, terms.

A :class:`Layout` names contiguous slices of a vector. Every place that reads or writes the
NLP's variables, its per-waypoint parameters or the terms of its point function does it through
one of the layouts here, by name, never by position: the symbolic unpack (CasADi) and the
numeric pack (numpy) use the same object, so they cannot disagree. The constraint rows are
declared by name in :mod:`rfsw_plan.planning.rows`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


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

    def width(self, name: str) -> int:
        """Width of one field."""
        sl = self._slices[name]
        return sl.stop - sl.start

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


#: The three fake-target offset components, in the order of every (K, 3) offset array
#: (:func:`rfsw_plan.process.task.offsets3`): lateral (along l), normal (along n), along-track
#: (along t) [mm in the NLP, m outside].
OFFSETS = Layout((("lateral", 1), ("normal", 1), ("along", 1)))

#: Short names of the offset components in row names (``offset_rate_lat[4]``).
OFFSET_LABELS = ("lat", "norm", "along")

#: Offsets that the smoothing term smooths: the along-track offset is fixed by the pin's
#: along-track row, so it is not smoothed.
SMOOTHED_OFFSETS = ("lateral", "normal")


def variable_layout(n: int) -> Layout:
    """Variables per waypoint: q [rad] (n), offsets [mm] (3, :data:`OFFSETS`), sigma [mm],
    and rho (``tolerated``), the share of the requested force uncertainty the window holds at
    every waypoint (one value for the whole plan, kept equal by the link rows so the KKT matrix
    stays banded). The NLP's vector x stacks K of these (waypoint-major) and then c_max."""
    return Layout((("q", n), ("offsets", OFFSETS.size), ("sigma", 1), ("tolerated", 1)))


#: Scale of each variable in the NLP relative to SI: offsets are in mm.
VARIABLE_SCALE = {"q": 1.0, "offsets": 1e3, "sigma": 1.0, "tolerated": 1.0}


def point_layout(n: int) -> Layout:
    """Per-waypoint parameters: nominal target [m], seam frame t, l, n, wrench (base frame)
    [N, Nm], force spread u |f| per seam component [N], outer correction (lateral, normal,
    along-track) [mm], singularity row (sign, floor, det at q_lin, q_lin [rad], d det / dq),
    weld flag, depth flag (1 where the depth window applies: in the plate under position
    control), surface flag (1 at the plunge start, where the pin must not be below the
    surface), standstill flag (1 where the tool stands with the pin in the plate) and the
    lateral pin error held there [mm] (the window centre), the flag of the standing
    waypoints at full depth (the pin at the planned depth), and the normal pin error the
    objective centres the depth on [mm] (``depth_at``: 0, or under the coupled axial law the
    depth window's centre, see :func:`~rfsw_plan.planning.nlp.depth_targets`), and the
    travel-speed rows' seam chords and their offsets [mm]
    (:func:`~rfsw_plan.planning.nlp.travel_parameters`), and the in-plane seam tangent the
    along-track error is measured along (:func:`~rfsw_plan.planning.verify.along_tangents`)."""
    return Layout((("target", 3), ("t", 3), ("l", 3), ("n", 3), ("wrench", 6),
                   ("force_spread", 3), ("correction", 3), ("det_sign", 1), ("det_floor", 1),
                   ("det_value", 1), ("q_lin", n), ("det_grad", n), ("weld", 1),
                   ("depth_on", 1), ("surface_on", 1), ("standing", 1), ("stand_at", 1),
                   ("standing_full", 1), ("depth_at", 1), ("travel_in", 3),
                   ("travel_out", 3), ("travel_at", 2), ("t_along", 3)))


#: Global scalars passed to every waypoint: the objective weights, the lateral compliance
#: reference [mm/kN], window centre and half width [mm], 1 / K and the share of the stiffness
#: weight on the mean (1 - ``min_stiffness_share``).
GLOBALS = Layout((("w_stiffness", 1), ("w_worst", 1), ("w_robust", 1), ("w_centre", 1),
                  ("w_depth", 1), ("compliance_ref", 1), ("centre", 1), ("half_width", 1),
                  ("inv_k", 1), ("w_proximity", 1), ("mean_share", 1)))
N_GLOB = GLOBALS.size

#: Terms the point function returns besides its rows, per waypoint (NLP units): lateral
#: compliance l^T C_tt l [mm/kN], worst case r [mm], robust excess sigma [mm], and the NLP's
#: own predicted pin error (lateral e, normal, along-track) [mm] with the outer correction.
TERMS = Layout((("lateral_compliance", 1), ("worst_case", 1), ("robust_excess", 1),
                ("error", 1), ("normal_error", 1), ("along_error", 1)))

#: The predicted pin error terms in the order of a (K, 3) offset or error array.
ERROR_TERMS = ("error", "normal_error", "along_error")


def problem_layout(n: int, K: int) -> Layout:
    """The whole parameter vector: K waypoints' parameters (waypoint-major), 1 / link length
    [1/m] (K - 1), the globals, the smoothing weights and the window bounds [mm]."""
    return Layout((("points", point_layout(n).size * K), ("inv_link", max(K - 1, 0)),
                   ("globals", N_GLOB), ("w_smooth_q", 1), ("w_smooth_o", 1),
                   ("lower", 1), ("upper", 1)))


def n_par(n: int) -> int:
    """Per-waypoint parameters (see :func:`point_layout`)."""
    return point_layout(n).size


def columns(layout: Layout, names: tuple[str, ...]) -> NDArray[np.int_]:
    """Positions of some fields of a layout, in the order given (for numpy fancy indexing)."""
    return np.concatenate([np.arange(layout[name].start, layout[name].stop) for name in names])
