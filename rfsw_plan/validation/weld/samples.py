"""The executed plan at the measured track points: joints, wrench and seam frames.

The predicted pin path of a weld, from the plan's commanded joints (interpolated in arc length
as the controller runs them), under the logged wrench (the model's sensor effects applied,
smoothed over ``smooth_s`` to remove sensor noise the structure does not follow) or the planned
one, with a robot model::

    e_lat(s) = l . (FK_p(q(s)) + dX_p(q(s), F(s)) - p(s))      (advancing side +) [m]
    e_norm(s) = n . (FK_p(q(s)) + dX_p(q(s), F(s)) - p(s))     (up the tool axis +) [m]

(dX the model's process deflection with the problem's seam reference; p the seam point at the
pin depth.) This prediction is the input of the weld diagnosis
(:mod:`rfsw_plan.validation.weld.fit`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError
from rfsw_plan.io.force_series import ForceSeries
from rfsw_plan.planfiles.rebuild import PlannedWaypoints
from rfsw_plan.process.force_fit import series_in_seam_frame
from rfsw_plan.process.frames import FloatArray
from rfsw_plan.process.problem import Problem
from rfsw_plan.process.seam import interpolate_frames


@dataclass(frozen=True)
class WeldSamples:
    """The executed plan at the measured track points (weld phase).

    Attributes:
        s: Arc length from the seam start [m], shape (N,).
        t: Time from the process start at which the tool passes s [s], shape (N,).
        q: Commanded joints [rad], shape (N, n).
        wrench: Wrench used for the prediction, base frame [N, N m], shape (N, 6).
        p: Seam point at the pin depth, base frame [m], shape (N, 3).
        l: Lateral direction (advancing side), shape (N, 3).
        n: Tool axis, shape (N, 3).
        logged: True if the wrench is the (sensor-corrected) log, False if planned.
    """

    s: FloatArray
    t: FloatArray
    q: FloatArray
    wrench: FloatArray
    p: FloatArray
    l: FloatArray
    n: FloatArray
    logged: bool

    def predict(self, model: ElastostaticModel, reference: str) -> tuple[FloatArray, FloatArray]:
        """(e_lat, e_norm) of a model [m], each shape (N,) (module docstring)."""
        batch = model.batch(self.q)
        W = self.wrench
        if self.logged:
            sensor = [e for e in model.groups.wrench if e.sensor_only]
            if sensor:
                W = W + sum((e.delta_wrench(batch, W, e.params) for e in sensor),
                            np.zeros_like(W))
        dX = model.process_deflection_batch(batch, W, reference)  # type: ignore[arg-type]
        d = batch.T[:, :3, 3] + dX[:, :3] - self.p
        return np.einsum("ki,ki->k", d, self.l), np.einsum("ki,ki->k", d, self.n)


def _running_mean_time(t: FloatArray, y: FloatArray, window: float) -> FloatArray:
    """Centred running mean over ``window`` seconds of each column of y (N, d)."""
    if window <= 0 or y.shape[0] < 3:
        return y
    dt = float(np.median(np.diff(t)))
    n = max(1, round(window / dt) | 1)
    c = np.vstack([np.zeros((1, y.shape[1])), np.cumsum(y, axis=0)])
    k = np.arange(y.shape[0])
    lo = np.clip(k - n // 2, 0, y.shape[0])
    hi = np.clip(k + n - n // 2, 0, y.shape[0])
    out: FloatArray = (c[hi] - c[lo]) / (hi - lo)[:, None]
    return out


def weld_samples(
    problem: Problem, plan: PlannedWaypoints, s: FloatArray, series: ForceSeries | None = None,
    smooth_s: float = 0.25,
) -> WeldSamples:
    """Joints, wrench and seam frames where the tool passes the arc lengths ``s`` [m].

    Raises:
        InputError: The plan has no weld waypoints.
    """
    w = plan.phase == "weld"
    if not np.any(w):
        raise InputError("plan", "phase", "the plan has no weld waypoints")
    frames = problem.frames()
    length = float(frames.s[-1] - frames.s[0])
    sched = problem.process.schedule(frames, 0.02)
    ws = np.asarray(sched.phase) == "weld"
    sw, iw = np.unique(sched.s[ws], return_index=True)
    t = np.interp(s, sw, sched.t[ws][iw])
    s_wp, q_wp = plan.s[w], plan.q[w]
    q = np.stack([np.interp(s, s_wp, q_wp[:, j]) for j in range(q_wp.shape[1])], axis=1)
    fr = interpolate_frames(frames, frames.s[0] + np.clip(s, 0.0, length))
    at = problem.process.evaluate(frames, t)
    if series is None:
        wrench = at.wrench_base
        logged = False
    else:
        rot = problem.planning.tool_rotation
        sch_log = problem.process.evaluate(frames, series.t)
        f_seam, m_seam = series_in_seam_frame(series, sch_log, rot)
        f_seam = _running_mean_time(series.t, f_seam, smooth_s)
        f_t = np.stack([np.interp(t, series.t, f_seam[:, j]) for j in range(3)], axis=1)
        force = at.frames.to_base(f_t)
        if m_seam is not None:
            m_seam = _running_mean_time(series.t, m_seam, smooth_s)
            m_t = np.stack([np.interp(t, series.t, m_seam[:, j]) for j in range(3)], axis=1)
            moment = at.frames.to_base(m_t)
        else:
            moment = at.moment_base
        wrench = np.hstack([force, moment])
        logged = True
    return WeldSamples(s=s, t=t, q=q, wrench=wrench, p=fr.p, l=fr.l, n=fr.n, logged=logged)


__all__ = ["WeldSamples", "weld_samples"]
