"""A virtual trial weld: what a welding engineer brings back from the cell.

One open-loop run of a planned path on the :class:`~rfsw_plan.realtime.simulator.VirtualWeld`
(truth robot, process drift, sensor noise and delay), returned as the two measurements of a
real trial weld:

* the **force log** of the wrist sensor, base frame, at the controller cycle (what
  ``plan --forces`` and ``validate-weld --forces`` read; format of
  :mod:`rfsw_plan.io.force_series`);
* the **weld track**: the offset of the weld (the true pin path) from the joint line along the
  seam, ``s_mm, e_lat_mm, e_norm_mm`` every ``track_step`` of arc length, with white
  measurement noise (default 0.05 mm, a laser line scanner) and gaps (scanner drop-outs;
  format of :mod:`rfsw_plan.io.weld_track`).

The truth's pin is what the weld really did (``inside_window_fraction`` along the weld length,
:func:`~rfsw_plan.realtime.metrics.weld_metrics`); the two files are all a user would have.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError
from rfsw_plan.io.force_series import ForceSeries
from rfsw_plan.io.weld_track import WeldTrack
from rfsw_plan.process.problem import Problem
from rfsw_plan.realtime.base import FloatArray, NoCompensation
from rfsw_plan.realtime.compare import PlannedWaypoints, planned_path
from rfsw_plan.realtime.metrics import WeldMetrics, weld_metrics
from rfsw_plan.realtime.simulator import SimConfig, VirtualWeld, WeldRun


@dataclass(frozen=True)
class TrialWeld:
    """Outcome of :func:`simulate_trial_weld`.

    Attributes:
        run: The virtual weld (true pin, lateral error per cycle).
        metrics: Weld metrics of the true pin against the window.
        forces: Logged wrench (sensor noise, delay, drift), base frame.
        track: Measured weld track (noise, gaps), seam form with ``e_norm``.
        truth_e_lat: True lateral offset at the track's s [m], shape (N,) (no noise).
    """

    run: WeldRun
    metrics: WeldMetrics
    forces: ForceSeries
    track: WeldTrack
    truth_e_lat: FloatArray

    def write(self, folder: str | Path, stem: str = "trial") -> tuple[Path, Path]:
        """Write ``<stem>_forces.csv`` and ``<stem>_track.csv`` (atomically) into a folder."""
        from rfsw_plan.files import prepare_output_dir
        from rfsw_plan.io.force_series import write_force_series
        from rfsw_plan.io.weld_track import write_weld_track

        out = prepare_output_dir(folder)
        f_path = write_force_series(out / f"{stem}_forces.csv", self.forces)
        t_path = write_weld_track(out / f"{stem}_track.csv", self.track)
        return f_path, t_path


def simulate_trial_weld(
    problem: Problem,
    plan: PlannedWaypoints,
    model: ElastostaticModel,
    truth: ElastostaticModel | None = None,
    config: SimConfig | None = None,
    track_noise: float = 0.05e-3,
    track_step: float = 0.5e-3,
    gap_fraction: float = 0.03,
    seed: int = 0,
) -> TrialWeld:
    """Run a planned path open loop on the truth and return the log and the track.

    Args:
        problem: The welding problem (seam, process, window, seam reference).
        plan: The planned joints per waypoint (:func:`~rfsw_plan.realtime.compare.planned_waypoints`
            of a plan result, or :func:`~rfsw_plan.validation.plan_record.read_plan_dir`'s).
        model: The robot model the plan was made with (it does not move the pin; kept for the
            controller inputs).
        truth: The robot as it really is (default: the model).
        config: Controller cycle, sensor and process drift (default :class:`SimConfig`).
        track_noise: 1-sigma white noise of the measured track [m] (default 0.05 mm).
        track_step: Arc-length spacing of the track points [m].
        gap_fraction: Share of the track lost in one contiguous drop-out plus isolated points.
        seed: Seed of the track noise and gaps.

    Raises:
        InputError: Negative noise, non-positive step or a gap fraction outside [0, 0.5).
    """
    if not track_noise >= 0:
        raise InputError("trial weld", "track_noise", f"got {track_noise:g}", ">= 0")
    if not track_step > 0:
        raise InputError("trial weld", "track_step", f"got {track_step:g}", "> 0")
    if not 0.0 <= gap_fraction < 0.5:
        raise InputError("trial weld", "gap_fraction", f"got {gap_fraction:g}", "0 <= g < 0.5")
    cfg = config or SimConfig()
    frames = problem.frames()
    schedule = problem.process.schedule(frames, cfg.cycle_s)
    weld = VirtualWeld(schedule, model, truth, cfg, problem.seam_reference)
    path = planned_path(weld, plan)
    run = weld.run(NoCompensation(), path, label="trial")
    measured = weld.measured_wrench(path)
    forces = ForceSeries(t=weld.t.copy(), force=measured[:, :3].copy(),
                         moment=measured[:, 3:].copy(), frame="base", source="virtual trial weld")
    # The true pin along the seam, seam frame, at the track's arc lengths.
    w = run.weld
    s_w, idx = np.unique(run.s[w], return_index=True)
    n_dir = np.stack([np.interp(weld.t, schedule.t, schedule.frames.n[:, j]) for j in range(3)],
                     axis=1)
    n_dir /= np.linalg.norm(n_dir, axis=1, keepdims=True)
    e_norm_c = np.einsum("ki,ki->k", run.pin - run.seam, n_dir)
    s_tr = np.arange(s_w[0], s_w[-1] + 1e-12, track_step)
    e_lat = np.interp(s_tr, s_w, run.lateral_error[w][idx])
    e_norm = np.interp(s_tr, s_w, e_norm_c[w][idx])
    rng = np.random.default_rng(seed)
    lat_m = e_lat + track_noise * rng.standard_normal(s_tr.size)
    norm_m = e_norm + track_noise * rng.standard_normal(s_tr.size)
    keep = np.ones(s_tr.size, dtype=bool)
    n_gap = round(gap_fraction * s_tr.size)
    if n_gap >= 2:
        start = int(rng.integers(s_tr.size // 4, max(s_tr.size // 4 + 1, 3 * s_tr.size // 4)))
        keep[start:start + n_gap // 2] = False
        keep[rng.choice(s_tr.size, n_gap - n_gap // 2, replace=False)] = False
    lat_m = np.where(keep, lat_m, np.nan)
    track = WeldTrack("seam", s_tr, lat_m, np.where(keep, norm_m, np.nan), None,
                      "virtual trial weld", int(np.sum(~keep)))
    return TrialWeld(run=run, metrics=weld_metrics(run, problem.window), forces=forces,
                     track=track, truth_e_lat=e_lat)
