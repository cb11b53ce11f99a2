"""The planning task: the waypoints the NLP places the robot at, with their frames and loads.

A task has ``K = m + k`` waypoints: first ``m`` stationary *time waypoints* at the seam start
(plunge and dwell, where the forces ramp up while the tool does not travel), then the ``k``
weld waypoints along the seam. Every waypoint has a seam frame, a nominal TCP target (the seam
point; during the plunge raised along the tool axis by the depth still to go), the wrench on the
tool and the time it is reached (stationary ones) or the travel from the previous one.

Fake-target offsets are stored as (K, 3) arrays (lateral, normal, along-track) [m]: the commanded
TCP position is p_k + o_lat l_k + o_norm n_k + o_along t_k (:func:`offsets3` pads a (K, 2)
array of lateral and normal offsets with a zero along-track column).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.model import SeamReference
from rfsw_plan.exceptions import InputError
from rfsw_plan.process.frames import LoadSchedule, SeamFrames
from rfsw_plan.process.seam import interpolate_frames

if TYPE_CHECKING:
    from rfsw_plan.process.problem import Problem

FloatArray = NDArray[np.float64]

#: Sample time of the load schedule a task is built from [s].
SCHEDULE_DT = 0.05
#: Largest lateral motion of the predicted pin while the tool stands in the plate (plunge,
#: dwell, weld start) [m]: the pin stirs one hole; moving it sideways while standing widens it
#: (issue 38's limit for the dwell).
STANDSTILL_MOTION = 0.05e-3
#: Largest depth error of the predicted pin while the tool stands at full depth (the plunge's
#: end, the dwell, the weld start) [m] (+- along the tool axis).
STANDING_DEPTH_TOL = 0.05e-3
#: Default largest number of stationary (plunge, dwell) waypoints of a task.
MAX_START_WAYPOINTS = 12


@dataclass(frozen=True)
class PlanTask:
    """Waypoints to plan, base frame, SI.

    Attributes:
        frames: Seam frame of every waypoint (K rows; stationary ones repeat the start frame).
        target: Nominal TCP target (seam point, raised along n while plunging) [m], (K, 3).
        force_seam: Force on the tool in the seam frame (f_t, f_l, f_n) [N], (K, 3).
        moment_base: Moment on the tool at the TCP, base frame [N m], (K, 3).
        phase: Phase of every waypoint ("plunge", "dwell" or "weld"), (K,).
        time: Time each waypoint is reached in the schedule [s], (K,), non-decreasing.
        depth: Commanded plunge depth below the surface [m], (K,).
        n_start: Number of stationary waypoints m at the start.
        travel_speed: Weld travel speed [m/s].
        reference: How the seam points relate to the robot (``taught`` or ``absolute``); the
            modelled process wrench deflects the TCP by
            :meth:`~rfsw_plan.elastostatics.model.ElastostaticModel.process_deflection` with it.
        axial_control: ``position`` or ``force`` (the process's, see
            :class:`~rfsw_plan.process.forces.ProcessModel`): under force control the axial
            force is the controller's set force, so its uncertainty does not deflect the
            robot (:attr:`spread_weights`) and the depth is the controller's.
        penetration_stiffness: Slope k_p [N/m] of the process's penetration law
            (``[process.coupling]``, :class:`~rfsw_plan.process.cosim.PenetrationLaw`) under
            position control, 0 without one: the robust claim then spreads the material's
            response, not the axial force (:func:`~rfsw_plan.planning.verify.robust_claim`).
        stop_time: Times of the end stop from the weld's end [s], (E,), increasing from 0
            (empty: no end stop): the tool stands at the last weld waypoint, the pin in the
            plate, while the forces relax (:meth:`~rfsw_plan.process.forces.ProcessModel.profile`).
        stop_force_seam: The force on the tool at those times in the last waypoint's seam
            frame (f_t, f_l, f_n) [N], (E, 3) (the first row is the weld's last force).
    """

    frames: SeamFrames
    target: FloatArray
    force_seam: FloatArray
    moment_base: FloatArray
    phase: NDArray[np.str_]
    time: FloatArray
    depth: FloatArray
    n_start: int
    travel_speed: float
    reference: SeamReference = "taught"
    axial_control: str = "position"
    penetration_stiffness: float = 0.0
    stop_time: FloatArray = field(default_factory=lambda: np.zeros(0))
    stop_force_seam: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))

    @property
    def end_stop(self) -> float:
        """Length of the end stop [s] (0: none)."""
        return float(self.stop_time[-1]) if len(self.stop_time) else 0.0

    def __len__(self) -> int:
        return int(self.target.shape[0])

    @property
    def spread_weights(self) -> FloatArray:
        """Which seam-frame force components (f_t, f_l, f_n) are uncertain, (3,): all under
        position control; under axial force control the controller holds f_n at its set
        force, so only f_t and f_l (seed 000 §2: the force loop acts along the tool axis)."""
        return np.array([1.0, 1.0, 0.0 if self.axial_control == "force" else 1.0])

    @property
    def plate_normal(self) -> FloatArray:
        """The plate (surface) normal at every waypoint, (K, 3): the tool axis n without its
        part along the seam's own direction (the tilt turns t and n together about l, so the
        untilted seam tangent comes from the seam points: d p / d s over the weld
        waypoints; stationary waypoints take the first weld waypoint's)."""
        return plate_normals(self.frames.s[self.n_start:], self.frames.p[self.n_start:],
                             self.frames.n, self.frames.s)

    @property
    def at_surface(self) -> NDArray[np.bool_]:
        """Waypoints at the plunge start (plunge phase, depth 0: the pin touches the surface
        at zero force), (K,)."""
        return np.asarray((self.phase == "plunge") & (self.depth <= 0))

    @property
    def standing(self) -> NDArray[np.bool_]:
        """Waypoints where the tool stands at the seam start with the pin in the plate, (K,):
        the plunge (below the surface) and the dwell, and the first weld waypoint (the weld
        starts from rest, at the dwell's last force). The pin must not move sideways there
        (:data:`STANDSTILL_MOTION`)."""
        stand = np.zeros(len(self), dtype=bool)
        stand[: self.n_start] = True
        if self.n_start and len(self) > self.n_start:
            stand[self.n_start] = True
        return np.asarray(stand & ~self.at_surface)

    @property
    def standing_full(self) -> NDArray[np.bool_]:
        """Standing waypoints at full depth (the plunge's end, the dwell, the weld start), (K,):
        there the pin is at the planned depth (:data:`STANDING_DEPTH_TOL`), so the plunge
        ends where it was planned to, not shallower with the rest sinking during the dwell."""
        full = float(np.max(self.depth)) if len(self) else 0.0
        return np.asarray(self.standing & (self.depth >= full - 1e-12))

    @property
    def s(self) -> FloatArray:
        """Arc length [m], (K,)."""
        return self.frames.s

    @property
    def wrench_base(self) -> FloatArray:
        """Wrench on the tool at the TCP, base frame [N, N m], (K, 6)."""
        return np.hstack([self.frames.to_base(self.force_seam), self.moment_base])

    @property
    def weld(self) -> slice:
        """Slice of the weld waypoints."""
        return slice(self.n_start, len(self))

    def link_travel(self) -> FloatArray:
        """Travel between neighbours [m], (K - 1,) (0 for stationary links)."""
        return np.diff(self.s)

    def link_times(self) -> FloatArray:
        """Time between neighbours [s], (K - 1,)."""
        return np.diff(self.time)

    def link_lengths(self) -> FloatArray:
        """Equivalent travel h of each link [m], (K - 1,): the travel, or for a stationary
        link the distance the time step stands for at the travel speed (floor 1 um)."""
        return np.maximum(np.maximum(self.link_travel(), self.link_times() * self.travel_speed),
                          1e-6)


def plate_normals(sw: FloatArray, pw: FloatArray, n: FloatArray, s: FloatArray) -> FloatArray:
    """Plate normals at arc lengths s (N,) with tool axes n (N, 3): n without its part along
    the seam tangent d p / d s of the weld points (sw (k,) [m], pw (k, 3) [m]), interpolated
    linearly in s; unit, (N, 3)."""
    sw = np.asarray(sw, dtype=float)
    pw = np.asarray(pw, dtype=float)
    n = np.atleast_2d(np.asarray(n, dtype=float))
    if len(sw) < 2:
        return np.asarray(n / np.linalg.norm(n, axis=1, keepdims=True))
    tw = np.gradient(pw, sw, axis=0)
    ts = np.stack([np.interp(s, sw, tw[:, i]) for i in range(3)], axis=1)
    ts /= np.linalg.norm(ts, axis=1, keepdims=True)
    v = n - np.einsum("ki,ki->k", n, ts)[:, None] * ts
    return np.asarray(v / np.linalg.norm(v, axis=1, keepdims=True))


def offsets3(offsets: FloatArray) -> FloatArray:
    """Offsets (lateral, normal, along-track) [m], shape (K, 3), from a (K, 2) or (K, 3) array
    (a (K, 2) array has no along-track part)."""
    o = np.atleast_2d(np.asarray(offsets, dtype=float))
    if o.shape[1] == 2:
        o = np.column_stack([o, np.zeros(len(o))])
    if o.shape[1] != 3:
        raise InputError("plan", "offsets", f"shape {o.shape}", "(K, 2) or (K, 3)")
    return o


def _stack(a: SeamFrames, b: SeamFrames) -> SeamFrames:
    return SeamFrames(*(np.concatenate([getattr(a, f), getattr(b, f)])
                        for f in ("s", "p", "t", "l", "n")))


def task_constant_force(
    frames: SeamFrames, force_seam: FloatArray, travel_speed: float,
    reference: SeamReference = "taught",
) -> PlanTask:
    """A task of weld waypoints only, with one seam-frame force everywhere (tests, baselines).

    Args:
        frames: Weld waypoints (k rows).
        force_seam: Force (f_t, f_l, f_n) [N], shape (3,) or (k, 3).
        travel_speed: Weld speed [m/s].
        reference: Seam reference (see :class:`PlanTask`).
    """
    k = len(frames)
    f = np.broadcast_to(np.asarray(force_seam, dtype=float), (k, 3)).copy()
    return PlanTask(frames, frames.p.copy(), f, np.zeros((k, 3)), np.full(k, "weld"),
                    (frames.s - frames.s[0]) / travel_speed, np.zeros(k), 0, float(travel_speed),
                    reference)


def schedule_for(problem: Problem, frames: SeamFrames | None = None) -> LoadSchedule:
    """The load schedule of a problem's process along its seam frames (default: at the
    problem's spacing), sampled every :data:`SCHEDULE_DT` without the approach: the schedule
    every task and every rebuilt plan is made from."""
    return problem.process.schedule(problem.frames() if frames is None else frames,
                                    SCHEDULE_DT, approach=False)


def task_for(problem: Problem, spacing: float | None = None,
             max_start: int = MAX_START_WAYPOINTS) -> PlanTask:
    """The planning task of a problem: seam frames at ``spacing`` [m] (default: the problem's),
    its load schedule (:func:`schedule_for`), then :func:`task_from_schedule` with the
    problem's seam reference.

    The one recipe shared by the planner (:func:`rfsw_plan.planning.api.plan`), the placement
    map, and the plan folder's rebuild (``check``, ``validate-weld``), so a written plan is
    re-verified on the task it was planned on.

    Args:
        problem: The problem.
        spacing: Weld waypoint spacing along the seam [m] (default: ``problem.spacing``).
        max_start: Most stationary waypoints (the planner option ``max_start_waypoints``).
    """
    frames = problem.seam.frames(problem.spacing if spacing is None else spacing)
    task = task_from_schedule(frames, schedule_for(problem, frames), max_start,
                              problem.seam_reference, problem.process.axial_control)
    if problem.coupling is None or task.axial_control != "position":
        return task
    from rfsw_plan.process.deviation import problem_penetration_law

    return replace(task, penetration_stiffness=problem_penetration_law(problem).stiffness)


def task_from_schedule(
    frames: SeamFrames, schedule: LoadSchedule, max_start: int = MAX_START_WAYPOINTS,
    reference: SeamReference = "taught", axial_control: str = "position",
) -> PlanTask:
    """The task of a seam and its load schedule.

    Weld waypoints take the schedule's weld-phase force interpolated at their arc length; where
    that force still ramps up (travel start) extra waypoints are inserted.
    Up to ``max_start`` stationary waypoints sample plunge and dwell (where the force changes
    most, always including the plunge's end at full depth, one more if the even spread missed
    it) so the offsets can follow the force ramp; the weld's first waypoint is the dwell's end
    (at its force).

    Args:
        frames: Weld waypoints along the seam (k rows).
        schedule: The process over time (plunge and dwell at s = 0, then weld).
        max_start: Most stationary waypoints.
        reference: Seam reference (see :class:`PlanTask`).
        axial_control: ``position`` or ``force`` (see :class:`PlanTask`).
    """
    weld = schedule.mask("weld")
    if not np.any(weld):
        raise InputError("process", "schedule", "has no weld phase", "a weld phase")
    # The weld starts at the last stationary sample before its first sample (a sample on a
    # phase boundary belongs to the phase it completes): its force is the weld's at s = 0 (the
    # profile is continuous there), so the first weld waypoint carries the standstill force,
    # not the force after one schedule step of travel (which put -125 N of traverse force on
    # the tool standing at s = 0, zk500_table6_seam).
    first = int(np.flatnonzero(weld)[0])
    if first > 0 and schedule.phase[first - 1] in ("plunge", "dwell"):
        weld = weld.copy()
        weld[first - 1] = True
    sw = schedule.s[weld]
    order = np.argsort(sw, kind="stable")
    sw = sw[order]
    fw = schedule.force_seam[weld][order]
    mw = schedule.moment_base[weld][order]
    frames = _refine_ramp(frames, sw, fw)
    k = len(frames)
    f = np.stack([np.interp(frames.s, sw, fw[:, i]) for i in range(3)], axis=1)
    mom = np.stack([np.interp(frames.s, sw, mw[:, i]) for i in range(3)], axis=1)
    t_weld0 = float(schedule.t[weld][0]) if np.any(weld) else 0.0
    v = float((sw[-1] - sw[0]) / max(schedule.t[weld][-1] - t_weld0, 1e-12))
    if v <= 0:
        raise InputError("process", "weld", "travel speed is not positive", "> 0")
    stat = np.flatnonzero(np.isin(schedule.phase, ("plunge", "dwell")))
    # The stationary sample at the weld start is the first weld waypoint.
    stat = stat[schedule.t[stat] < t_weld0 - 1e-12] if len(stat) else stat
    if len(stat) and max_start > 0:
        idx = _pick_ramp_samples(schedule, stat, max_start)
        # The plunge's end (full depth) is always a waypoint: the timed plunge ends there and
        # the dwell starts, so the dwell lasts the process's dwell time (without it the timed
        # plunge ran on to the first dwell waypoint, 0.35 s into the dwell of
        # fanuc_butt_1700mm, and the dwell came out 4.65 s for 5 s).
        plunge = stat[schedule.phase[stat] == "plunge"]
        if len(plunge) and max_start > 1:
            idx = np.union1d(idx, plunge[-1:])
    else:
        idx = np.zeros(0, dtype=int)
    # The end stop: the weld's last sample, then the stop's (at the seam end).
    stop = np.flatnonzero(schedule.phase == "stop")
    t_weld_end = float(schedule.t[weld][-1])
    stop_time = np.concatenate([[0.0], schedule.t[stop] - t_weld_end]) if len(stop) \
        else np.zeros(0)
    stop_force = np.vstack([fw[-1:], schedule.force_seam[stop]]) if len(stop) \
        else np.zeros((0, 3))
    depth_full = float(np.max(schedule.depth)) if len(schedule) else 0.0
    m = len(idx)
    start = SeamFrames(np.zeros(m), *(np.repeat(getattr(frames, a)[:1], m, 0) for a in "ptln"))
    depth_s = schedule.depth[idx]
    target_s = start.p + (depth_full - depth_s)[:, None] * start.n
    all_frames = _stack(start, frames)
    return PlanTask(
        frames=all_frames,
        target=np.vstack([target_s, frames.p]),
        force_seam=np.vstack([schedule.force_seam[idx], f]),
        moment_base=np.vstack([schedule.moment_base[idx], mom]),
        phase=np.concatenate([schedule.phase[idx].astype(str), np.full(k, "weld")]),
        time=np.concatenate([schedule.t[idx], t_weld0 + (frames.s - frames.s[0]) / v]),
        depth=np.concatenate([depth_s, np.full(k, depth_full)]),
        n_start=m,
        travel_speed=v,
        reference=reference,
        axial_control=axial_control,
        stop_time=stop_time,
        stop_force_seam=stop_force,
    )


def _refine_ramp(frames: SeamFrames, sw: FloatArray, fw: FloatArray,
                 divisions: int = 8) -> SeamFrames:
    """Extra weld waypoints where the weld force still ramps (travel start): the waypoint
    spacing divided by ``divisions`` up to one spacing past the end of the ramp, so the joint
    spline resolves the offsets that follow the force."""
    if len(frames) < 2:
        return frames
    steady = fw[-1]
    dev = np.linalg.norm(fw - steady, axis=1) / max(float(np.linalg.norm(steady)), 1e-9)
    ramping = np.flatnonzero(dev > 0.005)
    if not len(ramping):
        return frames
    s_ramp = float(sw[ramping[-1]])
    h = float(np.min(np.diff(frames.s)))
    s_end = min(s_ramp + h, float(frames.s[-1]))
    extra = np.arange(frames.s[0], s_end, h / divisions)
    s_new = np.unique(np.concatenate([frames.s, extra]))
    s_new = s_new[np.concatenate([[True], np.diff(s_new) > 1e-3 * h / divisions])]
    return interpolate_frames(frames, s_new)


def _pick_ramp_samples(
    schedule: LoadSchedule, stat: NDArray[np.int_], max_start: int
) -> NDArray[np.int_]:
    """Indices of stationary samples spread evenly over the force change (+ first and last)."""
    f = schedule.force_seam[stat]
    step = np.linalg.norm(np.diff(f, axis=0), axis=1)
    dt = np.diff(schedule.t[stat])
    scale = np.max(np.linalg.norm(f, axis=1)) + 1e-9
    # Arc length in (force, time) space: evenly in force change, but never long gaps in time.
    span_t = max(float(schedule.t[stat][-1] - schedule.t[stat][0]), 1e-9)
    w = np.concatenate([[0.0], np.cumsum(step / scale + 0.25 * dt / span_t)])
    marks = np.linspace(0, w[-1], max_start + 1)[1:]
    idx = np.unique(np.searchsorted(w, marks, side="left").clip(0, len(stat) - 1))
    idx = np.unique(np.concatenate([[0], idx, [len(stat) - 1]]))
    return stat[idx]
