"""A map of a problem over a requested region, with the bad-input checks of the CLI.

:func:`map_problem` is what ``rfsw-plan map`` and ``rfsw-plan place`` run first: the grid
(:func:`~rfsw_plan.placement.region.build_grid`), the map, and one-line errors (exit 2) when
the request cannot give a single usable placement:

* a region where the robot reaches the seam at no placement (the message gives the reachable
  extent from a radial scan);
* a robot base height range at which every placement is infeasible (the message counts why);
* an empty yaw range (:func:`~rfsw_plan.placement.region.yaw_values`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rfsw_plan.exceptions import InputError
from rfsw_plan.placement.map import MapInput, PlacementMap, compute_map, map_input
from rfsw_plan.placement.region import ReachExtent, build_grid, radial_scan


@dataclass(frozen=True)
class MapRequest:
    """What the user asked for (SI; None = default).

    Attributes:
        region: (x0, x1, y0, y1[, z0, z1]) of the seam anchor, base frame [m].
        yaw_range_deg: (a0, a1) yaw about the vertical relative to the given placement [deg].
        base_height: (h0, h1) change of the robot base height [m].
        shape: Grid points (nx, ny, nyaw, nz).
        max_weld: Weld waypoints evaluated per placement.
    """

    region: tuple[float, ...] | None = None
    yaw_range_deg: tuple[float, float] | None = None
    base_height: tuple[float, float] | None = None
    shape: tuple[int, int, int, int] = (25, 25, 8, 3)
    max_weld: int = 50


@dataclass(frozen=True)
class MapSession:
    """A computed map with its input and the reach extent of the default region (if used)."""

    input: MapInput
    map: PlacementMap
    extent: ReachExtent | None


def map_problem(problem: Any, request: MapRequest, options: Any = None) -> MapSession:
    """Grid, map and input checks for a problem (see the module docstring).

    Raises:
        InputError: Unreachable region, empty yaw range, infeasible height range.
    """
    mi = map_input(problem, request.max_weld, options)
    grid, ext = build_grid(mi, request.region, request.yaw_range_deg, request.base_height,
                           request.shape)
    m = compute_map(mi, grid)
    if not np.any(m.status != "unreachable") and request.region is not None:
        scan = radial_scan(mi, grid.yaw, grid.z)
        r = request.region
        raise InputError("region", "", f"the robot reaches the seam at no placement with its "
                         f"anchor in x {r[0] * 1e3:g}..{r[1] * 1e3:g} mm, y {r[2] * 1e3:g}.."
                         f"{r[3] * 1e3:g} mm; {scan.text()}")
    if not np.any(m.feasible):
        st, cnt = np.unique(m.status, return_counts=True)
        why = ", ".join(f"{c} {s}" for s, c in zip(st, cnt, strict=True))
        if request.base_height is not None:
            h0, h1 = request.base_height
            raise InputError("base_height", "",
                             f"every placement is infeasible at robot base heights "
                             f"{h0 * 1e3:g}..{h1 * 1e3:g} mm ({why} of {len(m.status)})",
                             "a height range where the seam is reachable within the joint "
                             "limits")
        where = "region" if request.region is not None else "placement"
        raise InputError(where, "", f"every placement is infeasible ({why} of "
                         f"{len(m.status)})", "a region with a feasible placement")
    return MapSession(mi, m, ext)
