"""The region a map covers: user ranges, the default region and the reachable extent.

Default region (what a cell designer looks at first): the reachable part of the robot's
workspace in front of the part's given position, at the seam's height. A radial scan along the
ray from the robot's base axis through the seam anchor (every yaw of the grid, every height)
finds the anchor radii [r_min, r_max] at which the seam is feasible; the region is the bounding
box of that annulus over +-45 deg of polar angle around the given placement. Joint 1 turns
about the base axis, so this sector holds the same poses up to q1 (other directions differ only
by the joint-1 limits).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.placement.geometry import PlacementGrid
from rfsw_plan.placement.map import MapInput, compute_map
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: Half opening of the default sector around the given placement [rad].
SECTOR = float(np.deg2rad(45.0))


def reach_radius(robot: Robot, samples: int = 20000, seed: int = 0) -> float:
    """Largest horizontal distance of the TCP from the base z axis [m] over random joint values
    within the limits (plus 5 %)."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.description.lower, robot.description.upper
    Q = lo + (hi - lo) * rng.random((samples, robot.nq))
    T, _ = robot.batch_fk_jacobian(Q)
    return float(np.max(np.linalg.norm(T[:, :2, 3], axis=1))) * 1.05


@dataclass(frozen=True)
class ReachExtent:
    """Anchor radii from the robot's base axis at which the seam is feasible.

    Attributes:
        r_min, r_max: Smallest and largest feasible anchor radius [m] (NaN: none).
        heights: Anchor heights scanned [m].
        theta: Polar angle of the scan ray [rad].
    """

    r_min: float
    r_max: float
    heights: FloatArray
    theta: float

    @property
    def empty(self) -> bool:
        """No feasible radius."""
        return not np.isfinite(self.r_min)

    def text(self) -> str:
        """One-line description in mm."""
        z = ", ".join(f"{h * 1e3:.0f}" for h in self.heights)
        if self.empty:
            return f"the seam is feasible at no anchor radius at height(s) z = {z} mm"
        c, s = np.cos(self.theta), np.sin(self.theta)
        return (f"the seam is feasible with its anchor {self.r_min * 1e3:.0f}.."
                f"{self.r_max * 1e3:.0f} mm from the robot's base axis at z = {z} mm (toward "
                f"the given placement: x "
                f"{self.r_min * c * 1e3:.0f}..{self.r_max * c * 1e3:.0f} mm, y "
                f"{self.r_min * s * 1e3:.0f}..{self.r_max * s * 1e3:.0f} mm)")


def radial_scan(mi: MapInput, yaws: FloatArray, heights: FloatArray,
                n: int = 41) -> ReachExtent:
    """Feasible anchor radii along the ray through the given placement (see module doc)."""
    anchor = mi.anchor
    theta = float(np.arctan2(anchor[1], anchor[0]))
    r_reach = reach_radius(mi.model.robot)
    r = np.linspace(0.05 * r_reach, r_reach, n)
    # Scanned along the base's +x axis: joint 1 turns about the base axis, so this is the ray
    # through the given placement turned by -theta (only q1 and its limits differ).
    grid = PlacementGrid(r, np.array([0.0]), yaws, heights)
    m = compute_map(mi, grid, progress_desc="reach scan")
    ok = m.feasible.reshape(grid.shape).any(axis=(1, 2, 3))
    if not np.any(ok):
        return ReachExtent(float("nan"), float("nan"), heights, theta)
    return ReachExtent(float(np.min(r[ok])), float(np.max(r[ok])), heights, theta)


def default_region(mi: MapInput, yaws: FloatArray, heights: FloatArray
                   ) -> tuple[tuple[float, float, float, float], ReachExtent]:
    """(x0, x1, y0, y1) [m] of the default region and the reach extent it came from.

    Raises:
        InputError: The seam is feasible at no radius (at these heights).
    """
    ext = radial_scan(mi, yaws, heights)
    if ext.empty:
        raise InputError("placement", "", f"no placement is feasible: {ext.text()}",
                         "a seam the robot can reach")
    th = ext.theta + np.linspace(-SECTOR, SECTOR, 91)
    xs = np.concatenate([ext.r_min * np.cos(th), ext.r_max * np.cos(th)])
    ys = np.concatenate([ext.r_min * np.sin(th), ext.r_max * np.sin(th)])
    return (float(xs.min()), float(xs.max()), float(ys.min()), float(ys.max())), ext


def yaw_values(yaw_range_deg: tuple[float, float] | None, n: int) -> FloatArray:
    """Yaw grid [rad]: n values over a range [deg] (ends included), or by default n values
    evenly over the full turn, 0 (the given orientation) included, sorted in [-180, 180)."""
    if yaw_range_deg is None:
        return np.deg2rad(np.sort((np.arange(n) * 360.0 / n + 180.0) % 360.0 - 180.0))
    a0, a1 = yaw_range_deg
    if a1 < a0:
        raise InputError("yaw_range_deg", "", f"empty range {a0:g}..{a1:g} deg", "a0 <= a1")
    if a1 == a0 or n == 1:
        return np.deg2rad(np.array([0.5 * (a0 + a1)]))
    return np.deg2rad(np.linspace(a0, a1, n))


def build_grid(mi: MapInput, region: tuple[float, ...] | None,
               yaw_range_deg: tuple[float, float] | None,
               base_height: tuple[float, float] | None,
               shape: tuple[int, int, int, int] = (25, 25, 8, 3),
               ) -> tuple[PlacementGrid, ReachExtent | None]:
    """The grid of a map: region (x0, x1, y0, y1[, z0, z1]) [m] or the default region; yaw range
    [deg] or the full turn; robot base height change (h0, h1) [m] (anchor z = z_given - h) or
    the region's heights or the seam's own height. ``shape`` = (nx, ny, nyaw, nz); nz is used
    only when a height range is given.

    Raises:
        InputError: Both a height range and region heights, or an empty range.
    """
    nx, ny, nyaw, nz = shape
    if min(shape) < 1:
        raise InputError("shape", "", f"got {shape}", "at least 1 point per axis")
    z_given = float(mi.anchor[2])
    if base_height is not None and region is not None and len(region) == 6:
        raise InputError("base_height", "", "the region already gives heights z0,z1",
                         "the height either in `region` or as `base_height`")
    if base_height is not None:
        h0, h1 = base_height
        if h1 < h0:
            raise InputError("base_height", "", f"empty range {h0 * 1e3:g}.."
                             f"{h1 * 1e3:g} mm", "h0 <= h1")
        heights = z_given - np.linspace(h0, h1, nz if h1 > h0 else 1)
    elif region is not None and len(region) == 6:
        heights = np.linspace(region[4], region[5], nz if region[5] > region[4] else 1)
    else:
        heights = np.array([z_given])
    yaws = yaw_values(yaw_range_deg, nyaw)
    ext = None
    if region is None:
        try:
            box, ext = default_region(mi, yaws, heights)
        except InputError as exc:
            if base_height is None:
                raise
            raise InputError("base_height", "",
                             f"every placement is infeasible at robot base heights "
                             f"{base_height[0] * 1e3:g}..{base_height[1] * 1e3:g} mm "
                             f"({exc.problem})", "a height range where the seam is reachable "
                             "within the joint limits") from None
    else:
        box = tuple(region[:4])  # type: ignore[assignment]
        if box[1] < box[0] or box[3] < box[2]:
            raise InputError("region", "", "empty range", "x0 <= x1 and y0 <= y1")
    xs = np.linspace(box[0], box[1], nx if box[1] > box[0] else 1)
    ys = np.linspace(box[2], box[3], ny if box[3] > box[2] else 1)
    return PlacementGrid(xs, ys, yaws, np.sort(heights)), ext
