"""The measured weld track as offsets along the seam, and its noise floor.

A laser line scan of the bead, or seed 000's lateral offset Delta y = D1 - D2 (Figs. 15-17),
read by :mod:`rfsw_plan.io.weld_track`, becomes offsets from the joint line at arc lengths of
the seam (:func:`track_on_seam`, checked for units and overlap). The noise floor sigma of a
residual along the seam is estimated from successive differences (:func:`noise_floor`): the
model error is smooth along the seam, the measurement noise is not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rfsw_plan.exceptions import InputError
from rfsw_plan.io.weld_track import WeldTrack
from rfsw_plan.process.frames import FloatArray
from rfsw_plan.process.problem import Problem

#: A median |offset| above this is not a weld deviation: wrong units or wrong frame [m].
MAX_MEDIAN_OFFSET = 20e-3
#: A track whose largest |offset| is below this [m] is in metres in ``_mm`` columns (a weld
#: wanders by tenths of a millimetre, a scanner resolves about 0.01 mm).
MIN_PEAK_OFFSET = 5e-6
#: The track must overlap at least this share of the seam.
MIN_OVERLAP_SHARE = 0.25


@dataclass(frozen=True)
class TrackOnSeam:
    """The measured track as offsets along the seam, inside the seam.

    Attributes:
        s: Arc length [m], shape (N,), increasing.
        e_lat: Measured lateral offset [m], (N,).
        e_norm: Measured normal offset [m], (N,), or None.
        overlap: (start, end) of the track on the seam [m].
        seam_length: Seam length [m].
        dropped: Points outside the seam.
        gaps: Rows of the file with a gap.
    """

    s: FloatArray
    e_lat: FloatArray
    e_norm: FloatArray | None
    overlap: tuple[float, float]
    seam_length: float
    dropped: int
    gaps: int


def track_on_seam(track: WeldTrack, problem: Problem) -> TrackOnSeam:
    """Offsets of the track from the joint line along the seam (seam form as it is; base
    form projected on the nearest seam point), checked for units and overlap.

    Raises:
        InputError: Median |offset| above :data:`MAX_MEDIAN_OFFSET` (wrong units or frame), or
            the track overlaps less than :data:`MIN_OVERLAP_SHARE` of the seam (says the
            overlap).
    """
    frames = problem.frames()
    length = float(frames.s[-1] - frames.s[0])
    src = track.source
    if track.form == "base":
        assert track.xyz is not None
        dense = problem.seam.frames(min(0.5e-3, length / 50))
        from scipy.spatial import cKDTree

        k = np.asarray(cKDTree(dense.p).query(track.xyz)[1], dtype=int)
        dk = track.xyz - dense.p[k]
        s = dense.s[k] - dense.s[0] + np.einsum("ki,ki->k", dk, dense.t[k])
        e_lat = np.einsum("ki,ki->k", dk, dense.l[k])
        e_norm = None
        where = "x_mm, y_mm, z_mm projected on the seam"
        order = np.argsort(s)
        s, e_lat = s[order], e_lat[order]
    else:
        assert track.s is not None and track.e_lat is not None
        s, e_lat, e_norm = track.s, track.e_lat, track.e_norm
        where = "column e_lat_mm"
    ok = np.isfinite(s) & np.isfinite(e_lat)
    if e_norm is not None:
        ok &= np.isfinite(e_norm)
    gaps = track.n_gaps + int(np.sum(~ok))
    s, e_lat = s[ok], e_lat[ok]
    e_norm = None if e_norm is None else e_norm[ok]
    if s.size < 3:
        raise InputError(src, "", f"{s.size} measured point(s)", "at least 3")
    med = float(np.median(np.abs(e_lat)))
    if med > MAX_MEDIAN_OFFSET:
        raise InputError(src, where, f"median offset {med * 1e3:.4g} mm = {med:.3g} m from the "
                         "joint line: wrong units or wrong frame",
                         f"offsets of a few mm at most (window {problem.window.lower * 1e3:g}.."
                         f"{problem.window.upper * 1e3:g} mm), in mm")
    peak = float(np.max(np.abs(e_lat)))
    if 0.0 < peak < MIN_PEAK_OFFSET:  # 0.0008 "mm": 0.8 mm written in metres
        raise InputError(src, where, f"every offset is below {MIN_PEAK_OFFSET * 1e3:g} mm "
                         f"(largest {peak * 1e3:.3g} mm): metres instead of mm?",
                         f"offsets in mm (x1000: largest {peak * 1e6:.3g} mm); no weld and no "
                         "scanner is that exact")
    lo, hi = max(float(s[0]), 0.0), min(float(s[-1]), length)
    ov = max(hi - lo, 0.0)
    inside = (s >= -1e-9) & (s <= length + 1e-9)
    if ov < MIN_OVERLAP_SHARE * length or int(np.sum(inside)) < 3:
        hint = " (s in metres?)" if float(s[-1]) < length * 1e3 * 2e-3 and track.form == "seam" \
            else ""
        raise InputError(src, "s" if track.form == "seam" else "x_mm, y_mm, z_mm",
                         f"the track covers s = {float(s[0]) * 1e3:.1f}..{float(s[-1]) * 1e3:.1f}"
                         f" mm, the seam 0..{length * 1e3:.1f} mm: overlap {ov * 1e3:.1f} mm "
                         f"({100 * ov / length:.0f} %){hint}",
                         f"a track along at least {100 * MIN_OVERLAP_SHARE:.0f} % of the seam")
    return TrackOnSeam(s=s[inside], e_lat=e_lat[inside],
                       e_norm=None if e_norm is None else e_norm[inside], overlap=(lo, hi),
                       seam_length=length, dropped=int(np.sum(~inside)), gaps=gaps)


def noise_floor(s: FloatArray, r: FloatArray) -> float:
    """1-sigma measurement noise from successive differences of the residual [m]:
    sigma^2 = mean((r_k+1 - r_k)^2) / 2 over neighbours no further apart than twice the
    median spacing (a gap does not count as a difference)."""
    ds = np.diff(s)
    dr = np.diff(r)
    near = ds <= 2.0 * float(np.median(ds))
    if not np.any(near):
        return float(np.std(r))
    return float(np.sqrt(np.mean(dr[near] ** 2) / 2.0))


__all__ = ["MAX_MEDIAN_OFFSET", "MIN_OVERLAP_SHARE", "TrackOnSeam", "noise_floor",
           "track_on_seam"]
