"""Weld-quality metrics of a virtual weld, measured along the weld length.

All metrics use the weld phase only and weight each cycle by the arc length it covers, so a
slower weld speed does not change them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rfsw_plan.process.window import WeldWindow
from rfsw_plan.realtime.base import FloatArray
from rfsw_plan.realtime.simulator import WeldRun


@dataclass(frozen=True)
class DirectionChange:
    """Behaviour where the travel direction turns (e.g. the arc of a curved seam).

    Attributes:
        s_start: Start of the turning region, from the weld start [m].
        s_end: End of the region plus the look-ahead after it [m].
        turn_angle: Total change of travel direction in the region [rad].
        max_abs_lateral: Max |lateral error| in the region [m].
        inside_window_fraction: Fraction of the region's length inside the window [-].
    """

    s_start: float
    s_end: float
    turn_angle: float
    max_abs_lateral: float
    inside_window_fraction: float

    def to_dict(self) -> dict[str, float]:
        """JSON-ready dictionary with mm/deg units in the keys."""
        return {
            "s_start_mm": self.s_start * 1e3,
            "s_end_mm": self.s_end * 1e3,
            "turn_angle_deg": float(np.rad2deg(self.turn_angle)),
            "max_abs_lateral_mm": self.max_abs_lateral * 1e3,
            "inside_window_fraction": self.inside_window_fraction,
        }


@dataclass(frozen=True)
class WeldMetrics:
    """Metrics of one virtual weld.

    Attributes:
        inside_window_fraction: Fraction of the weld length with the pin in the window [-].
        max_abs_lateral: Max |lateral error| over the weld [m].
        rms_lateral: Length-weighted RMS of the lateral error over the weld [m].
        mean_lateral: Length-weighted mean lateral error [m].
        settling: Length from the weld start until the pin stays inside the window [m]
            (0 if it never leaves; the weld length if it never settles, see ``settled``).
        start_error: Lateral error at the weld start [m].
        weld_length: Weld length [m].
        direction_change: Behaviour at the largest change of travel direction, if the seam
            turns (None for a straight seam).
    """

    inside_window_fraction: float
    max_abs_lateral: float
    rms_lateral: float
    mean_lateral: float
    settling: float
    start_error: float
    weld_length: float
    direction_change: DirectionChange | None = None
    settled: bool = True

    def settling_text(self) -> str:
        """Settling distance for tables: mm, or ``never`` if the pin ends outside."""
        return f"{self.settling * 1e3:.1f}" if self.settled else "never"

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary with mm units in the keys."""
        out: dict[str, object] = {
            "inside_window_fraction": self.inside_window_fraction,
            "max_abs_lateral_mm": self.max_abs_lateral * 1e3,
            "rms_lateral_mm": self.rms_lateral * 1e3,
            "settling_mm": self.settling * 1e3,
            "settled": self.settled,
            "mean_lateral_mm": self.mean_lateral * 1e3,
            "start_error_mm": self.start_error * 1e3,
            "weld_length_mm": self.weld_length * 1e3,
        }
        out["direction_change"] = (
            self.direction_change.to_dict() if self.direction_change else None
        )
        return out


def _segment_weights(s: FloatArray) -> FloatArray:
    """Arc length attributed to each sample (half the distance to each neighbour) [m]."""
    ds = np.diff(s)
    w = np.zeros_like(s)
    w[:-1] += 0.5 * ds
    w[1:] += 0.5 * ds
    return w


def _turning_region(
    s: FloatArray, travel: FloatArray, min_curvature: float, look_after: float
) -> tuple[int, int, float] | None:
    """Indices [i0, i1) of the main turning region and its turn angle, or None."""
    if len(s) < 3:
        return None
    cosang = np.clip(np.einsum("ki,ki->k", travel[1:], travel[:-1]), -1.0, 1.0)
    dth = np.arccos(cosang)
    ds = np.diff(s)
    curv = np.divide(dth, ds, out=np.zeros_like(dth), where=ds > 1e-12)
    turning = curv > min_curvature
    if not np.any(turning):
        return None
    # Largest connected run of turning segments.
    edges = np.diff(np.concatenate([[0], turning.astype(int), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    angles = [float(dth[a:b].sum()) for a, b in zip(starts, ends, strict=True)]
    j = int(np.argmax(angles))
    i0, i1 = int(starts[j]), int(ends[j]) + 1
    i1 = int(np.searchsorted(s, s[i1 - 1] + look_after, side="right"))
    return i0, max(i1, i0 + 1), angles[j]


def weld_metrics(
    run: WeldRun,
    window: WeldWindow,
    min_curvature: float = 1.0,
    look_after: float = 20e-3,
) -> WeldMetrics:
    """Metrics of a virtual weld against the weld window.

    Args:
        run: The simulated weld.
        window: The weld window (lateral bounds) [m].
        min_curvature: Travel-direction change rate that counts as turning [rad/m]
            (1 rad/m = a 1 m radius).
        look_after: Length after the turning region still attributed to it [m].
    """
    w = run.weld
    s = run.s[w]
    e = run.lateral_error[w]
    s = s - s[0]
    wt = _segment_weights(s)
    L = float(s[-1])
    inside = (e >= window.lower) & (e <= window.upper)
    total = float(wt.sum())
    frac = float(wt[inside].sum() / total) if total > 0 else float(inside.all())
    rms = float(np.sqrt(np.sum(wt * e**2) / total)) if total > 0 else float(np.abs(e).max())
    mean = float(np.sum(wt * e) / total) if total > 0 else float(e.mean())
    out_idx = np.flatnonzero(~inside)
    settled = not (out_idx.size and out_idx[-1] == len(e) - 1)
    if out_idx.size == 0:
        settling = 0.0
    elif out_idx[-1] == len(e) - 1:
        settling = L
    else:
        settling = float(s[out_idx[-1] + 1])
    dc = None
    region = _turning_region(s, run.travel[w], min_curvature, look_after)
    if region is not None:
        i0, i1, ang = region
        er, wr = e[i0:i1], wt[i0:i1]
        ins = inside[i0:i1]
        dc = DirectionChange(
            s_start=float(s[i0]), s_end=float(s[i1 - 1]), turn_angle=ang,
            max_abs_lateral=float(np.abs(er).max()),
            inside_window_fraction=float(wr[ins].sum() / wr.sum()) if wr.sum() > 0 else 1.0,
        )
    return WeldMetrics(
        inside_window_fraction=frac, max_abs_lateral=float(np.abs(e).max()), rms_lateral=rms,
        mean_lateral=mean, settling=settling, start_error=float(e[0]), weld_length=L,
        direction_change=dc, settled=settled,
    )


__all__ = ["DirectionChange", "WeldMetrics", "weld_metrics"]
