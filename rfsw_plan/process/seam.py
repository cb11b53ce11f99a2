"""The taught seam: points, interpolation, tool tilt, rotation sense, and seam frames.

A seam is taught as two or more points in the robot base frame (seed 000 §3.2.6 teaches the
first and last point of the butt joint; seed 001 Table 6 gives a start and an end point). The
points are joined by straight segments (``'linear'``) or a cubic spline through them
(``'spline'``, chord-length parameterised). Travel goes from the first to the last point
(``reverse=True`` flips it).

Frames at arc length s (all base frame, unit vectors; see :mod:`rfsw_plan.process.frames`):

* ``t_s`` seam tangent, ``n_s`` surface normal made orthogonal to ``t_s``;
* ``l = sigma * (n_s x t_s)`` toward the advancing side, sigma = +1 for a clockwise spindle
  (seen from above, looking down the tool axis) and -1 for counter-clockwise;
* the tool tilt theta (trailing, seed 001: 2 deg) turns the pair (t_s, n_s) about l so the top
  of the tool leans back against travel::

      n = cos(theta) n_s - sin(theta) t_s        (tool axis, workpiece -> spindle)
      t = cos(theta) t_s + sin(theta) n_s        (travel direction in the tool's plane)

  so (t, l, n) stays orthonormal and the process forces measured in the tool frame (axial
  along the tool axis, traverse normal to it; seed 001 Fig. 3c) map directly onto it. With
  theta = 0, t is the seam tangent. (t, l, n) is right-handed for 'cw', left-handed for 'ccw'.

Why clockwise gives l = n_s x t_s: a spindle turning clockwise seen from above has angular
velocity omega = -w n_s; the tool surface velocity omega x r at r = R (n_s x t_s) is
+w R t_s, i.e. along travel, which is the definition of the advancing side.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import numpy as np

from rfsw_plan.exceptions import InputError
from rfsw_plan.process.frames import FloatArray, SeamFrames

if TYPE_CHECKING:
    from scipy.interpolate import CubicSpline

#: Largest tool tilt accepted [deg] (FSW tools are tilted 0-5 deg; 15 deg is a sanity bound).
MAX_TILT_DEG = 15.0
#: Points closer than this are duplicates [m].
DUPLICATE_TOL = 1e-6
#: Interpolation names.
INTERPOLATIONS = ("linear", "spline")
#: Spindle rotation senses, seen from above looking down the tool axis.
ROTATIONS = ("cw", "ccw")

Interpolation = Literal["linear", "spline"]
Rotation = Literal["cw", "ccw"]


def rotation_sign(rotation: str, source: str = "seam", where: str = "rotation") -> float:
    """+1 for 'cw', -1 for 'ccw' (the sign sigma of l = sigma n_s x t_s).

    Raises:
        InputError: Any other value.
    """
    if rotation not in ROTATIONS:
        raise InputError(source, where, f"unknown rotation sense '{rotation}'", "'cw' or 'ccw'")
    return 1.0 if rotation == "cw" else -1.0


def _unit(v: FloatArray) -> FloatArray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass(frozen=True)
class Seam:
    """A taught seam with its process-related orientation parameters.

    Attributes:
        points: Taught points on the joint line at the pin-tip depth, base frame [m],
            shape (m, 3), m >= 2, in travel order (before ``reverse``).
        interpolation: 'linear' (polyline) or 'spline' (C2 cubic through the points).
        tilt: Trailing tool tilt angle theta [rad], |theta| <= 15 deg.
        rotation: Spindle rotation sense 'cw' or 'ccw' seen from above (looking down the tool
            axis toward the workpiece).
        surface_normal: Workpiece surface normal, base frame, shape (3,) for all points or
            (m, 3) per point; default +z of the base.
        reverse: Travel from the last point to the first.
        source: Name of the file/option the seam came from (for error messages).
    """

    points: FloatArray
    interpolation: Interpolation = "linear"
    tilt: float = 0.0
    rotation: Rotation = "cw"
    surface_normal: FloatArray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    reverse: bool = False
    source: str = "seam"
    # Derived in __post_init__ (travel order applied): points, normals, chord parameter,
    # spline, and the dense arc-length table s(u).
    _pts: FloatArray = field(init=False, repr=False, compare=False)
    _nrm: FloatArray = field(init=False, repr=False, compare=False)
    _u: FloatArray = field(init=False, repr=False, compare=False)
    _spl: CubicSpline | None = field(init=False, repr=False, compare=False)
    _uu: FloatArray = field(init=False, repr=False, compare=False)
    _ss: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        src = self.source
        pts = np.asarray(self.points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise InputError(src, "points", f"got shape {pts.shape}", "a list of (x, y, z) points")
        if pts.shape[0] < 2:
            raise InputError(src, "points", f"got {pts.shape[0]} point(s)", "at least 2 points")
        if not np.all(np.isfinite(pts)):
            raise InputError(src, "points", "points contain NaN or infinity", "finite values")
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        if float(np.max(np.linalg.norm(pts - pts[0], axis=1))) < DUPLICATE_TOL:
            raise InputError(src, "points", "zero-length seam: all points coincide",
                             "a seam longer than 1 um")
        dup = np.flatnonzero(seg < DUPLICATE_TOL)
        if dup.size:
            i = int(dup[0])
            raise InputError(src, f"points {i + 1} and {i + 2}",
                             "duplicate consecutive points", "distinct consecutive points")
        if self.interpolation not in INTERPOLATIONS:
            raise InputError(src, "interpolation", f"unknown interpolation "
                             f"'{self.interpolation}'", "'linear' or 'spline'")
        rotation_sign(self.rotation, src)
        if not np.isfinite(self.tilt) or abs(np.rad2deg(self.tilt)) > MAX_TILT_DEG + 1e-12:
            raise InputError(src, "tilt_deg", f"tilt {np.rad2deg(self.tilt):g} deg is out of range",
                             f"|tilt| <= {MAX_TILT_DEG:g} deg")
        nrm = np.asarray(self.surface_normal, dtype=float)
        if nrm.shape not in ((3,), (pts.shape[0], 3)):
            raise InputError(src, "surface_normal", f"got shape {nrm.shape}",
                             f"3 values or one normal per point ({pts.shape[0]})")
        if not np.all(np.isfinite(nrm)) or np.any(np.linalg.norm(nrm, axis=-1) < 1e-12):
            raise InputError(src, "surface_normal", "zero or non-finite normal",
                             "a non-zero vector")
        nrm = np.broadcast_to(_unit(nrm), pts.shape).copy()
        if self.reverse:
            pts, nrm = pts[::-1].copy(), nrm[::-1].copy()
        # Chord-length parameter of the taught points [m].
        u = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
        object.__setattr__(self, "_pts", pts)
        object.__setattr__(self, "_nrm", nrm)
        object.__setattr__(self, "_u", u)
        if self.interpolation == "spline" and pts.shape[0] >= 3:
            from scipy.interpolate import CubicSpline  # a spline seam's only use of SciPy's

            spl = CubicSpline(u, pts, axis=0, bc_type="not-a-knot")
        else:
            spl = None
        object.__setattr__(self, "_spl", spl)
        # Dense arc-length table s(u) for the spline (the polyline has s = u).
        if spl is None:
            uu, ss = u, u
        else:
            uu = np.linspace(0.0, u[-1], max(2001, 50 * pts.shape[0]))
            d = np.linalg.norm(spl(uu, 1), axis=1)
            ss = np.concatenate([[0.0], np.cumsum(0.5 * (d[1:] + d[:-1]) * np.diff(uu))])
        object.__setattr__(self, "_uu", uu)
        object.__setattr__(self, "_ss", ss)
        for i, (tt, nn) in enumerate(zip(self._tangent(u), nrm, strict=True)):
            if abs(float(tt @ nn)) > 1.0 - 1e-6:
                raise InputError(src, f"point {i + 1}", "seam tangent is parallel to the surface "
                                 "normal", "a seam that runs along the surface")

    # -- geometry ----------------------------------------------------------------------------
    @property
    def length(self) -> float:
        """Arc length of the seam [m]."""
        return float(self._ss[-1])

    @property
    def sigma(self) -> float:
        """+1 for a clockwise spindle, -1 for counter-clockwise."""
        return rotation_sign(self.rotation, self.source)

    def _u_of_s(self, s: FloatArray) -> FloatArray:
        return np.interp(s, self._ss, self._uu)

    def _position(self, u: FloatArray) -> FloatArray:
        if self._spl is not None:
            return np.asarray(self._spl(u), dtype=float)
        pts, uk = self._pts, self._u
        return np.stack([np.interp(u, uk, pts[:, i]) for i in range(3)], axis=-1)

    def _tangent(self, u: FloatArray) -> FloatArray:
        if self._spl is not None:
            return _unit(self._spl(u, 1))
        pts, uk = self._pts, self._u
        seg = np.clip(np.searchsorted(uk, u, side="right") - 1, 0, len(uk) - 2)
        return _unit(pts[seg + 1] - pts[seg])

    def _normal(self, u: FloatArray) -> FloatArray:
        nrm, uk = self._nrm, self._u
        return _unit(np.stack([np.interp(u, uk, nrm[:, i]) for i in range(3)], axis=-1))

    def surface_normal_at(self, s: FloatArray) -> FloatArray:
        """The declared surface normal (``surface_normal``, unit, interpolated between the
        points) at arc lengths s [m], base frame, shape (k, 3); unlike the frames' normal it
        is not made normal to the seam tangent."""
        return self._normal(self._u_of_s(np.clip(np.asarray(s, dtype=float), 0, self.length)))

    def frames_at(self, s: FloatArray) -> SeamFrames:
        """Seam frames at given arc lengths.

        Args:
            s: Arc length from the seam start [m], shape (k,), within [0, length].

        Returns:
            Frames (base frame) with p on the joint line at the pin-tip depth.
        """
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        u = self._u_of_s(s)
        p = self._position(u)
        ts = self._tangent(u)
        ns = self._normal(u)
        ns = _unit(ns - ts * np.einsum("ki,ki->k", ns, ts)[:, None])
        lat = self.sigma * np.cross(ns, ts)
        c, sn = np.cos(self.tilt), np.sin(self.tilt)
        n = c * ns - sn * ts
        t = c * ts + sn * ns
        return SeamFrames(s=s, p=p, t=t, l=lat, n=n)

    def frames(self, spacing: float) -> SeamFrames:
        """Seam frames at waypoints evenly spaced in arc length, both ends included.

        Args:
            spacing: Largest distance between waypoints [m], > 0.

        Raises:
            InputError: Non-positive spacing.
        """
        if not np.isfinite(spacing) or spacing <= 0:
            raise InputError(self.source, "spacing_mm", f"got {spacing * 1e3:g}", "> 0")
        k = int(np.ceil(self.length / spacing - 1e-9)) + 1
        return self.frames_at(np.linspace(0.0, self.length, max(k, 2)))

    def seam_tangent(self, s: FloatArray) -> FloatArray:
        """Untilted seam tangent t_s at arc lengths s [m], base frame, shape (k, 3)."""
        return self._tangent(self._u_of_s(np.clip(np.asarray(s, dtype=float), 0, self.length)))


def interpolate_frames(frames: SeamFrames, s: FloatArray) -> SeamFrames:
    """Frames at arbitrary arc lengths, interpolated between waypoint frames.

    Positions are interpolated linearly in s; the direction triad is interpolated linearly
    and re-orthonormalised (t first, then n, then l keeps its side). Exact at the waypoints.

    Args:
        frames: Waypoint frames (k >= 1 rows, s strictly increasing).
        s: Query arc lengths [m], shape (N,); clipped to the frames' range.
    """
    s = np.asarray(s, dtype=float)
    if len(frames) == 1:
        idx = np.zeros(s.shape, dtype=int)
        return SeamFrames(s=s.copy(), p=frames.p[idx], t=frames.t[idx], l=frames.l[idx],
                          n=frames.n[idx])
    sc = np.clip(s, frames.s[0], frames.s[-1])

    def lerp(a: FloatArray) -> FloatArray:
        return np.stack([np.interp(sc, frames.s, a[:, i]) for i in range(3)], axis=-1)

    t = _unit(lerp(frames.t))
    n = lerp(frames.n)
    n = _unit(n - t * np.einsum("ki,ki->k", n, t)[:, None])
    lat = lerp(frames.l)
    lat = lat - t * np.einsum("ki,ki->k", lat, t)[:, None]
    lat = _unit(lat - n * np.einsum("ki,ki->k", lat, n)[:, None])
    return SeamFrames(s=s.copy(), p=lerp(frames.p), t=t, l=lat, n=n)
