"""Virtual weld: where the pin really goes for a nominal path and a compensation strategy.

Ingredients:

* **Truth robot**: an :class:`~rfsw_plan.elastostatics.model.ElastostaticModel`, possibly
  different from the model the controllers and the planner use (scaled stiffness, hidden
  effects; see :func:`truth_model`).
* **Process**: the :class:`~rfsw_plan.process.frames.LoadSchedule` (plunge, dwell, weld,
  retract) resampled at the controller cycle, with a slow force drift along the seam
  (:class:`ProcessVariation`, default +-10 %) that only the sensor sees, not the plan.
* **Sensor** (:class:`SensorModel`): samples the true wrench at its own rate, distorts it by
  the truth's sensor-only effects (misalignment, bias; :func:`sensor_reading`), adds white
  noise, and delivers each sample after a delay.
* **Controller**: one :class:`~rfsw_plan.realtime.base.Strategy` step per cycle (default 4 ms,
  KUKA RSI); its correction offset is applied ``actuation_delay_cycles`` later.

Linearisation (what makes a 12 s weld simulate in milliseconds): the model quantities the
controllers need (Jacobian, model deflection under measured and planned wrench) are evaluated
once, vectorised, along the nominal path; they do not depend on the controller state up to
second order (a few mm of correction barely changes the compliance). After the controller
loop the commanded joints follow from a first-order update ``q_c = q + J^+ [c; 0]`` (base
frame, rotation unchanged), and the actual pin is evaluated exactly with the truth robot:
``p_pin = FK(q_c) + dX_truth(q_c, F_true)`` (relative to zero process load for a taught
seam). The lateral error is
``e = (p_pin - p_seam) . l`` [m], positive toward the advancing side.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.effects import PoseBatch, WrenchEffect
from rfsw_plan.elastostatics.model import ElastostaticModel, SeamReference
from rfsw_plan.exceptions import InputError
from rfsw_plan.process.frames import LoadSchedule
from rfsw_plan.realtime.base import ControllerInputs, FloatArray, Strategy


@dataclass(frozen=True)
class SensorModel:
    """Force/torque sensor in the end effector.

    Attributes:
        rate_hz: Sample rate [Hz].
        delay_s: Delay from sampling to availability in the controller [s].
        noise_force_N: Standard deviation of the white noise per force component [N].
        noise_moment_Nm: Standard deviation per moment component [N m].
        seed: Seed of the noise generator (runs are reproducible).
    """

    rate_hz: float = 1000.0
    delay_s: float = 0.004
    noise_force_N: float = 30.0
    noise_moment_Nm: float = 3.0
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.rate_hz > 0:
            raise InputError("sensor", "rate_hz", f"got {self.rate_hz:g}", "> 0")
        if not self.delay_s >= 0:
            raise InputError("sensor", "delay_s", f"got {self.delay_s:g}", ">= 0")
        if self.noise_force_N < 0 or self.noise_moment_Nm < 0:
            raise InputError("sensor", "noise", "negative standard deviation", ">= 0")

    def scaled_noise(self, factor: float) -> SensorModel:
        """The same sensor with the noise multiplied by ``factor``."""
        return SensorModel(
            self.rate_hz, self.delay_s, self.noise_force_N * factor,
            self.noise_moment_Nm * factor, self.seed,
        )


@dataclass(frozen=True)
class ProcessVariation:
    """Slow variation of the process wrench along the seam, unknown to the plan.

    During the weld the whole wrench is multiplied by ``1 + amplitude sin(2 pi s / lambda)``
    (zero at the weld start, so it does not disturb the start transient).

    Attributes:
        amplitude: Relative amplitude [-] (default 0.10, i.e. +-10 %).
        wavelength_m: Wavelength lambda [m]; None = the weld length (one full period).
    """

    amplitude: float = 0.10
    wavelength_m: float | None = None

    def __post_init__(self) -> None:
        if not 0.0 <= self.amplitude < 1.0:
            raise InputError("variation", "amplitude", f"got {self.amplitude:g}", "0 <= a < 1")
        if self.wavelength_m is not None and not self.wavelength_m > 0:
            raise InputError("variation", "wavelength_m", f"got {self.wavelength_m:g}", "> 0")

    def factor(self, s: FloatArray, weld: NDArray[np.bool_], weld_length: float) -> FloatArray:
        """Wrench multiplier per sample, shape like ``s``; 1 outside the weld."""
        lam = self.wavelength_m or max(weld_length, 1e-9)
        f = 1.0 + self.amplitude * np.sin(2.0 * np.pi * s / lam)
        return np.where(weld, f, 1.0)


@dataclass(frozen=True)
class SimConfig:
    """Settings of the virtual weld.

    Attributes:
        cycle_s: Controller cycle [s] (KUKA RSI: 4 ms).
        sensor: The force sensor.
        variation: The slow process variation.
        actuation_delay_cycles: Cycles between a strategy's output and the robot moving.
        active_phases: Phases in which the real-time correction may act.
    """

    cycle_s: float = 0.004
    sensor: SensorModel = field(default_factory=SensorModel)
    variation: ProcessVariation = field(default_factory=ProcessVariation)
    actuation_delay_cycles: int = 1
    active_phases: tuple[str, ...] = ("weld",)

    def __post_init__(self) -> None:
        if not self.cycle_s > 0:
            raise InputError(
                "simulator", "cycle_ms", f"controller cycle {self.cycle_s * 1e3:g} ms", "> 0 ms"
            )
        if self.actuation_delay_cycles < 0:
            raise InputError(
                "simulator", "actuation_delay_cycles", f"got {self.actuation_delay_cycles}", ">= 0"
            )


@dataclass(frozen=True)
class NominalPath:
    """The path the robot runs before any real-time correction, at the controller cycles.

    Attributes:
        name: ``"taught"`` or ``"plan"``.
        q: Commanded joint values [rad], shape (K, n).
        planned_for_load: True if the path already pre-compensates the schedule's nominal
            wrench (an offline plan); False for a taught path (planned for no load).
    """

    name: str
    q: FloatArray
    planned_for_load: bool


@dataclass(frozen=True)
class WeldRun:
    """Outcome of one virtual weld.

    Attributes:
        strategy: Strategy name (``none``, ``realtime_seed000``, ``offline``...).
        path: Nominal path name.
        t: Cycle times [s], shape (K,).
        s: Arc length of the nominal tool position [m], shape (K,).
        phase: Phase per cycle, shape (K,).
        lateral_error: Lateral pin error (advancing side positive) [m], shape (K,).
        pin: Actual pin position, base frame [m], shape (K, 3).
        seam: Seam point at the nominal position, base frame [m], shape (K, 3).
        travel: Travel direction t, base frame, shape (K, 3).
        correction: Applied real-time correction, base frame [m], shape (K, 3).
        sim_time_s: Wall time of this run (controller loop + pin evaluation) [s].
    """

    strategy: str
    path: str
    t: FloatArray
    s: FloatArray
    phase: NDArray[np.str_]
    lateral_error: FloatArray
    pin: FloatArray
    seam: FloatArray
    travel: FloatArray
    correction: FloatArray
    sim_time_s: float

    @property
    def weld(self) -> NDArray[np.bool_]:
        """Mask of the weld-phase cycles."""
        return self.phase == "weld"


def truth_model(
    model: ElastostaticModel,
    stiffness_scale: float = 1.0,
    effects: Iterable[tuple[str, Mapping[str, float] | None]] = (),
) -> ElastostaticModel:
    """A truth robot that differs from the model.

    Args:
        model: The model the controllers and the planner use.
        stiffness_scale: Factor on every joint stiffness (0.8 = 20 % softer).
        effects: Extra (hidden) effects as ``(label, params)``; params None = the prior.

    Raises:
        InputError: Non-positive scale, or an effect already in the model.
        UnknownNameError: Unknown effect name.
    """
    if not stiffness_scale > 0:
        raise InputError(
            "truth", "stiffness_scale", f"got {stiffness_scale:g}", "> 0 (1 = same as model)"
        )
    truth = model.copy()
    truth.joint_compliance.params = truth.joint_compliance.params / stiffness_scale
    for label, params in effects:
        truth = truth.with_effect(label, dict(params) if params else None)
    return truth


def sensor_reading(
    truth: ElastostaticModel, batch: PoseBatch, wrench: FloatArray, tol: float = 1e-12,
    max_iter: int = 100,
) -> FloatArray:
    """What a sensor with the truth's sensor-only effects logs for a true wrench.

    A sensor-only effect e (sensor misalignment, force sensor bias) maps the logged wrench L
    to the true one, F = L + sum_e dF_e(L) (:meth:`ElastostaticModel.true_wrench`); the
    sensor does the inverse, solved by the fixed point L <- F - sum_e dF_e(L) from L = F
    (one step for a bias, which is constant; for a misalignment by phi the error shrinks by
    about |phi| per step).

    Args:
        truth: The robot as it really is; only its sensor-only wrench effects are used.
        batch: Poses at the sample times (the tool rotation turns sensor-frame quantities).
        wrench: True wrench at the TCP [N, N m], base frame, shape (m, 6).
        tol: Convergence tolerance relative to the largest wrench component [-].
        max_iter: Maximum fixed-point steps.

    Returns:
        Logged wrench [N, N m], base frame, shape (m, 6); ``wrench`` itself (same array)
        when the truth has no sensor-only effect.

    Raises:
        InputError: The fixed point does not converge (a sensor effect too large to invert,
            e.g. a misalignment near 1 rad or more).
    """
    sensor: list[WrenchEffect] = [e for e in truth.groups.wrench if e.sensor_only]
    F = np.asarray(wrench, dtype=float)
    if not sensor:
        return F
    scale = tol * max(float(np.max(np.abs(F), initial=0.0)), 1.0)
    L = F.copy()
    for _ in range(max_iter):
        L_new = F - sum((e.delta_wrench(batch, L, e.params) for e in sensor),
                        np.zeros_like(F))
        done = float(np.max(np.abs(L_new - L), initial=0.0)) <= scale
        L = L_new
        if done:
            return L
    raise InputError(
        "truth", ", ".join(e.label for e in sensor),
        f"the sensor reading does not converge in {max_iter} fixed-point steps",
        "sensor effects small enough to invert (misalignment well below 1 rad)",
    )


def _interp_rows(t_new: FloatArray, t: FloatArray, y: FloatArray) -> FloatArray:
    """Linear interpolation of each column of y (N, d) at t_new, shape (K, d)."""
    return np.stack([np.interp(t_new, t, y[:, j]) for j in range(y.shape[1])], axis=1)


def _min_norm_step(J: FloatArray, twist: FloatArray) -> FloatArray:
    """Joint step dq with J dq = twist, per row: J^T (J J^T)^-1 twist [rad], shape (K, n).

    Exact inverse for a non-singular 6-joint arm, minimum-norm step for a redundant one.
    """
    JJt = np.einsum("kin,kjn->kij", J, J)
    y = np.linalg.solve(JJt, twist[..., None])[..., 0]
    return np.einsum("kin,ki->kn", J, y)


def _unit(v: FloatArray) -> FloatArray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


class VirtualWeld:
    """One weld process, ready to run any nominal path with any strategy.

    Args:
        schedule: The process over time (forces in the seam frame, seam frames).
        model: The elastostatic model the controllers use.
        truth: The robot as it really is; None = the model itself.
        config: Cycle, sensor and process variation.
        reference: How the seam was obtained (``taught`` or ``absolute``): the truth's
            deflection under the true process wrench is taken relative to zero process load
            for a taught seam (:meth:`ElastostaticModel.process_deflection`). The truth's
            sensor-only effects do not move the pin; they distort what the simulated force
            sensor logs (:meth:`measured_wrench`).
    """

    def __init__(
        self,
        schedule: LoadSchedule,
        model: ElastostaticModel,
        truth: ElastostaticModel | None = None,
        config: SimConfig | None = None,
        reference: SeamReference = "taught",
    ) -> None:
        self.config = config or SimConfig()
        self.reference: SeamReference = reference
        self.model = model
        self.truth = truth if truth is not None else model
        self.schedule = schedule
        cfg = self.config
        ts = np.asarray(schedule.t, dtype=float)
        if ts.size < 2 or ts[-1] <= ts[0]:
            raise InputError("schedule", "t", "fewer than two distinct time samples")
        dt = cfg.cycle_s
        K = int(np.floor((ts[-1] - ts[0]) / dt + 1e-9)) + 1
        self.t = ts[0] + dt * np.arange(K)
        idx = np.clip(np.searchsorted(ts, self.t, side="right") - 1, 0, len(ts) - 1)
        self.phase = np.asarray(schedule.phase)[idx]
        self.weld_mask = self.phase == "weld"
        if not np.any(self.weld_mask):
            raise InputError("schedule", "phase", "no weld phase", "samples with phase 'weld'")
        self.active = np.isin(self.phase, cfg.active_phases)
        self.s = np.interp(self.t, ts, schedule.s)
        fr = schedule.frames
        self.seam = _interp_rows(self.t, ts, fr.p)
        self.travel = _unit(_interp_rows(self.t, ts, fr.t))
        self.lateral = _unit(_interp_rows(self.t, ts, fr.l))
        sw = self.s[self.weld_mask]
        self.weld_length = float(sw.max() - sw.min())
        self.wrench_nominal = self._wrench_at(self.t)
        self.wrench_true = self.wrench_nominal * self._drift(self.t)[:, None]
        self._sensor_samples()
        #: Wrench read by the controller at each cycle [N, N m], base frame, shape (K, 6),
        #: from a sensor without the truth's sensor-only effects; the reading along a path,
        #: with them, is :meth:`measured_wrench`.
        self.wrench_measured = self._read(self._true_read)

    # -- process and sensor ------------------------------------------------------------------
    def _wrench_at(self, times: FloatArray) -> FloatArray:
        """Nominal schedule wrench at arbitrary times, base frame [N, N m], shape (m, 6)."""
        sch = self.schedule
        ts = sch.t
        f_seam = _interp_rows(times, ts, sch.force_seam)
        fr = sch.frames
        R = np.stack(
            [_unit(_interp_rows(times, ts, v)) for v in (fr.t, fr.l, fr.n)], axis=-1
        )
        f = np.einsum("kij,kj->ki", R, f_seam)
        m = _interp_rows(times, ts, sch.moment_base)
        return np.hstack([f, m])

    def _drift(self, times: FloatArray) -> FloatArray:
        sch = self.schedule
        idx = np.clip(np.searchsorted(sch.t, times, side="right") - 1, 0, len(sch.t) - 1)
        weld = np.asarray(sch.phase)[idx] == "weld"
        s = np.interp(times, sch.t, sch.s)
        s0 = float(np.min(self.s[self.weld_mask]))
        return self.config.variation.factor(s - s0, weld, self.weld_length)

    def _sensor_samples(self) -> None:
        """The sensor sample the controller reads at each cycle (the latest one older than
        the delay): its time, true wrench and noise, and whether any sample has arrived."""
        sen = self.config.sensor
        t0 = self.t[0]
        n_samples = int(np.floor((self.t[-1] - t0) * sen.rate_hz + 1e-9)) + 1
        j = np.floor((self.t - sen.delay_s - t0) * sen.rate_hz + 1e-9).astype(int)
        valid = j >= 0
        j = np.clip(j, 0, n_samples - 1)
        t_read = t0 + j / sen.rate_hz
        rng = np.random.default_rng(sen.seed)
        noise = rng.standard_normal((n_samples, 6))
        noise[:, :3] *= sen.noise_force_N
        noise[:, 3:] *= sen.noise_moment_Nm
        self._t_read = t_read
        self._true_read = self._wrench_at(t_read) * self._drift(t_read)[:, None]
        self._noise_read = noise[j]
        self._valid_read = valid

    def _read(self, logged: FloatArray) -> FloatArray:
        """Noise and delay on the sensor's (possibly distorted) samples, shape (K, 6)."""
        w = logged + self._noise_read
        w[~self._valid_read] = 0.0  # nothing has arrived yet
        return w

    def measured_wrench(self, path: NominalPath) -> FloatArray:
        """Wrench the controller reads at each cycle along a path [N, N m], base frame,
        shape (K, 6).

        Each sample is what the truth's sensor logs (:func:`sensor_reading`) for the true
        wrench at the tool orientation of the nominal path at the sample time, then noise and
        delay as in :attr:`wrench_measured` (which it equals when the truth has no
        sensor-only effect). The real-time correction moves the tool, not its orientation
        (:meth:`run`), and the deflection's rotation (mrad) is neglected.
        """
        if not any(e.sensor_only for e in self.truth.effects):
            return self.wrench_measured
        q_read = _interp_rows(self._t_read, self.t, path.q)
        logged = sensor_reading(self.truth, self.truth.batch(q_read), self._true_read)
        return self._read(logged)

    # -- nominal paths -----------------------------------------------------------------------
    def path_from_waypoints(
        self,
        s_wp: FloatArray,
        q_wp: FloatArray,
        name: str = "taught",
        planned_for_load: bool = False,
        stationary: tuple[FloatArray, FloatArray] | None = None,
    ) -> NominalPath:
        """Resample a waypoint path at the controller cycles.

        Joints are interpolated linearly in arc length; the stationary phases (plunge,
        dwell at s = 0) take the first waypoint unless ``stationary`` gives a time series.

        Args:
            s_wp: Waypoint arc lengths [m], shape (k,), increasing.
            q_wp: Waypoint joint values [rad], shape (k, n).
            name: Path name.
            planned_for_load: True if the path pre-compensates the nominal wrench.
            stationary: Optional ``(t, q)`` joint values [rad] over time [s] for the cycles
                before the weld (an offline plan's offsets over the plunge/dwell ramp).
        """
        s_wp = np.asarray(s_wp, dtype=float)
        q_wp = np.atleast_2d(np.asarray(q_wp, dtype=float))
        if s_wp.ndim != 1 or s_wp.shape[0] != q_wp.shape[0]:
            raise InputError(name, "waypoints", "s and q lengths differ")
        q = _interp_rows(self.s, s_wp, q_wp)
        if stationary is not None:
            t_st, q_st = np.asarray(stationary[0], float), np.atleast_2d(stationary[1])
            pre = self.t < self.t[self.weld_mask][0]
            q[pre] = _interp_rows(self.t[pre], t_st, q_st)
        return NominalPath(name, q, planned_for_load)

    # -- running -----------------------------------------------------------------------------
    def controller_inputs(self, path: NominalPath) -> ControllerInputs:
        """Everything the controller knows, cycle by cycle, for one nominal path."""
        if path.q.shape[0] != len(self.t):
            raise InputError(path.name, "q", f"{path.q.shape[0]} rows", f"{len(self.t)} cycles")
        batch = self.model.batch(path.q)
        measured = self.measured_wrench(path)
        dX_meas = self.model.deflection_batch(batch, measured)
        F_plan = self.wrench_nominal if path.planned_for_load else np.zeros_like(
            self.wrench_nominal
        )
        dX_plan = (
            self.model.deflection_batch(batch, F_plan)
            if path.planned_for_load else np.zeros_like(dX_meas)
        )
        return ControllerInputs(
            t=self.t, dt=self.config.cycle_s, phase=self.phase, active=self.active, s=self.s,
            lateral=self.lateral, q=path.q, jacobian=batch.J, force_measured=measured,
            force_planned=F_plan, model_deflection=dX_meas, model_deflection_planned=dX_plan,
        )

    def run(
        self,
        strategy: Strategy,
        path: NominalPath,
        label: str | None = None,
        inputs: ControllerInputs | None = None,
    ) -> WeldRun:
        """Simulate one weld.

        Args:
            strategy: The real-time strategy (``NoCompensation`` for open loop).
            path: The nominal path.
            label: Name of the run (default: the strategy's name).
            inputs: Precomputed :meth:`controller_inputs` for this path (saves time when
                several strategies share a path).
        """
        tic = time.perf_counter()
        if inputs is None:
            inputs = self.controller_inputs(path)
        elif inputs.q is not path.q:
            raise InputError(path.name, "inputs", "controller inputs belong to another path")
        corr = np.asarray(strategy.run(inputs), dtype=float)
        d = self.config.actuation_delay_cycles
        applied = np.zeros_like(corr)
        if d == 0:
            applied[:] = corr
        else:
            applied[d:] = corr[:-d]
        q_cmd = path.q
        if np.any(applied):
            twist = np.hstack([applied, np.zeros_like(applied)])
            q_cmd = path.q + _min_norm_step(inputs.jacobian, twist)
        tb = self.truth.batch(q_cmd)
        dX = self.truth.process_deflection_batch(tb, self.wrench_true, self.reference)
        pin = tb.T[:, :3, 3] + dX[:, :3]
        e = np.einsum("ki,ki->k", pin - self.seam, self.lateral)
        return WeldRun(
            strategy=label or strategy.name, path=path.name, t=self.t, s=self.s,
            phase=self.phase, lateral_error=e, pin=pin, seam=self.seam, travel=self.travel,
            correction=applied, sim_time_s=time.perf_counter() - tic,
        )
