"""Parametric FSW process forces over the phases approach, plunge, dwell, weld, stop, retract.

The force is the wrench the workpiece applies to the tool at the TCP, given in the seam frame
(t, l, n) of :mod:`rfsw_plan.process.frames` (seed 001 Fig. 3c: axial Fd, lateral Fl,
resistance/traverse Fr)::

    f_t = -Fr * g_t        (traverse, resists travel)
    f_l = sign_l * Fl * g_l (lateral; along l = toward the advancing side for sign_l = +1)
    f_n = +F_n(t)          (axial, pushes the tool back up the tool axis)
    m   = sigma * M_s * g_m * n   (spindle reaction torque about the tool axis, base frame)

Ramps (rho = depth / plunge depth, tau = time in the phase, s = distance welded; the
first-order ramps are continuous across phase boundaries):

* approach: no contact, all zero.
* plunge: F_n = F_pk * rho (penetration resistance grows with the contact); g_l = g_t = 0
  (a stationary rotating tool stirs symmetrically); g_m = rho.
* dwell: F_n = Fd + (F_pk - Fd) exp(-tau/T_d) (the material softens, seed 001 Fig. 10:
  the tool keeps sinking during dwell and stabilises after ~10 s); the lateral force builds
  with the stirring, g_l = c_l (1 - exp(-tau/T_d)); g_t = 0; g_m = 1.
* weld: every component relaxes to its steady value over a length constant L of travel,
  x(s) = x_ss + (x_0 - x_ss) exp(-s/L) with x_0 the value at the end of dwell; g_t = 1 -
  exp(-s/L); g_m = 1.
* stop (the end stop): travel has ended and the tool stands at the seam end, the pin in the
  plate; every component relaxes from its weld-end value x_w to the start standstill's,
  x_stand = (0, c_l Fl, Fd) (no traverse force without travel, the dwell's share of the
  lateral force, the steady axial force), over the stop's length T_e = ``end_stop``::

      x(tau) = x_w + (x_stand - x_w) S(tau / T_e),   S(u) = 10 u^3 - 15 u^4 + 6 u^5

  continuous with the weld at tau = 0 and at the standstill value at tau = T_e, from rest
  and to rest (S' = S'' = 0 at both ends: the offsets that follow the force start and end
  without a jump in speed, so the joint jerk stays finite on any sample grid; an
  exponential with the dwell's T_d starts at its steepest and broke the jerk limit at the
  stream's cycle). ASSUMED: the seeds measure no end stop; see :data:`END_STOP`.
* retract: all components scale with rho as the tool leaves the material (from the stop's
  end: the standstill's forces).

Lateral-force sign (default +1, configurable as ``lateral_sign``): friction on the pin's
leading edge, where the tool meets cold, hard material. For a clockwise spindle with travel
+x and the surface normal +z, the leading-edge surface velocity omega x r is -y (toward the
retreating side), so friction pushes the tool toward +y, the advancing side: f_l = +Fl. The
trailing edge pushes the other way but works on softened material, so the leading edge wins.
Because l follows the rotation sense and the travel direction, the base-frame lateral force
flips when the travel direction flips (seed 000 Fig. 18). On the ZK-500 Table 6 seam this sign
gives +4.9..5.0 mm (toward the advancing side) for the 4.9 mm measured in seed 001; the
opposite sign gives -5.0 mm: the magnitude does not decide the sign, only its direction.

Spindle torque: the workpiece resists the spindle's rotation, so the reaction torque on the
tool is opposite to omega. For 'cw' omega = -w n, so the torque is +M_s n; sigma = +1 ('cw')
or -1 ('ccw') is read from the handedness of the frames (det [t l n]). The seeds do not
measure it (seed 001's spindle is rated 55 N m, an upper bound), so bundled processes set 0.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rfsw_plan.exceptions import InputError
from rfsw_plan.process.frames import FloatArray, LoadSchedule, SeamFrames

#: Parameters of :class:`ProcessForces` the fit can estimate, in vector order.
FIT_PARAMS = (
    "axial",
    "lateral",
    "traverse",
    "plunge_peak_axial",
    "dwell_lateral_fraction",
    "dwell_tau",
    "ramp_length",
    "spindle_torque",
)


@dataclass(frozen=True)
class ProcessForces:
    """Steady forces and ramp constants of the parametric force model.

    Attributes:
        axial: Steady axial force Fd [N], along +n (seed 001: 4842.58 N).
        lateral: Steady lateral force magnitude Fl [N] (seed 001: 1350.87 N).
        traverse: Steady traverse (resistance) force Fr [N], along -t (seed 001: 899.80 N).
        lateral_sign: +1 if the lateral force points to the advancing side (+l), -1 if to the
            retreating side.
        plunge_peak_axial: Axial force at the end of the plunge [N]; None = ``axial``.
        dwell_lateral_fraction: Fraction c_l of Fl built up by a long dwell [-].
        dwell_tau: Softening time constant T_d of the dwell [s].
        ramp_length: Length constant L over which the weld forces settle [m].
        spindle_torque: Reaction torque M_s of the workpiece on the tool about its axis [N m].
        source: Where the numbers come from.
    """

    axial: float
    lateral: float
    traverse: float
    lateral_sign: float = 1.0
    plunge_peak_axial: float | None = None
    dwell_lateral_fraction: float = 0.5
    dwell_tau: float = 2.0
    ramp_length: float = 1.0e-3
    spindle_torque: float = 0.0
    source: str = ""

    def __post_init__(self) -> None:
        for name in ("axial", "lateral", "traverse", "dwell_lateral_fraction", "spindle_torque"):
            v = getattr(self, name)
            if not np.isfinite(v):
                raise InputError("process.forces", name, f"got {v}", "a finite number")
        for name in ("axial", "lateral", "traverse"):
            if getattr(self, name) < 0:
                raise InputError("process.forces", f"{name}_N", f"got {getattr(self, name):g}",
                                 ">= 0 (the direction is fixed by the model)")
        if self.lateral_sign not in (1.0, -1.0):
            raise InputError("process.forces", "lateral_sign", f"got {self.lateral_sign:g}",
                             "+1 (toward the advancing side) or -1")
        if self.plunge_peak_axial is not None and not self.plunge_peak_axial >= 0:
            raise InputError("process.forces", "plunge_peak_axial_N",
                             f"got {self.plunge_peak_axial:g}", ">= 0")
        if not self.dwell_tau > 0:
            raise InputError("process.forces", "dwell_tau_s", f"got {self.dwell_tau:g}", "> 0")
        if not self.ramp_length > 0:
            raise InputError("process.forces", "ramp_length_mm",
                             f"got {self.ramp_length * 1e3:g}", "> 0")

    @property
    def peak_axial(self) -> float:
        """Axial force at the end of the plunge [N]."""
        return self.axial if self.plunge_peak_axial is None else self.plunge_peak_axial

    @property
    def steady_seam(self) -> FloatArray:
        """Steady weld force in the seam frame (f_t, f_l, f_n) [N], shape (3,)."""
        return np.array([-self.traverse, self.lateral_sign * self.lateral, self.axial])

    def vector(self) -> FloatArray:
        """Parameters in :data:`FIT_PARAMS` order (lateral signed), SI units."""
        return np.array([
            self.axial, self.lateral_sign * self.lateral, self.traverse, self.peak_axial,
            self.dwell_lateral_fraction, self.dwell_tau, self.ramp_length, self.spindle_torque,
        ])

    def with_vector(self, x: FloatArray, source: str | None = None) -> ProcessForces:
        """A copy with parameters from a :data:`FIT_PARAMS`-ordered vector (lateral signed)."""
        lat = float(x[1])
        return replace(
            self, axial=float(x[0]), lateral=abs(lat),
            lateral_sign=1.0 if lat >= 0 else -1.0, traverse=float(x[2]),
            plunge_peak_axial=float(x[3]), dwell_lateral_fraction=float(x[4]),
            dwell_tau=float(x[5]), ramp_length=float(x[6]), spindle_torque=float(x[7]),
            source=self.source if source is None else source,
        )


@dataclass(frozen=True)
class PhaseTimes:
    """Start times and durations of the phases [s] for one seam length."""

    approach: float
    plunge: float
    dwell: float
    weld: float
    retract: float
    stop: float = 0.0

    @property
    def durations(self) -> FloatArray:
        """Duration of each phase in :data:`PHASES` order [s], shape (6,)."""
        return np.array([self.approach, self.plunge, self.dwell, self.weld, self.stop,
                         self.retract])

    @property
    def starts(self) -> FloatArray:
        """Start time of each phase in :data:`PHASES` order [s], shape (6,)."""
        return np.concatenate([[0.0], np.cumsum(self.durations)[:-1]])

    @property
    def total(self) -> float:
        """Total process time [s]."""
        return float(np.sum(self.durations))


#: Default spindle run-up time [s]: ASSUMED. No seed states one (seed 001's electric spindle is
#: rated 5000 rpm and 55 N m, its acceleration is not given); 2 s brings a motor spindle of
#: that class to a weld speed of 1200-1500 rpm with room to spare. Set ``spindle_runup_s`` in
#: ``[process]`` from the spindle's data sheet.
SPINDLE_RUNUP = 2.0

#: Default end stop [s]: ASSUMED. No seed measures the forces after travel ends (seed 001's
#: Fig. 10 and seed 000's Fig. 22 show the plunge, dwell and weld); the tool stands for 1.5
#: dwell time constants T_d (the bundled T_d = 2 s, itself ASSUMED: how long the standing
#: tool's forces take to settle at the start) while the forces relax to the start
#: standstill's, so the retract starts from them. Set ``end_stop_s`` in ``[process]`` from a
#: measured force log (0: no end stop, the forces relax over the retract).
END_STOP = 3.0

#: Axial control modes of the weld (``[process] axial_control``).
AXIAL_CONTROLS = ("position", "force")


@dataclass(frozen=True)
class ProcessModel:
    """FSW process: phase kinematics plus the parametric force model.

    Attributes:
        forces: Force parameters.
        travel_speed: Weld travel speed [m/s] (seed 001: 3 mm/s; seed 000: 6 mm/s).
        plunge_speed: Plunge speed [m/s] (seed 001: 2 mm/s).
        plunge_depth: Commanded depth of the pin tip below the surface at the end of the
            plunge [m]; the seam points lie at this depth.
        dwell_time: Dwell at full depth before travel [s].
        retract_speed: Retract speed [m/s].
        approach_height: Height above the surface where the approach starts [m]; 0 = none.
        approach_speed: Approach speed [m/s].
        rotation_speed_rpm: Spindle speed [rpm] (written with every sample of the plan).
        spindle_runup: Time the spindle takes from rest to ``rotation_speed_rpm`` [s]: the
            plan stands at the spindle clearance above the plate for it, after the
            spindle-start hook and before the plunge moves down (default
            :data:`SPINDLE_RUNUP`).
        end_stop: How long the tool stands at the seam end with the pin in the plate before
            the retract, while the forces relax to the start standstill's [s] (default
            :data:`END_STOP`; 0: none).
        axial_control: ``position`` (seed 001: the robot holds the commanded depth; the
            planner's depth rows apply) or ``force`` (seed 000: the controller's axial force
            loop holds the set force ``forces.axial`` and with it the depth; the program
            switches it on and off through the ``force_on``/``force_off`` hooks).
        name: Process name.
        material: Workpiece material (informational).
        thickness: Sheet thickness [m] (informational).
        source: Where the numbers come from.
    """

    forces: ProcessForces
    travel_speed: float
    plunge_speed: float
    plunge_depth: float
    dwell_time: float = 5.0
    retract_speed: float = 5.0e-3
    approach_height: float = 0.0
    approach_speed: float = 10.0e-3
    rotation_speed_rpm: float = 0.0
    spindle_runup: float = SPINDLE_RUNUP
    end_stop: float = END_STOP
    axial_control: str = "position"
    name: str = ""
    material: str = ""
    thickness: float = 0.0
    source: str = ""

    def __post_init__(self) -> None:
        checks = {
            "travel_speed_mm_s": (self.travel_speed, 1e3),
            "plunge_speed_mm_s": (self.plunge_speed, 1e3),
            "plunge_depth_mm": (self.plunge_depth, 1e3),
            "retract_speed_mm_s": (self.retract_speed, 1e3),
            "approach_speed_mm_s": (self.approach_speed, 1e3),
        }
        for key, (v, scale) in checks.items():
            if not (np.isfinite(v) and v > 0):
                raise InputError("process", key, f"got {v * scale:g}", "> 0")
        if not (np.isfinite(self.spindle_runup) and self.spindle_runup >= 0):
            raise InputError("process", "spindle_runup_s", f"got {self.spindle_runup:g}", ">= 0")
        if not (np.isfinite(self.end_stop) and self.end_stop >= 0):
            raise InputError("process", "end_stop_s", f"got {self.end_stop:g}", ">= 0")
        if not (np.isfinite(self.dwell_time) and self.dwell_time >= 0):
            raise InputError("process", "dwell_s", f"got {self.dwell_time:g}", ">= 0")
        if self.axial_control not in AXIAL_CONTROLS:
            raise InputError("process", "axial_control", f"got {self.axial_control!r}",
                             " or ".join(f'"{a}"' for a in AXIAL_CONTROLS))
        if not (np.isfinite(self.approach_height) and self.approach_height >= 0):
            raise InputError("process", "approach_height_mm",
                             f"got {self.approach_height * 1e3:g}", ">= 0")

    # -- timing ------------------------------------------------------------------------------
    def phase_times(self, length: float) -> PhaseTimes:
        """Phase durations [s] for a seam of arc length ``length`` [m]."""
        return PhaseTimes(
            approach=self.approach_height / self.approach_speed,
            plunge=self.plunge_depth / self.plunge_speed,
            dwell=self.dwell_time,
            weld=length / self.travel_speed,
            retract=self.plunge_depth / self.retract_speed,
            stop=self.end_stop,
        )

    def steady_force_seam(self) -> FloatArray:
        """Steady weld force (f_t, f_l, f_n) in the seam frame [N], shape (3,)."""
        return self.forces.steady_seam

    # -- the parametric profile --------------------------------------------------------------
    def profile(
        self, t: FloatArray, length: float, forces: ProcessForces | None = None
    ) -> tuple[np.ndarray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """Phase, arc length, depth, seam-frame force and axial torque at given times.

        Args:
            t: Times from the start of the process [s], shape (N,).
            length: Seam arc length [m].
            forces: Force parameters to use (default: ``self.forces``; the fit passes trials).

        Returns:
            phase (N,) str, s (N,) [m], depth (N,) [m], force_seam (N, 3) (f_t, f_l, f_n)
            [N], torque (N,) reaction torque magnitude about the tool axis [N m] (to be
            multiplied by sigma n).
        """
        fp = self.forces if forces is None else forces
        t = np.asarray(t, dtype=float)
        pt = self.phase_times(length)
        st = pt.starts
        # A sample on a phase boundary belongs to the phase it completes (the weld ends at
        # s = length, the plunge at full depth); t = 0 starts the first phase.
        idx = np.clip(np.searchsorted(st, t, side="left") - 1, 0, 5)
        # Zero-length phases (no approach, no dwell, no end stop) must never own a sample.
        dur = pt.durations
        for k in range(6):
            while True:
                bad = (idx == k) & (dur[k] <= 0)
                if not bad.any():
                    break
                idx[bad] = min(k + 1, 5)
        phases = np.array(["approach", "plunge", "dwell", "weld", "stop", "retract"])
        tau = np.clip(t - st[idx], 0.0, None)
        N = t.shape[0]
        s = np.zeros(N)
        depth = np.zeros(N)
        F = np.zeros((N, 3))
        torque = np.zeros(N)
        h, dp = self.approach_height, self.plunge_depth
        Fd, Fl, Fr = fp.axial, fp.lateral_sign * fp.lateral, fp.traverse
        Fpk, cl, Td, L, Ms = (fp.peak_axial, fp.dwell_lateral_fraction, fp.dwell_tau,
                              fp.ramp_length, fp.spindle_torque)
        # End-of-dwell values (start values of the weld ramps).
        e_d = np.exp(-pt.dwell / Td)
        fn0 = Fd + (Fpk - Fd) * e_d
        gl0 = cl * (1.0 - e_d)

        m = idx == 0
        depth[m] = -h + self.approach_speed * tau[m]
        m = idx == 1
        rho = np.clip(self.plunge_speed * tau[m] / dp, 0.0, 1.0)
        depth[m] = rho * dp
        F[m, 2] = Fpk * rho
        torque[m] = Ms * rho
        m = idx == 2
        e = np.exp(-tau[m] / Td)
        depth[m] = dp
        F[m, 2] = Fd + (Fpk - Fd) * e
        F[m, 1] = Fl * cl * (1.0 - e)
        torque[m] = Ms
        m = idx == 3
        s[m] = np.clip(self.travel_speed * tau[m], 0.0, length)
        e = np.exp(-s[m] / L)
        depth[m] = dp
        F[m, 0] = -Fr * (1.0 - e)
        F[m, 1] = Fl * (1.0 - (1.0 - gl0) * e)
        F[m, 2] = Fd + (fn0 - Fd) * e
        torque[m] = Ms
        e_w = np.exp(-length / L)
        end = np.array([-Fr * (1.0 - e_w), Fl * (1.0 - (1.0 - gl0) * e_w), Fd + (fn0 - Fd) * e_w])
        if pt.stop > 0:
            m = idx == 4
            stand = np.array([0.0, Fl * cl, Fd])
            u = np.clip(tau[m] / pt.stop, 0.0, 1.0)
            prog = u * u * u * (10.0 + u * (6.0 * u - 15.0))
            s[m] = length
            depth[m] = dp
            F[m] = end[None] + prog[:, None] * (stand - end)[None]
            torque[m] = Ms
            end = stand
        m = idx == 5
        rho = np.clip(1.0 - self.retract_speed * tau[m] / dp, 0.0, 1.0)
        s[m] = length
        depth[m] = rho * dp
        F[m] = rho[:, None] * end
        torque[m] = Ms * rho
        return phases[idx], s, depth, F, torque

    def evaluate(
        self, frames: SeamFrames, t: FloatArray, forces: ProcessForces | None = None
    ) -> LoadSchedule:
        """The load schedule at given times.

        Args:
            frames: Seam waypoint frames (base frame) from :meth:`Seam.frames`.
            t: Sample times from the start of the process [s], shape (N,), non-decreasing.
            forces: Force parameters (default ``self.forces``).

        Returns:
            LoadSchedule whose frames sit at the commanded tool-tip position: during approach,
            plunge and retract the tip is ``plunge_depth - depth`` above the seam point along
            n; during weld it is on the seam. ``frames.s`` is the schedule's s (repeats).
        """
        from rfsw_plan.process.seam import interpolate_frames

        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or (t.size > 1 and np.any(np.diff(t) < 0)):
            raise InputError("schedule", "t", "times are not a non-decreasing 1-D array",
                             "non-decreasing times")
        length = float(frames.s[-1] - frames.s[0])
        phase, s, depth, F, torque = self.profile(t, length, forces)
        fr = interpolate_frames(frames, frames.s[0] + s)
        p = fr.p + (self.plunge_depth - depth)[:, None] * fr.n
        fr = SeamFrames(s=s, p=p, t=fr.t, l=fr.l, n=fr.n)
        sigma = np.sign(np.linalg.det(fr.rotation()))
        moment = (sigma * torque)[:, None] * fr.n
        return LoadSchedule(t=t, phase=phase, s=s, depth=depth, frames=fr, force_seam=F,
                            moment_base=moment)

    def schedule(self, frames: SeamFrames, dt: float, approach: bool = True) -> LoadSchedule:
        """The load schedule sampled every ``dt`` through all phases (seed 001 Table 6 uses
        a 0.1 s iteration interval).

        Args:
            frames: Seam waypoint frames from :meth:`Seam.frames`.
            dt: Sample interval [s], > 0.
            approach: Include the approach phase (if ``approach_height`` > 0).

        Returns:
            LoadSchedule; each phase boundary and the process end are sampled exactly.
        """
        if not (np.isfinite(dt) and dt > 0):
            raise InputError("schedule", "dt_s", f"got {dt:g}", "> 0")
        length = float(frames.s[-1] - frames.s[0])
        pt = self.phase_times(length)
        t0 = 0.0 if approach else pt.approach
        grid = np.arange(t0, pt.total, dt)
        t = np.unique(np.concatenate([grid, pt.starts[pt.starts >= t0], [pt.total]]))
        # Boundary samples closer than dt/100 to a grid sample are merged.
        keep = np.concatenate([[True], np.diff(t) > dt * 1e-2])
        return self.evaluate(frames, t[keep])
