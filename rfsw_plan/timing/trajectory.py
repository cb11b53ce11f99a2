"""The timed trajectory of a plan: approach, plunge, dwell, weld at constant speed, retract.

* Weld: the planned joint values are a cubic spline q(s) in arc length. The weld speed v is a
  process parameter: the speed of the *pin* along the seam (heat input per millimetre). The
  plan puts the predicted (loaded) pin on the seam point s_k of every waypoint, along the track
  too (:mod:`rfsw_plan.planning.nlp`: the along-track fake-target offset takes up the lag of the
  pin behind the commanded TCP, several millimetres while the traverse force ramps up over the
  first millimetre of travel), at the force the process model gives with the pin there. So s
  is the pin's arc length and is timed directly, s(t) = v t, with jerk-limited Ruckig ramps
  from rest to v (``accelerate``) and from v to rest (``decelerate``). The commanded TCP is
  at s + o_along(s): it runs ahead of the pin while the lag winds up, at the speed ratio
  1 + d o_along / ds = 1 - d delta / ds >= 1 (delta the along-track deflection), and at v
  where the force is steady.
  TOPPRA gives the highest limit-feasible path speed; a weld speed above it is reported.

  Reading of issue 4 §8 ("the timed trajectory keeps the TCP speed at the weld speed within
  1 % during welding"): the predicted loaded pin, i.e. FK(q(t)) + dX(q(t), F(t)) of every
  sample by the numeric model (:func:`rfsw_plan.planning.verify.pin_track`), travels along
  the seam at v within 1 % at every ``weld`` sample, force ramp included; the commanded TCP
  speed is v within 1 % wherever the process force is steady on a straight seam (during the
  ramp it must be faster, or the pin would slow down). On a curved seam the commanded TCP runs
  on the offset curve seam + offsets, whose speed differs from v by the curvature times the
  lateral offset and by the pose-dependent change of the deflection (kr600_curved_seam: up to
  about 4 % on its 200 mm arc with an 8 mm lateral offset); there only the pin's speed is v.
* Approach: from the safe height (``clearance`` above the plate surface, along the plate
  normal) down the tool axis to ``spindle_clearance`` above the surface, at the approach
  speed: Ruckig on the distance along the tool axis, mapped to joints by IK on a grid (cubic
  spline in the distance). The first sample is at the safe height, at zero force and with
  the offsets of the plunge start (the first stationary waypoint, at zero force).
* Plunge: from ``spindle_clearance`` above the surface (where the spindle-start hook runs;
  the tool first stands there for the process's ``spindle_runup`` while the spindle runs up)
  to full depth, Ruckig on the depth, mapped through the planned stationary waypoints by a
  shape-preserving (monotone, Fritsch-Carlson PCHIP) interpolation in depth (the stretch in
  the air, before the first waypoint at the surface, by IK along the tool axis).
* End stop (``stop``): the tool stands at the seam end while the wrench relaxes to the start
  standstill's over the task's stop schedule (:attr:`PlanTask.stop_time`), the commanded TCP
  where the predicted pin stays where the weld left it (:func:`_stop_map`, a fixed point over
  IK and the deflection model); without an end stop the retract relaxes it.
* Retract: in the plate, up the tool axis at the process retract speed, the wrench falling
  with the depth still in the plate (the process model's retract force,
  :meth:`~rfsw_plan.process.forces.ProcessModel.profile`), from the end stop's (without one
  while it relaxes to the start standstill's, :func:`retract_wrench`), and the fake-target offsets
  following it, so the pin leaves along the tool axis; once the pin is
  at the surface, up to the safe height at the approach speed at zero force.
* Dwell: the planned stationary waypoints in time, in Cartesian space: the commanded TCP on
  the straight line between neighbouring waypoints and the tool turned by their slerp, at rest
  at every waypoint, the offsets and wrench with the same progress, so the offsets follow the
  force ramp and the pin stays between the waypoints' errors (:func:`_dwell_piece`).

  Shape preservation is what keeps the pin in place: between two stationary waypoints every
  offset and force component stays between the two waypoints' values (no overshoot). A
  clamped cubic spline through the same knots (what this module used first) overshoots
  between knots with very different spacing and swung the commanded TCP of fanuc_butt_1700mm
  by 15 mm in x and 25 mm in y during a 3.1 kN dwell (296 samples outside the window),
  while the planned dwell waypoints moved q1 by 0.005 deg.

Every sample is then checked against the joint velocity, acceleration and jerk limits
(derivatives by finite differences on the sampled joint path).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicHermiteSpline, CubicSpline, PchipInterpolator

from rfsw_plan.exceptions import InfeasibleError
from rfsw_plan.process.forces import ProcessModel
from rfsw_plan.process.plan_options import PlanOptions
from rfsw_plan.process.task import PlanTask, offsets3
from rfsw_plan.robot.ik import solve_ik
from rfsw_plan.robot.kinematics import Robot
from rfsw_plan.timing.ruckig_ import profile_1dof
from rfsw_plan.timing.toppra_ import max_path_speed

FloatArray = NDArray[np.float64]
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TimingLimits:
    """Limits of the Cartesian Ruckig pieces (joint limits come from the robot).

    Attributes:
        acceleration: Along the tool axis or the seam [m/s^2].
        jerk: Along the tool axis or the seam [m/s^3].
        clearance: Safe height of the pin tip above the plate surface, along the plate
            normal, where the approach starts and the retract ends [m].
        approach_speed: Approach speed, and retract speed once the pin is out [m/s].
        plunge_speed: Plunge speed [m/s].
        dt: Sample time [s].
        spindle_clearance: Height of the pin tip above the surface where the approach ends
            and the plunge (spindle started) begins [m].
        retract_speed: Retract speed while the pin is in the plate [m/s].
        spindle_runup: Time the tool stands at the spindle clearance after the spindle starts,
            before it moves down, while the spindle runs up [s] (the process's
            ``spindle_runup``; 0: none).
        spindle_rpm: Spindle speed of the weld [rpm] (the process's ``rotation_speed_rpm``).
        travel_start: Least length of the weld-start acceleration [m] (0: the acceleration
            limit alone): :data:`TRAVEL_START_LENGTHS` of the process's force build-up length
            (:func:`timing_limits`), so the pin does not reach the weld speed while the
            traverse force still builds at its steepest.
    """

    acceleration: float = 0.1
    jerk: float = 1.0
    clearance: float = 50e-3
    approach_speed: float = 20e-3
    plunge_speed: float = 2e-3
    dt: float = 0.01
    spindle_clearance: float = 2e-3
    retract_speed: float = 2e-3
    spindle_runup: float = 0.0
    spindle_rpm: float = 0.0
    travel_start: float = 0.0


#: The weld-start acceleration spans at least this many of the process's force build-up
#: lengths L (``[process.forces] ramp_length_mm``). The traverse force builds over the first
#: millimetres of travel, f_t = F_r (1 - exp(-s/L)); the pin's along-track deflection then
#: changes at (d delta / d F) F_r exp(-s/L) / L x ds/dt, so an uncertain force moves the pin's
#: speed most where the force is steepest, s ~ 0..L. Reaching the weld speed within 0.16 mm
#: (0.1 m/s^2) put the full speed on that stretch, and the pin speed limited every bundled
#: claim there (zk500 +-4.35 %). Accelerating over 2 L at constant acceleration, v = v_w
#: sqrt(s / 2L), the product v exp(-s/L) peaks at 0.30 v_w (s = L/2) instead of 0.86 v_w:
#: the weld starts gently while the force builds, as a welding engineer runs the traverse in.
TRAVEL_START_LENGTHS = 2.0


def weld_acceleration(v: float, lim: TimingLimits) -> float:
    """The acceleration from rest to the weld speed v [m/s]: the limit's, or less, so the
    acceleration spans at least ``lim.travel_start`` [m] (v^2 / (2 a); the jerk limit only
    lengthens it) [m/s^2]."""
    if lim.travel_start > 0:
        return min(lim.acceleration, v * v / (2 * lim.travel_start))
    return lim.acceleration


def timing_limits(options: PlanOptions, process: ProcessModel, dt: float | None = None
                  ) -> TimingLimits:
    """The timing limits of a problem: the planner options' safe height (the process's
    ``approach_height`` when > 0), spindle clearance and approach speed, the process's plunge
    and retract speeds, spindle run-up and speed, and the sample time (``dt`` or the
    options')."""
    return TimingLimits(
        clearance=process.approach_height if process.approach_height > 0
        else options.clearance,
        approach_speed=options.approach_speed, plunge_speed=process.plunge_speed,
        dt=options.sample_dt if dt is None else dt,
        spindle_clearance=options.spindle_clearance, retract_speed=process.retract_speed,
        spindle_runup=process.spindle_runup, spindle_rpm=process.rotation_speed_rpm,
        travel_start=TRAVEL_START_LENGTHS * process.forces.ramp_length)


@dataclass(frozen=True)
class TimedTrajectory:
    """Sampled joint trajectory with everything the waypoint files need (SI, base frame).

    Attributes:
        t: Time [s], (N,), increasing.
        phase: ``approach``, ``plunge``, ``dwell``, ``accelerate``, ``weld``, ``decelerate``,
            ``retract``, (N,).
        s: Arc length of the seam point the pin is at [m], (N,) (0 before the weld, the seam
            length after it).
        q: Joint values [rad], (N, n).
        qd, qdd, qddd: Joint velocity, acceleration, jerk [rad/s, rad/s^2, rad/s^3], (N, n).
        offsets: Planned offsets (lateral, normal, along-track) [m], (N, 3).
        wrench: Wrench on the tool used by the plan [N, N m], (N, 6).
        weld_speed: Travel speed during ``weld`` [m/s].
        max_weld_speed: Highest limit-feasible constant path speed from TOPPRA [m/s].
        s_pin: Predicted (loaded) pin arc length along the seam [m], (N,): ``s`` as timed;
            the planner replaces it by the numeric model's evaluation of every sample
            (:func:`rfsw_plan.planning.verify.pin_track`).
        spindle_rpm: Commanded spindle speed [rpm], (N,): 0 before the plunge piece starts
            (where the spindle-start hook runs), rising linearly to the weld speed over the
            run-up while the tool stands at the spindle clearance, the weld speed until the
            pin tip is the spindle clearance above the surface again in the retract, then 0
            (the spindle is switched off; its run-down is not modelled).
        spindle_on: The spindle switched on, (N,) bool: from the plunge piece's start to the
            retract's first sample with the pin tip the spindle clearance above the surface
            (where the programs' spindle-stop hook runs; also for a process without a stated
            speed, ``rotation_speed_rpm`` 0).
    """

    t: FloatArray
    phase: NDArray[np.str_]
    s: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    qddd: FloatArray
    offsets: FloatArray
    wrench: FloatArray
    weld_speed: float
    max_weld_speed: float
    s_pin: FloatArray
    spindle_rpm: FloatArray
    spindle_on: NDArray[np.bool_]

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def tcp_speed(self, robot: Robot) -> FloatArray:
        """Commanded TCP speed |d FK_p / dt| [m/s], (N,)."""
        T = robot.batch_fk_jacobian(self.q)[0]
        return np.linalg.norm(np.gradient(T[:, :3, 3], self.t, axis=0), axis=1)

    def pin_speed(self) -> FloatArray:
        """Predicted pin speed along the seam d s_pin / dt [m/s], (N,): what the weld speed
        means to the process (heat input per mm)."""
        return np.asarray(np.gradient(self.s_pin, self.t))

    def limit_ratios(self, robot: Robot) -> dict[str, float]:
        """max |derivative| / limit over all samples and joints, per derivative order."""
        d = robot.description
        return {"velocity": float(np.max(np.abs(self.qd) / d.velocity)),
                "acceleration": float(np.max(np.abs(self.qdd) / d.acceleration)),
                "jerk": float(np.max(np.abs(self.qddd) / d.jerk))}


def _ik_line(robot: Robot, q_start: FloatArray, direction: FloatArray, dist: FloatArray,
             drift: FloatArray | None = None, length: float = 1.0) -> FloatArray:
    """Joint values moving the TCP from FK(q_start) by dist_i * direction (orientation kept),
    plus ``drift`` * dist_i / length [m] (3,) if given, by IK continuation, (len(dist), n)."""
    T0 = robot.fk(q_start)
    out = np.zeros((len(dist), robot.nq))
    q = q_start.copy()
    for i, x in enumerate(dist):
        T = T0.copy()
        T[:3, 3] = T0[:3, 3] + x * direction
        if drift is not None:
            T[:3, 3] += drift * (x / length)
        res = solve_ik(robot, T, q, tol_pos=1e-8, tol_rot=1e-8)
        if not res.converged:
            raise InfeasibleError(f"approach/retract: IK fails {x * 1e3:.1f} mm along the tool "
                                  "axis", constraint="reach")
        q = res.q
        out[i] = q
    return out


def _grid_map(robot: Robot, q_end: FloatArray, n_axis: FloatArray, length: float
              ) -> CubicSpline:
    """q(x) for x in [0, length], x the distance from FK(q_end) along n_axis."""
    xs = np.linspace(0.0, length, 11)
    Q = _ik_line(robot, q_end, n_axis, xs)
    return CubicSpline(xs, Q, axis=0)


#: A deflection model for the retract: (q (N, n) [rad], wrench (N, 6) [N, N m]) -> the TCP
#: deflection (N, 3) [m] (the planner passes its elastostatic model's process deflection).
Deflection = Callable[[FloatArray, FloatArray], FloatArray]


def retract_wrench(x: FloatArray, length: float, wrench_end: FloatArray,
                   wrench_stand: FloatArray) -> FloatArray:
    """The wrench of the retract in the plate at the pin's rise x [m] (N,) of ``length`` [m],
    (N, 6) [N, N m]:

        W(x) = rho (rho W_end + (1 - rho) W_stand),   rho = 1 - x / length,

    falling with the depth still in the plate (the process model's retract,
    :meth:`~rfsw_plan.process.forces.ProcessModel.profile`) while it relaxes from the weld's
    wrench W_end to the start standstill's W_stand (the dwell's end: no traverse force, the
    dwell's share of the lateral force). ASSUMED: the seeds measure no end stop; travel has
    stopped, so the forces relax to what they are when the tool stands at the start, and do
    so as the tool leaves (no step: W(0) = W_end)."""
    rho = np.clip(1.0 - np.asarray(x, dtype=float) / length, 0.0, 1.0)[:, None]
    return np.asarray(rho * (rho * wrench_end[None] + (1.0 - rho) * wrench_stand[None]))


def _pin_fixed_point(robot: Robot, q_end: FloatArray, Q: FloatArray, goal: FloatArray,
                     W: FloatArray, deflection: Deflection, rounds: int, tol: float,
                     failure: Callable[[int], str]) -> FloatArray:
    """The commanded TCP positions (m, 3) [m] at which the *predicted* pin is at ``goal``
    (m, 3) under the wrenches ``W`` (m, 6): ``rounds`` of cmd = goal - dX(Q, W), then Q from
    IK of cmd (orientation of ``q_end``'s pose kept, each point from the previous one), with
    the first point held at ``q_end``'s TCP. ``Q`` (m, n) [rad] is the start and is updated in
    place. Raises :class:`InfeasibleError` (``failure(i)``) where the IK fails at point i."""
    x0 = robot.fk(q_end)[:3, 3]
    T0 = robot.fk(q_end)
    cmd = goal
    for _ in range(rounds):
        cmd = goal - deflection(Q, W)
        cmd[0] = x0
        q = q_end.copy()
        for i in range(1, len(goal)):
            T = T0.copy()
            T[:3, 3] = cmd[i]
            res = solve_ik(robot, T, q, tol_pos=tol, tol_rot=tol)
            if not res.converged:
                raise InfeasibleError(failure(i), constraint="reach")
            q = res.q
            Q[i] = q
    return cmd


def _stop_map(robot: Robot, q_end: FloatArray, task: PlanTask, wrench_end: FloatArray,
              wrench_stand: FloatArray, deflection: Deflection | None, points: int = 11,
              rounds: int = 4) -> tuple[CubicSpline, CubicSpline]:
    """Joint values q(lam) and offsets o(lam) (lateral, normal, along-track) [m] of the end
    stop, lam in [0, 1] the progress of the wrench from the weld's last ``wrench_end`` to the
    standstill's ``wrench_stand`` (W = W_end + lam (W_stand - W_end)): the commanded TCP is
    where the *predicted* pin stays at the weld's last predicted pin while the wrench relaxes
    (a fixed point over IK and ``deflection``, as the retract's, :func:`_retract_map`), the
    orientation kept; without ``deflection`` the robot holds its last pose."""
    fr = task.frames
    lam = np.linspace(0.0, 1.0, points)
    x0 = robot.fk(q_end)[:3, 3]
    Q = np.repeat(q_end[None], points, 0)
    cmd = np.repeat(x0[None], points, 0)
    if deflection is not None:
        W = wrench_end[None] + lam[:, None] * (wrench_stand - wrench_end)[None]
        goal = x0 + deflection(q_end[None], wrench_end[None])[0]
        cmd = _pin_fixed_point(
            robot, q_end, Q, np.repeat(goal[None], points, 0), W, deflection, rounds, 1e-9,
            lambda i: f"end stop: IK fails {lam[i] * 100:.0f} % of the way through the force "
                      "relaxation")
    rel = cmd - fr.p[-1][None]
    O = np.stack([rel @ fr.l[-1], rel @ fr.n[-1], rel @ fr.t[-1]], axis=1)
    return CubicSpline(lam, Q, axis=0), CubicSpline(lam, O, axis=0)


def _relaxed_wrench(task: PlanTask, wrench_last: FloatArray, wrench_end: FloatArray
                    ) -> FloatArray:
    """What the forces relax to over the retract (base frame, (6,)) [N, N m]: with an end stop
    they already have (its last wrench, ``wrench_end``); without one, the start standstill's
    wrench (the weld's first waypoint: the dwell's end) at the seam's end frame, the moments of
    the weld's last sample ``wrench_last`` kept (no start phases: that wrench itself)."""
    if task.end_stop > 0:
        return wrench_end
    m = task.n_start
    if not m:
        return wrench_last
    return np.concatenate([task.frames.rotation()[-1] @ task.force_seam[m], wrench_last[3:]])


def _stop_piece(robot: Robot, task: PlanTask, q_end: FloatArray, wrench_end: FloatArray,
                s_end: float, dt: float, deflection: Deflection | None
                ) -> tuple[tuple[str, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray],
                           FloatArray]:
    """The end stop as a timeline piece (phase, t [s], s [m], q [rad], offsets [m], wrench
    (base frame) [N, N m]) and the joints it ends at (the relaxation's end, lam = 1) [rad]:
    ``task.end_stop`` seconds at the seam's end ``s_end`` while the seam-frame force relaxes
    over the task's stop schedule (:func:`stop_progress`), the moments held, the joints and
    offsets on :func:`_stop_map`'s fixed point."""
    R_end = task.frames.rotation()[-1]
    t = np.linspace(0.0, task.end_stop, max(int(np.ceil(task.end_stop / dt)), 1) + 1)
    f_stop, lam = stop_progress(task, t)
    W_stop = np.hstack([f_stop @ R_end.T, np.repeat(wrench_end[None, 3:], len(t), 0)])
    W_stand = np.concatenate([R_end @ task.stop_force_seam[-1], wrench_end[3:]])
    smap, somap = _stop_map(robot, q_end, task, wrench_end, W_stand, deflection)
    return ("stop", t, np.full_like(t, s_end), smap(lam), somap(lam), W_stop), \
        smap(np.array([1.0]))[0]


def stop_progress(task: PlanTask, t: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The end stop's seam-frame force (f_t, f_l, f_n) [N] (N, 3) at times t [s] (N,) from the
    weld's end (shape-preserving between the task's stop samples, :func:`monotone_interp`:
    continuous in slope, so the offsets that follow it have no speed steps), and its progress
    lam (N,) from the weld's last force (0) to the stop's last (1), the projection on the
    straight line between them (every component relaxes with the same profile)."""
    F = monotone_interp(task.stop_time, task.stop_force_seam, np.asarray(t, dtype=float))
    d = task.stop_force_seam[-1] - task.stop_force_seam[0]
    dd = float(d @ d)
    lam = ((F - task.stop_force_seam[0]) @ d) / dd if dd > 0 else np.ones(len(t))
    return F, np.clip(lam, 0.0, 1.0)


def _retract_map(robot: Robot, q_end: FloatArray, task: PlanTask, o_vec: FloatArray,
                 length: float, wrench_end: FloatArray, deflection: Deflection | None,
                 rounds: int = 4, wrench_stand: FloatArray | None = None,
                 ) -> tuple[CubicSpline, CubicSpline]:
    """Joint values q(x) and offsets o(x) (lateral, normal, along-track) [m] of the retract in
    the plate, x in [0, length] the pin's rise along the tool axis n: the wrench falls as
    :func:`retract_wrench` (F_end (1 - x / length) without ``wrench_stand``) and the
    commanded TCP is where the *predicted* pin is the weld's
    last predicted pin moved by x n (``deflection`` given: a fixed point over IK and the
    deflection model), else the last commanded TCP moved by x n minus the offsets' share
    o (x / length) (linear in the force)."""
    fr = task.frames
    n_end, l_end, t_end = fr.n[-1], fr.l[-1], fr.t[-1]
    xs = np.linspace(0.0, length, 11)
    x0 = robot.fk(q_end)[:3, 3]
    cmd = x0 + xs[:, None] * n_end[None] - (xs / length)[:, None] * o_vec[None]
    Q = _ik_line(robot, q_end, n_end, xs, -o_vec, length)
    if deflection is not None:
        W = retract_wrench(xs, length, wrench_end,
                           wrench_end if wrench_stand is None else wrench_stand)
        pin_end = x0 + deflection(q_end[None], wrench_end[None])[0]
        goal = pin_end + xs[:, None] * n_end[None]
        cmd = _pin_fixed_point(
            robot, q_end, Q, goal, W, deflection, rounds, 1e-8,
            lambda i: f"retract: IK fails {xs[i] * 1e3:.1f} mm along the tool axis")
    target = fr.p[-1] + xs[:, None] * n_end[None]
    rel = cmd - target
    O = np.stack([rel @ l_end, rel @ n_end, rel @ t_end], axis=1)
    return CubicSpline(xs, Q, axis=0), CubicSpline(xs, O, axis=0)


def monotone_interp(xk: FloatArray, yk: FloatArray, x: FloatArray, rest_ends: bool = False
                    ) -> FloatArray:
    """Shape-preserving piecewise cubic (Fritsch-Carlson PCHIP) through (xk, yk), per column.

    Every value between two knots lies between the two knots' values: no overshoot, monotone
    where the data are monotone, flat where neighbouring knots are equal. With ``rest_ends``
    the slope at both ends is zero (the piece starts and ends at rest); a zero end slope keeps
    the Fritsch-Carlson monotonicity condition, so it cannot overshoot either.

    Args:
        xk: Knots, increasing, (k,).
        yk: Values at the knots, (k,) or (k, m).
        x: Where to evaluate, inside [xk[0], xk[-1]], (N,).
        rest_ends: Zero slope at the first and last knot.

    Returns:
        Values, (N,) or (N, m).
    """
    xk = np.asarray(xk, dtype=float)
    yk = np.asarray(yk, dtype=float)
    if len(xk) < 2:
        return np.repeat(yk[:1], len(x), axis=0)
    dydx = PchipInterpolator(xk, yk, axis=0).derivative()(xk)
    if rest_ends:
        dydx[0] = 0.0
        dydx[-1] = 0.0
    y = CubicHermiteSpline(xk, yk, dydx, axis=0)(np.clip(x, xk[0], xk[-1]))
    # Round-off of the Hermite basis can leave a value 1e-16 outside its knots' range.
    i = np.clip(np.searchsorted(xk, x, side="right") - 1, 0, len(xk) - 2)
    lo = np.minimum(yk[i], yk[i + 1])
    hi = np.maximum(yk[i], yk[i + 1])
    return np.asarray(np.clip(y, lo, hi))


#: Points per dwell segment at which the joint path is solved by IK (a cubic spline in the
#: segment's progress between them; its deviation from the exact IK is below 1e-9 rad).
DWELL_IK_POINTS = 41


def smoothstep(u: FloatArray) -> FloatArray:
    """Progress 10 u^3 - 15 u^4 + 6 u^5 of a segment at its normalised time u in [0, 1]: at rest
    and without acceleration at both ends (never outside [0, 1]), so the jerk is finite at
    every waypoint and the limits checked on one sample grid hold on any finer one (the cubic
    3 u^2 - 2 u^3 steps the acceleration at every waypoint: its jerk grew as the grid was
    refined, and the 4 ms stream needed 1.13 s more dwell than the 10 ms plan on
    zk500_table6_seam)."""
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    return np.asarray(u * u * u * (10.0 + u * (6.0 * u - 15.0)))


#: Sample step on which the dwell's joint velocity, acceleration and jerk are checked [s]
#: (at most; the plan's own step when finer), the same for every output sample time, so
#: the plan and a stream at the controller cycle dwell equally long.
DWELL_CHECK_DT = 1e-3


def _dwell_joint_path(robot: Robot, qk: FloatArray) -> list[CubicSpline]:
    """Per dwell segment, the joint values q(lambda) that keep the commanded TCP on the straight
    line between the segment's two waypoint TCP positions and turn the tool by the shortest
    rotation (slerp) between their orientations, lambda in [0, 1] the segment's progress.

    Solved by IK continuation at :data:`DWELL_IK_POINTS` values of lambda from the joint-space
    interpolation as seed, then a cubic spline in lambda.

    Raises:
        InfeasibleError: A point of the Cartesian segment is unreachable.
    """
    from scipy.spatial.transform import Rotation

    T = robot.batch_fk_jacobian(qk)[0]
    lam = np.linspace(0.0, 1.0, DWELL_IK_POINTS)
    out: list[CubicSpline] = []
    for k in range(len(qk) - 1):
        R0, R1 = T[k, :3, :3], T[k + 1, :3, :3]
        rv = Rotation.from_matrix(R0.T @ R1).as_rotvec()
        Q = np.empty((len(lam), robot.nq))
        Q[0], Q[-1] = qk[k], qk[k + 1]
        q = qk[k].copy()
        for i in range(1, len(lam) - 1):
            pose = np.eye(4)
            pose[:3, :3] = R0 @ Rotation.from_rotvec(lam[i] * rv).as_matrix()
            pose[:3, 3] = T[k, :3, 3] + lam[i] * (T[k + 1, :3, 3] - T[k, :3, 3])
            seed = q + (qk[k + 1] - qk[k]) * (lam[i] - lam[i - 1])
            res = solve_ik(robot, pose, seed, tol_pos=1e-9, tol_rot=1e-9)
            if not res.converged:
                raise InfeasibleError(
                    f"dwell: the commanded pose between stationary waypoints {k + 1} and "
                    f"{k + 2} is unreachable {lam[i] * 100:.0f} % of the way (misses it by "
                    f"{res.position_error * 1e3:.3f} mm)", constraint="reach")
            q = res.q
            Q[i] = q
        out.append(CubicSpline(lam, Q, axis=0))
    return out


def _dwell_piece(robot: Robot, tk: FloatArray, qk: FloatArray, ok: FloatArray, Fk: FloatArray,
                 dt: float, max_rounds: int = 30,
                 ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Samples of the dwell, each segment between two stationary waypoints lengthened where the
    schedule's time is too short for the joint velocity, acceleration and jerk limits.

    The pin is in the material and not travelling, so the dwell is interpolated in Cartesian
    space: within segment k the progress lambda = :func:`smoothstep` of the segment's normalised
    time (at rest at every waypoint) moves the commanded TCP on the straight line between the
    two waypoints' commanded TCP positions and turns the tool by the slerp of their
    orientations (:func:`_dwell_joint_path`); the offsets and the wrench follow the same
    lambda linearly (each joint held within the range of the waypoints' values). The commanded
    TCP then never leaves the box of the waypoints, and the
    predicted pin error, to first order a convex combination of the two waypoints' errors,
    stays between them. (Interpolating the joints instead moves the TCP on an arc whenever the
    tool turns about an axis off the spindle: kr600_curved_seam placed elsewhere by
    ``rfsw-plan place``, the head turning by 5 deg during the dwell, swung the pin 1.2 mm
    off the seam between two waypoints that were 0.6 and 0.3 mm off.)

    The schedule's last dwell segment ends at the first weld waypoint, whose traverse and
    lateral forces appear when travel starts; the schedule gives it one sample time (0.05 s),
    in which the fake target would have to jump by millimetres. That segment (and any other
    too short one) is stretched by the limit ratio until every sample is within the limits;
    the wrench follows the same stretched time, so the offsets stay in step with the force.

    Args:
        robot: The robot (limits).
        tk: Waypoint times from the dwell start [s], (k,), increasing.
        qk, ok, Fk: Joint values [rad], offsets [m], wrench [N, N m] at the waypoints.
        dt: Sample time [s].

    Returns:
        (t, q, offsets, wrench) sampled every dt (about) from 0.
    """
    d = robot.description
    seg = np.diff(tk)
    paths = _dwell_joint_path(robot, qk)
    def sampled(step: float) -> tuple[FloatArray, NDArray[np.int_], FloatArray, FloatArray]:
        knots = np.concatenate([[0.0], np.cumsum(seg)])
        T = float(knots[-1])
        t = np.linspace(0.0, T, max(int(np.ceil(T / step)), 1) + 1)
        which = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(seg) - 1)
        lam = smoothstep((t - knots[which]) / seg[which])
        qq = np.empty((len(t), robot.nq))
        for k, path in enumerate(paths):
            rows = which == k
            qq[rows] = path(lam[rows])
        # The straight line can need a joint a few nrad beyond the range of the waypoints
        # (fanuc_butt_1700mm placed at yaw -90 deg: 6.7e-9 rad); the planner's sample check
        # keeps every dwell joint within that range to 1e-9 rad, so the joints are held in it
        # (moving the TCP by nanometres; the check's TCP box catches any larger departure).
        return t, which, lam, np.clip(qq, np.min(qk, axis=0), np.max(qk, axis=0))

    for _ in range(max_rounds):
        t, which, lam, qq = sampled(min(dt, DWELL_CHECK_DT))
        qd = np.gradient(qq, t, axis=0)
        qdd = np.gradient(qd, t, axis=0)
        qddd = np.gradient(qdd, t, axis=0)
        grow = np.ones(len(seg))
        for order, val, limit in ((1, qd, d.velocity), (2, qdd, d.acceleration),
                                  (3, qddd, d.jerk)):
            ratio = np.max(np.abs(val) / limit, axis=1) / 0.9  # 10 % headroom
            for k in range(len(seg)):
                r = ratio[(which == k) | (which == k - 1) | (which == k + 1)]
                if len(r) and r.max() > 1.0:
                    grow[k] = max(grow[k], float(r.max()) ** (1.0 / order))
        if np.all(grow <= 1.0):
            break
        seg = seg * np.maximum(grow, 1.0)
    t, which, lam, qq = sampled(dt)
    T = float(t[-1])
    if tk[-1] + 1e-9 < T:
        log.info("dwell lengthened from %.2f s to %.2f s for the joint limits", tk[-1], T)

    def follow(values: FloatArray) -> FloatArray:
        v0, v1 = values[which], values[which + 1]
        return np.asarray(v0 + lam[:, None] * (v1 - v0))

    return t, qq, follow(np.asarray(ok, float)), follow(np.asarray(Fk, float))


Piece = tuple[str, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]
"""(phase, t relative to the piece start [s], s [m], q [rad], offsets [m], wrench)."""


def _stationary_pieces(robot: Robot, task: PlanTask, q: FloatArray, offsets: FloatArray,
                       lim: TimingLimits, q_air: FloatArray, start_depth: float) -> list[Piece]:
    """The spindle run-up, the plunge and the dwell (the task's stationary waypoints), from
    ``q_air`` at the spindle clearance (depth ``start_depth`` [m], negative: in the air)."""
    m = task.n_start
    dt = lim.dt
    F = task.wrench_base
    zero6 = np.zeros(6)
    depth_full = float(np.max(task.depth)) if len(task.depth) else 0.0
    pieces: list[Piece] = []
    if m and lim.spindle_runup > 0:
        # The spindle runs up while the tool stands at the spindle clearance (the plunge
        # piece starts here, with the spindle-start hook).
        t = np.linspace(0.0, lim.spindle_runup, max(int(np.ceil(lim.spindle_runup / dt)), 1) + 1)
        pieces.append(("plunge", t, np.zeros_like(t), np.repeat(q_air[None], len(t), 0),
                       np.repeat(offsets[:1], len(t), 0), np.tile(zero6, (len(t), 1))))
    if m:
        plunge = np.flatnonzero(task.phase[:m] == "plunge")
        dwell = np.flatnonzero(task.phase[:m] == "dwell")
        # Plunge: Ruckig on the depth, through the planned plunge waypoints (the piece ends
        # at the last waypoint at full depth; the dwell starts there).
        idx = plunge
        if not len(idx) or task.depth[idx[-1]] < depth_full - 1e-9:
            idx = np.append(idx, dwell[0] if len(dwell) else m)
            dwell = dwell[1:]
        dep = task.depth[idx]
        keep = np.append(np.diff(dep) > 1e-9, True)  # of equal depths keep the last
        idx, dep = idx[keep], dep[keep]
        end = int(idx[-1])
        if len(idx) >= 1:
            # Shape-preserving in depth: every plunge sample between its neighbouring
            # waypoints (Ruckig starts and ends the depth at rest), from the spindle clearance
            # (depth -air, in the air, at zero force).
            t, x, _, _ = profile_1dof(start_depth, dep[-1], 0.0, 0.0, lim.plunge_speed,
                                      lim.acceleration, lim.jerk, dt)
            pieces.append(("plunge", t, np.zeros_like(t),
                           monotone_interp(np.append(start_depth, dep),
                                           np.vstack([q_air, q[idx]]), x),
                           monotone_interp(np.append(start_depth, dep),
                                           np.vstack([offsets[idx[:1]], offsets[idx]]), x),
                           monotone_interp(np.append(start_depth, dep),
                                           np.vstack([zero6, F[idx]]), x)))
        # Dwell: the planned stationary waypoints in time, up to the first weld waypoint.
        idx = np.concatenate([[end], dwell[dwell > end], [m]]).astype(int)
        idx = idx[np.concatenate([[True], np.diff(idx) > 0])]
        tt = task.time[idx] - task.time[idx[0]]
        keep = np.append(np.diff(tt) > 1e-9, True)
        idx, tt = idx[keep], tt[keep]
        if len(idx) >= 2:
            t, qq, oo, ff = _dwell_piece(robot, tt, q[idx], offsets[idx], F[idx], dt)
            pieces.append(("dwell", t, np.zeros_like(t), qq, oo, ff))
    return pieces


def time_parameterise(
    robot: Robot, task: PlanTask, q: FloatArray, offsets: FloatArray,
    limits: TimingLimits | None = None, deflection: Deflection | None = None,
) -> TimedTrajectory:
    """Time a planned path and check every limit at every sample.

    Args:
        robot: The robot (joint velocity, acceleration, jerk limits).
        task: The planned task (stationary waypoints first, then weld waypoints).
        q: Planned joint values [rad], (K, n).
        offsets: Planned offsets (lateral, normal[, along-track]) [m], (K, 3) or (K, 2).
        limits: Cartesian limits of the Ruckig pieces and the sample time.
        deflection: The TCP deflection model (see :data:`Deflection`) that keeps the pin
            leaving the plate along the tool axis at the retract speed; None: the offsets
            fall linearly with the force.

    Raises:
        InfeasibleError: The weld speed exceeds what the joint limits allow (names the arc
            length and the TOPPRA speed), or a sample violates a joint limit.
    """
    lim = limits or TimingLimits()
    dt = lim.dt
    d = robot.description
    v = task.travel_speed
    m = task.n_start
    sw = task.s[m:]
    qw = q[m:]
    offsets = offsets3(offsets)
    ow = offsets[m:]
    F = task.wrench_base
    if len(sw) < 2:
        raise InfeasibleError("the weld needs at least two waypoints", constraint="waypoints")
    spline = CubicSpline(sw, qw, axis=0)
    o_spline = CubicSpline(sw, ow, axis=0)
    f_spline = CubicSpline(sw, F[m:], axis=0)

    # TOPPRA: the highest speed the joint limits allow along the weld path.
    psl = max_path_speed(sw, qw, d.velocity, d.acceleration)
    if v > psl.max_speed:
        raise InfeasibleError(
            f"weld speed {v * 1e3:.3g} mm/s is not feasible: the joint velocity and acceleration "
            f"limits allow at most {psl.max_speed * 1e3:.3g} mm/s at s = {psl.s_at * 1e3:.1f} mm "
            "(TOPPRA)", waypoint=int(m + np.argmin(np.abs(sw - psl.s_at))),
            constraint="weld_speed", margin=psl.max_speed - v)

    pieces: list[Piece] = []
    zero6 = np.zeros(6)
    n0 = task.frames.n[0]
    q_first = q[0]
    depth_full = float(np.max(task.depth)) if len(task.depth) else 0.0
    d0 = float(task.depth[0]) if m else depth_full
    # Distances along the tool axis that rise by a height along the plate normal.
    nplate = task.plate_normal

    def height(qq: FloatArray, k: int) -> float:
        """Height of the TCP at joint values qq above the plate (seam point k + plunge depth
        along the plate normal) [m]: the pin's at zero force."""
        surface = task.frames.p[k] + depth_full * nplate[k]
        return float(np.dot(nplate[k], robot.fk(qq)[:3, 3] - surface))

    cos0 = float(np.dot(n0, nplate[0]))
    h_first = height(q_first, 0)
    up = (lim.clearance - h_first) / cos0
    # Without stationary waypoints (no plunge) the approach ends on the first weld waypoint.
    air = (min(lim.spindle_clearance, lim.clearance) - h_first) / cos0 if m else 0.0
    # Approach: from the safe height above the plunge start down the tool axis to the spindle
    # clearance, at the offsets of the plunge start (zero force).
    amap = _grid_map(robot, q_first, n0, up)
    t, x, _, _ = profile_1dof(up, air, 0.0, 0.0, lim.approach_speed, lim.acceleration,
                              lim.jerk, dt)
    pieces.append(("approach", t, np.zeros_like(t), amap(x), np.repeat(offsets[:1], len(t), 0),
                   np.tile(zero6, (len(t), 1))))
    # Depth 0 is the first stationary waypoint (or the first weld waypoint); above it the
    # plunge starts in the air at the spindle clearance.
    q_air = amap(np.array([air]))[0]
    pieces += _stationary_pieces(robot, task, q, offsets, lim, q_air, d0 - air)
    # Weld: ramp up, constant speed, ramp down (Ruckig velocity interface) on the pin's arc
    # length s.
    t_a, x_a, _, _ = profile_1dof(0.0, None, 0.0, v, 10 * v, weld_acceleration(v, lim),
                                  lim.jerk, dt)
    L = float(sw[-1] - sw[0])
    if 2 * x_a[-1] >= L:
        raise InfeasibleError("the seam is shorter than the acceleration to the weld speed",
                              constraint="weld_speed")
    s_a = sw[0] + x_a
    pieces.append(("accelerate", t_a, s_a, spline(s_a), o_spline(s_a), f_spline(s_a)))
    s_start, s_end = s_a[-1], sw[-1] - x_a[-1]
    T = (s_end - s_start) / v
    n_w = max(int(np.ceil(T / dt)), 1)
    t = np.linspace(0.0, T, n_w + 1)
    s = s_start + v * t
    pieces.append(("weld", t, s, spline(s), o_spline(s), f_spline(s)))
    s_d = s_end + (x_a[-1] - x_a[::-1])  # mirror of the ramp up
    pieces.append(("decelerate", t_a, s_d, spline(s_d), o_spline(s_d), f_spline(s_d)))
    # End stop: the tool stands at the seam end, the pin in the plate, while the forces relax
    # to the start standstill's (the task's stop schedule); the offsets follow the force so
    # that the predicted pin stays where the weld left it.
    q_end, W_end = q[-1], F[-1]
    fr = task.frames
    if task.end_stop > 0:
        stop, q_end = _stop_piece(robot, task, q[-1], F[-1], float(sw[-1]), dt, deflection)
        pieces.append(stop)
        W_end = stop[5][-1]
    # Retract: out of the plate up the tool axis at the retract speed, the wrench and the
    # offsets falling with the depth still in the plate (the offsets' commanded displacement
    # o_lat l + o_norm n + o_along t unwinds along the way); then up to the safe height.
    n_end = task.frames.n[-1]
    cos1 = float(np.dot(n_end, nplate[-1]))
    o_end = pieces[-1][4][-1]
    o_vec = o_end[0] * fr.l[-1] + o_end[1] * fr.n[-1] + o_end[2] * fr.t[-1]
    dplate = max(depth_full / cos1, 1e-6)
    if deflection is not None and depth_full > 0:
        # From where the weld's last predicted pin really is (it may end a few micrometres
        # off the planned depth, inside the depth window): out of the plate exactly when the
        # in-plate retract ends.
        pin_end = robot.fk(q_end)[:3, 3] + deflection(q_end[None], W_end[None])[0]
        below = -float(np.dot(nplate[-1], pin_end - (fr.p[-1] + depth_full * nplate[-1])))
        dplate = max(below / cos1, 1e-6)
    if depth_full > 0:
        F_stand = _relaxed_wrench(task, F[-1], W_end)
        rmap, omap = _retract_map(robot, q_end, task, o_vec, dplate, W_end, deflection,
                                  wrench_stand=F_stand)
        t, x, _, _ = profile_1dof(0.0, dplate, 0.0, 0.0, lim.retract_speed, lim.acceleration,
                                  lim.jerk, dt)
        pieces.append(("retract", t, np.full_like(t, sw[-1]), rmap(x), omap(x),
                       retract_wrench(x, dplate, W_end, F_stand)))
        q_out = rmap(np.array([dplate]))[0]
    else:
        q_out = q_end
    rdist = (lim.clearance - height(q_out, len(task) - 1)) / cos1
    cmap = _grid_map(robot, q_out, n_end, rdist)
    t, x, _, _ = profile_1dof(0.0, rdist, 0.0, 0.0, lim.approach_speed, lim.acceleration,
                              lim.jerk, dt)
    zero3 = np.zeros(3) if depth_full > 0 else o_end
    pieces.append(("retract", t, np.full_like(t, sw[-1]), cmap(x),
                   np.repeat(zero3[None], len(t), 0), np.tile(zero6, (len(t), 1))))
    # The spindle stops where the pin tip is the spindle clearance above the surface (as it
    # started; the programs' spindle-stop hook is placed there too): the first sample of the
    # rise out of the plate that reaches it (no wrench there, the pin is the TCP).
    rise = (min(lim.spindle_clearance, lim.clearance) - height(q_out, len(task) - 1)) / cos1
    clear = np.flatnonzero(x >= rise - 1e-12)
    t_clear = float(t[clear[0]] if clear.size else t[-1])

    # Concatenate; drop the first sample of each piece after the first (it repeats the end).
    ts, ph, ss, qs, os_, fs = [], [], [], [], [], []
    t0 = 0.0
    # The spindle starts with the first plunge piece and stops in the last piece, the rise
    # out of the plate, with the pin tip the spindle clearance above the surface.
    t_on = t_off = 0.0
    for i, (name, t, s, qq, oo, ff) in enumerate(pieces):
        if i == 1:
            t_on = t0
        if i == len(pieces) - 1:
            t_off = t0 + t_clear
        sl = slice(1, None) if i else slice(None)
        ts.append(t0 + t[sl])
        ph.append(np.full(len(t[sl]), name))
        ss.append(s[sl])
        qs.append(qq[sl])
        os_.append(oo[sl])
        fs.append(ff[sl])
        t0 += float(t[-1])
    t = np.concatenate(ts)
    Q = np.vstack(qs)
    qd = np.gradient(Q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    qddd = np.gradient(qdd, t, axis=0)
    s_all = np.concatenate(ss)
    runup = np.clip((t - t_on) / lim.spindle_runup, 0.0, 1.0) if lim.spindle_runup > 0 \
        else (t >= t_on).astype(float)
    on = (t >= t_on) & (t <= t_off + 1e-9)
    rpm = np.where(on, lim.spindle_rpm * runup, 0.0)
    traj = TimedTrajectory(t, np.concatenate(ph), s_all, Q, qd, qdd, qddd,
                           np.vstack(os_), np.vstack(fs), v, psl.max_speed, s_all.copy(),
                           rpm, on)
    _check_limits(robot, traj)
    return traj


def _check_limits(robot: Robot, traj: TimedTrajectory) -> None:
    d = robot.description
    for name, val, limit in (("velocity", traj.qd, d.velocity),
                             ("acceleration", traj.qdd, d.acceleration),
                             ("jerk", traj.qddd, d.jerk)):
        ratio = np.abs(val) / limit
        i, j = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        if ratio[i, j] > 1.0:
            raise InfeasibleError(
                f"joint {j + 1} {name} limit exceeded by {100 * (ratio[i, j] - 1):.1f} % at "
                f"t = {traj.t[i]:.2f} s ({traj.phase[i]}, s = {traj.s[i] * 1e3:.1f} mm)",
                constraint=f"joint_{name}_q{j + 1}", margin=float(1.0 - ratio[i, j]))
