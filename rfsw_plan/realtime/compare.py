"""Offline pre-compensation against real-time compensation, on the same virtual weld.

Strategies (:data:`STRATEGIES`):

``none``
    The taught path, open loop.
``realtime_seed000``
    The taught path plus seed 000's force -> model -> averaged lateral correction.
``realtime_seed002``
    The taught path plus seed 002's model displacement -> MAF -> self-incrementing PID.
``offline``
    The planner's plan (poses and fake-target offsets, over plunge/dwell and weld), open loop.
``hybrid``
    The planner's plan plus a real-time correction of only the residual between the model
    deflection under the measured and under the planned force (:mod:`rfsw_plan.realtime.hybrid`).

Scenarios: the main run uses the truth given by the caller (default: truth = model); the
sensitivity reruns use a truth 20 % softer than the model, a hidden effect the model lacks,
and 3x sensor noise. The plan is computed once, from the model, and reused.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InfeasibleError, InputError, UnknownNameError
from rfsw_plan.files import write_figure, write_json, write_text
from rfsw_plan.numfmt import fixed, general
from rfsw_plan.planfiles.rebuild import PlannedWaypoints
from rfsw_plan.process.frames import LoadSchedule, SeamFrames
from rfsw_plan.process.problem import Problem
from rfsw_plan.process.taught import taught_path
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.progress import Bar
from rfsw_plan.realtime.base import FloatArray, NoCompensation, Strategy
from rfsw_plan.realtime.capped_pid import FilteredCappedPID
from rfsw_plan.realtime.force_feedback import ForceFeedbackFilteredCorrection
from rfsw_plan.realtime.hybrid import HybridResidual
from rfsw_plan.realtime.metrics import WeldMetrics, weld_metrics
from rfsw_plan.realtime.simulator import (
    NominalPath,
    ProcessVariation,
    SensorModel,
    SimConfig,
    VirtualWeld,
    WeldRun,
    truth_model,
)
from rfsw_plan.robot.kinematics import load_robot

#: Strategy names in report order.
STRATEGIES = ("none", "realtime_seed000", "realtime_seed002", "offline", "hybrid")
#: Strategies that need the offline plan.
PLANNED = ("offline", "hybrid")

EffectSpecs = tuple[tuple[str, Mapping[str, float] | None], ...]


Planner = Callable[[Problem], PlannedWaypoints]


def default_planner(problem: Problem) -> PlannedWaypoints:
    """Plan with :func:`rfsw_plan.planning.api.plan` (imported lazily).

    Raises:
        InfeasibleError: The planner finds no plan inside the window.
    """
    from rfsw_plan.planning.api import plan

    tic = time.perf_counter()
    result = plan(problem)
    toc = time.perf_counter() - tic
    return planned_waypoints(result, toc)


def planned_waypoints(result: Any, solve_time_s: float = 0.0) -> PlannedWaypoints:
    """Adapter from the planner's result (``.task`` PlanTask and ``.q``) to the simulator."""
    task = result.task
    q = np.asarray(result.q, dtype=float)
    return PlannedWaypoints(
        time=np.asarray(task.time, dtype=float), phase=np.asarray(task.phase).astype(str),
        s=np.asarray(task.s, dtype=float) - float(task.s[0]), q=q, solve_time_s=solve_time_s,
    )


@dataclass(frozen=True)
class CompareOptions:
    """Settings of a comparison.

    Attributes:
        strategies: Strategies to run, a subset of :data:`STRATEGIES`.
        cycle_s: Controller cycle [s].
        sensor: Force sensor.
        variation: Slow process variation (force drift along the seam).
        truth_stiffness_scale: Truth joint stiffness / model joint stiffness, main run.
        truth_effects: Hidden effects of the truth in the main run, ``(label, params)``.
        sensitivity: Also run the sensitivity scenarios.
        sensitivity_stiffness_scale: Truth stiffness factor of the stiffness scenario.
        hidden_effect: Effect of the hidden-effect scenario; None picks the tilting
            compliance with the largest lateral effect on this seam (at its prior).
        noise_factor: Sensor-noise factor of the noise scenario.
        seed000_average_percent: Seed 000 averaging percentage [%].
        seed000_update_s: Seed 000 update period [s]; None = every controller cycle.
        seed002_maf_samples: Seed 002 moving-average length [algorithm steps].
        seed002_step_s: Seed 002 algorithm step [s].
        hybrid_average_percent: Averaging percentage of the hybrid residual correction [%].
    """

    strategies: tuple[str, ...] = STRATEGIES
    cycle_s: float = 0.004
    sensor: SensorModel = field(default_factory=SensorModel)
    variation: ProcessVariation = field(default_factory=ProcessVariation)
    truth_stiffness_scale: float = 1.0
    truth_effects: EffectSpecs = ()
    sensitivity: bool = True
    sensitivity_stiffness_scale: float = 0.8
    hidden_effect: tuple[str, Mapping[str, float] | None] | None = None
    noise_factor: float = 3.0
    seed000_average_percent: float = 50.0
    seed000_update_s: float | None = 0.25
    seed002_maf_samples: int = 320
    seed002_step_s: float = 0.5e-3
    hybrid_average_percent: float = 95.0

    def __post_init__(self) -> None:
        if not self.strategies:
            raise InputError("compare", "strategies", "none given", ", ".join(STRATEGIES))
        for s in self.strategies:
            if s not in STRATEGIES:
                raise UnknownNameError("strategy", s, STRATEGIES)
        if not self.cycle_s > 0:
            raise InputError(
                "compare", "cycle_ms", f"controller cycle {self.cycle_s * 1e3:g} ms", "> 0 ms"
            )
        if not self.noise_factor >= 0:
            raise InputError("compare", "noise_factor", f"got {self.noise_factor:g}", ">= 0")

    def make_strategy(self, name: str) -> Strategy:
        """A fresh controller for a strategy name (the controller part only)."""
        if name in ("none", "offline"):
            return NoCompensation()
        if name == "realtime_seed000":
            return ForceFeedbackFilteredCorrection(self.seed000_average_percent,
                                                   self.seed000_update_s)
        if name == "realtime_seed002":
            return FilteredCappedPID(self.seed002_step_s, self.seed002_maf_samples)
        if name == "hybrid":
            return HybridResidual(self.hybrid_average_percent)
        raise UnknownNameError("strategy", name, STRATEGIES)


@dataclass(frozen=True)
class NormalError:
    """Seed 002 Table 3's metric: the tool position error along the surface normal.

    e_n = (p_pin - p_seam) . n over the weld cycles, with n the workpiece surface normal at the
    nominal position (base frame). Seed 002 measured it as the distance of the tracked TCP to
    the CAD surface; in-plane errors do not count.

    Attributes:
        mae: Mean absolute error, mean |e_n| over the weld cycles [m].
        max_abs: Largest |e_n| [m].
        mean: Mean signed error [m] (+ along n, away from the workpiece).
        std: Standard deviation of e_n [m].
    """

    mae: float
    max_abs: float
    mean: float
    std: float

    def to_dict(self) -> dict[str, float]:
        """JSON-ready dictionary (mm)."""
        return {"mae_normal_mm": self.mae * 1e3, "max_abs_normal_mm": self.max_abs * 1e3,
                "mean_normal_mm": self.mean * 1e3, "std_normal_mm": self.std * 1e3}


def normal_error(weld: VirtualWeld, run: WeldRun) -> NormalError:
    """:class:`NormalError` of one simulated weld (seed 002 Table 3's MAE along the normal)."""
    sch = weld.schedule
    ts = np.asarray(sch.t, dtype=float)
    nrm = np.column_stack([np.interp(run.t, ts, sch.frames.n[:, i]) for i in range(3)])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    w = run.weld
    e = np.einsum("ki,ki->k", run.pin[w] - run.seam[w], nrm[w])
    return NormalError(float(np.mean(np.abs(e))), float(np.max(np.abs(e))), float(np.mean(e)),
                       float(np.std(e)))


@dataclass(frozen=True)
class Scenario:
    """One truth / sensor setting with the results of every strategy.

    Attributes:
        name: ``main``, ``stiffness_-20%``, ``hidden_<effect>``, ``noise_x3``.
        description: What differs from the model.
        metrics: Metrics per strategy.
        runs: Simulated welds per strategy.
        normal: Error along the surface normal per strategy (seed 002 Table 3's MAE).
    """

    name: str
    description: str
    metrics: dict[str, WeldMetrics]
    runs: dict[str, WeldRun]
    normal: dict[str, NormalError] = field(default_factory=dict)

    def strategy_dict(self, name: str) -> dict[str, Any]:
        """JSON-ready metrics of one strategy: the lateral metrics and the normal error."""
        out = self.metrics[name].to_dict()
        if name in self.normal:
            out.update(self.normal[name].to_dict())
        return out


@dataclass(frozen=True)
class Consistency:
    """The simulator against the ``deviation`` command's prediction (no noise, no drift).

    Attributes:
        simulator_max_abs_lateral: Max |lateral| of ``none`` over the weld [m].
        deviation_max_abs_lateral: Max |lateral| at the waypoints under the steady weld force,
            the ``deviation`` command's headline figure [m].
        deviation_time_max_abs_lateral: Max |lateral| of the ``deviation`` time series over
            the weld (with the weld-start force ramp) [m].
        max_time_difference: Largest |simulator - deviation| over the weld samples of the
            ``deviation`` time series [m].
    """

    simulator_max_abs_lateral: float
    deviation_max_abs_lateral: float
    deviation_time_max_abs_lateral: float
    max_time_difference: float

    @property
    def relative_difference(self) -> float:
        """|sim - deviation| / |deviation| of the max |lateral| (headline figure) [-]."""
        d = self.deviation_max_abs_lateral
        return abs(self.simulator_max_abs_lateral - d) / max(abs(d), 1e-15)


@dataclass(frozen=True)
class CompareResult:
    """Outcome of :func:`compare`.

    Attributes:
        problem: Problem name.
        window: Weld window.
        options: The settings used.
        main: Main scenario.
        sensitivity: Sensitivity scenarios.
        consistency: Simulator vs. deviation command.
        plan_time_s: Planner wall time [s] (0 without offline strategies); printed, never
            written (the files are the same bytes for the same input).
        sim_time_s: Wall time of all simulations [s]; printed, never written.
        weld_duration_s: Duration of the weld phase [s].
        n_cycles: Controller cycles per weld.
        notes: Things the user should know (skipped strategies, assumptions).
    """

    problem: str
    window: WeldWindow
    options: CompareOptions
    main: Scenario
    sensitivity: tuple[Scenario, ...]
    consistency: Consistency | None
    plan_time_s: float
    sim_time_s: float
    weld_duration_s: float
    n_cycles: int
    notes: tuple[str, ...] = ()

    def write(self, folder: str | Path, plot: bool = True) -> list[Path]:
        """Write the compare folder (each file atomically): ``compare.json``, ``compare.md``
        and, with ``plot``, ``compare_lateral.png``. The folder must exist (the CLI prepares
        and locks it).

        Returns:
            The written paths.
        """
        out = Path(folder)
        write_json(out / "compare.json", self.to_dict())
        write_text(out / "compare.md", format_markdown(self))
        files = [out / "compare.json", out / "compare.md"]
        if plot:
            plot_lateral(self, out / "compare_lateral.png")
            files.append(out / "compare_lateral.png")
        return files

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (mm, s): ``compare.json``. No wall time (``plan_time_s``,
        ``sim_time_s``: printed by :func:`format_table`), so the same input writes the same
        bytes."""

        def scen(sc: Scenario) -> dict[str, Any]:
            return {
                "description": sc.description,
                "strategies": {k: sc.strategy_dict(k) for k in sc.metrics},
            }

        out: dict[str, Any] = {
            "problem": self.problem,
            "window": {"lower_mm": self.window.lower * 1e3, "upper_mm": self.window.upper * 1e3},
            "strategies": {k: self.main.strategy_dict(k) for k in self.main.metrics},
            "main": scen(self.main),
            "sensitivity": {sc.name: scen(sc) for sc in self.sensitivity},
            "settings": {
                "cycle_ms": self.options.cycle_s * 1e3,
                "sensor_rate_hz": self.options.sensor.rate_hz,
                "sensor_delay_ms": self.options.sensor.delay_s * 1e3,
                "sensor_noise_N": self.options.sensor.noise_force_N,
                "sensor_noise_Nm": self.options.sensor.noise_moment_Nm,
                "force_drift": self.options.variation.amplitude,
                "truth_stiffness_scale": self.options.truth_stiffness_scale,
                "truth_effects": [e[0] for e in self.options.truth_effects],
                "seed000_average_percent": self.options.seed000_average_percent,
                "seed000_update_ms": (self.options.seed000_update_s or 0.0) * 1e3,
                "seed002_maf_samples": self.options.seed002_maf_samples,
                "seed002_step_ms": self.options.seed002_step_s * 1e3,
                "hybrid_average_percent": self.options.hybrid_average_percent,
            },
            "weld_duration_s": self.weld_duration_s,
            "n_cycles": self.n_cycles,
            "notes": list(self.notes),
        }
        if self.consistency is not None:
            c = self.consistency
            out["consistency"] = {
                "simulator_max_abs_lateral_mm": c.simulator_max_abs_lateral * 1e3,
                "deviation_max_abs_lateral_mm": c.deviation_max_abs_lateral * 1e3,
                "deviation_time_max_abs_lateral_mm": c.deviation_time_max_abs_lateral * 1e3,
                "relative_difference": c.relative_difference,
                "max_time_difference_mm": c.max_time_difference * 1e3,
            }
        return out


# -- building blocks ------------------------------------------------------------------------
def check_filter_fits(options: CompareOptions, weld_duration: float) -> None:
    """Fail early if a strategy's filter window is longer than the weld.

    Raises:
        InputError: The seed 002 moving average, or the seed 000 update period, is longer
            than the weld.
    """
    upd = options.seed000_update_s
    if "realtime_seed000" in options.strategies and upd is not None and upd > weld_duration:
        raise InputError(
            "realtime_seed000", "update_period",
            f"averaging update period {upd * 1e3:g} ms is longer than the weld "
            f"({weld_duration * 1e3:g} ms)",
            "a period shorter than the weld",
        )
    if "realtime_seed002" in options.strategies:
        win = options.seed002_maf_samples * options.seed002_step_s
        if win > weld_duration:
            raise InputError(
                "realtime_seed002", "maf_samples",
                f"filter window {win * 1e3:g} ms ({options.seed002_maf_samples} x "
                f"{options.seed002_step_s * 1e3:g} ms) is longer than the weld "
                f"({weld_duration * 1e3:g} ms)",
                "a window shorter than the weld",
            )


def planned_path(weld: VirtualWeld, wp: PlannedWaypoints) -> NominalPath:
    """The offline plan at the controller cycles: time-interpolated over the stationary
    waypoints (plunge, dwell), arc-length-interpolated over the weld waypoints."""
    w = wp.phase == "weld"
    if not np.any(w):
        raise InputError("plan", "phase", "the plan has no weld waypoints")
    stationary = None
    if np.any(~w):
        stationary = (wp.time[~w], wp.q[~w])
    return weld.path_from_waypoints(
        wp.s[w], wp.q[w], name="plan", planned_for_load=True, stationary=stationary
    )


def pick_hidden_effect(
    model: ElastostaticModel, q: FloatArray, wrench: FloatArray, lateral: FloatArray
) -> tuple[str, None]:
    """The tilting compliance (at its prior) that moves the pin most laterally.

    Args:
        model: The model (the effect is one it does not have).
        q: A weld configuration [rad], shape (n,).
        wrench: The weld wrench there, base frame [N, N m], shape (6,).
        lateral: Lateral direction there, shape (3,).
    """
    base = float(model.deflection(q, wrench)[:3] @ lateral)
    best, best_d = "tilting_compliance:j1", -1.0
    for j in range(model.robot.nq):
        label = f"tilting_compliance:j{j + 1}"
        if model.has(label):
            continue
        d = abs(float(model.with_effect(label).deflection(q, wrench)[:3] @ lateral) - base)
        if d > best_d:
            best, best_d = label, d
    return best, None


def _run_scenario(
    name: str,
    description: str,
    weld: VirtualWeld,
    paths: dict[str, NominalPath],
    options: CompareOptions,
    window: WeldWindow,
    bar: Bar | None = None,
) -> Scenario:
    runs: dict[str, WeldRun] = {}
    inputs = {k: weld.controller_inputs(p) for k, p in paths.items()}
    for s in options.strategies:
        key = "plan" if s in PLANNED else "taught"
        if bar is not None:
            bar.set_description(f"compare {name}: {s}")
        runs[s] = weld.run(options.make_strategy(s), paths[key], label=s, inputs=inputs[key])
        if bar is not None:
            bar.update(1)
    metrics = {k: weld_metrics(r, window) for k, r in runs.items()}
    normal = {k: normal_error(weld, r) for k, r in runs.items()}
    return Scenario(name, description, metrics, runs, normal)


def consistency_check(
    problem: Problem, model: ElastostaticModel, frames: SeamFrames, q_taught: FloatArray,
    schedule: LoadSchedule, cycle_s: float,
) -> Consistency:
    """Run ``none`` without noise and drift and compare with the deviation prediction."""
    from rfsw_plan.process.deviation import predict_deviation

    dev = predict_deviation(model, frames, problem.process, q_taught, problem.window)
    cfg = SimConfig(
        cycle_s=cycle_s, sensor=SensorModel(noise_force_N=0.0, noise_moment_Nm=0.0),
        variation=ProcessVariation(amplitude=0.0),
    )
    vw = VirtualWeld(schedule, model, None, cfg, problem.seam_reference)
    run = vw.run(NoCompensation(), vw.path_from_waypoints(frames.s - frames.s[0], q_taught))
    wt = dev.schedule.mask("weld")
    e_sim = np.interp(dev.schedule.t[wt], run.t, run.lateral_error)
    return Consistency(
        simulator_max_abs_lateral=float(np.max(np.abs(run.lateral_error[run.weld]))),
        deviation_max_abs_lateral=dev.max_abs_lateral,
        deviation_time_max_abs_lateral=float(np.max(np.abs(dev.lateral_t[wt]))),
        max_time_difference=float(np.max(np.abs(e_sim - dev.lateral_t[wt]))),
    )


# -- the comparison -------------------------------------------------------------------------
def compare(
    problem: Problem,
    options: CompareOptions | None = None,
    planner: Planner | None = None,
) -> CompareResult:
    """Run every strategy on the same virtual weld, plus the sensitivity reruns.

    Args:
        problem: The welding problem.
        options: Settings (defaults: all strategies, 4 ms cycle, sensitivity on).
        planner: Offline planner (default :func:`default_planner`); only called when
            ``offline`` or ``hybrid`` is requested.

    Raises:
        UnknownNameError: Unknown strategy or effect.
        InputError: Non-positive cycle, filter window longer than the weld, bad effect
            parameters.
        UnreachableError: The taught seam is unreachable.
    """
    opts = options or CompareOptions()
    robot = load_robot(problem.robot)
    model = ElastostaticModel(robot)
    frames = problem.frames()
    weld_duration = float(frames.s[-1] - frames.s[0]) / problem.process.travel_speed
    check_filter_fits(opts, weld_duration)
    # Validate the truth before the (slow) plan.
    truth_main = truth_model(model, opts.truth_stiffness_scale, opts.truth_effects)
    if opts.hidden_effect is not None:
        truth_model(model, 1.0, (opts.hidden_effect,))
    schedule = problem.process.schedule(frames, opts.cycle_s)
    q_taught = taught_path(robot, frames, problem.q_seed(), problem.planning.tool_rotation)
    notes: list[str] = []
    wp: PlannedWaypoints | None = None
    strategies = opts.strategies
    if any(s in PLANNED for s in strategies):
        try:
            wp = (planner or default_planner)(problem)
        except InfeasibleError as exc:
            notes.append(f"offline plan infeasible, offline and hybrid skipped: {exc}")
            strategies = tuple(s for s in strategies if s not in PLANNED)
            if not strategies:
                raise
            opts = replace(opts, strategies=strategies)
    tic = time.perf_counter()
    cfg = SimConfig(cycle_s=opts.cycle_s, sensor=opts.sensor, variation=opts.variation)
    weld_main = VirtualWeld(schedule, model, truth_main, cfg, problem.seam_reference)
    paths = {"taught": weld_main.path_from_waypoints(frames.s - frames.s[0], q_taught)}
    if wp is not None:
        paths["plan"] = planned_path(weld_main, wp)
    desc = "truth = model" if truth_main is model or (
        opts.truth_stiffness_scale == 1.0 and not opts.truth_effects) else (
        f"truth stiffness x{opts.truth_stiffness_scale:g}"
        + "".join(f" + {e[0]}" for e in opts.truth_effects))
    n_scenarios = 4 if opts.sensitivity else 1  # main, stiffness, hidden effect, noise
    with Bar(len(opts.strategies) * n_scenarios, "compare", unit="weld") as bar:
        main, scenarios = _run_scenarios(problem, opts, model, truth_main, frames, q_taught,
                                         schedule, cfg, weld_main, paths, desc, notes, bar)
    sim_time = time.perf_counter() - tic
    cons = consistency_check(problem, model, frames, q_taught, schedule, opts.cycle_s)
    return CompareResult(
        problem=problem.name, window=problem.window, options=opts, main=main,
        sensitivity=tuple(scenarios), consistency=cons,
        plan_time_s=wp.solve_time_s if wp is not None else 0.0, sim_time_s=sim_time,
        weld_duration_s=weld_duration, n_cycles=len(weld_main.t), notes=tuple(notes),
    )


def _run_scenarios(
    problem: Problem, opts: CompareOptions, model: ElastostaticModel,
    truth_main: ElastostaticModel, frames: Any, q_taught: FloatArray, schedule: Any,
    cfg: SimConfig, weld_main: VirtualWeld, paths: dict[str, NominalPath], desc: str,
    notes: list[str], bar: Bar,
) -> tuple[Scenario, list[Scenario]]:
    """The main scenario and, with ``opts.sensitivity``, the stiffness, hidden-effect and
    noise reruns (each runs every strategy; ``bar`` advances by one per weld)."""
    main = _run_scenario("main", desc, weld_main, paths, opts, problem.window, bar)
    scenarios: list[Scenario] = []
    if not opts.sensitivity:
        return main, scenarios
    k = opts.sensitivity_stiffness_scale
    t_soft = truth_model(model, k * opts.truth_stiffness_scale, opts.truth_effects)
    scenarios.append(_run_scenario(
        f"stiffness_{(k - 1) * 100:+.0f}%", f"truth joint stiffness x{k:g} of the model",
        VirtualWeld(schedule, model, t_soft, cfg, problem.seam_reference), paths, opts,
        problem.window, bar))
    mid = len(frames) // 2
    weld_idx = np.flatnonzero(schedule.mask("weld"))
    i_mid = weld_idx[np.argmin(np.abs(schedule.s[weld_idx] - (frames.s[mid] - frames.s[0])))]
    wmid = schedule.wrench_base[i_mid]
    hidden = opts.hidden_effect or pick_hidden_effect(
        model, q_taught[mid], wmid, frames.l[mid])
    if truth_main.has(hidden[0]):
        notes.append(f"hidden effect {hidden[0]} is already in the main truth; skipped")
    else:
        t_hid = truth_model(model, opts.truth_stiffness_scale,
                            (*opts.truth_effects, hidden))
        scenarios.append(_run_scenario(
            f"hidden_{hidden[0]}", f"truth has {hidden[0]} (model does not)",
            VirtualWeld(schedule, model, t_hid, cfg, problem.seam_reference), paths, opts,
            problem.window, bar))
    f = opts.noise_factor
    cfg_noise = replace(cfg, sensor=opts.sensor.scaled_noise(f))
    scenarios.append(_run_scenario(
        f"noise_x{f:g}", f"sensor noise x{f:g}",
        VirtualWeld(schedule, model, truth_main, cfg_noise, problem.seam_reference), paths,
        opts, problem.window, bar))
    return main, scenarios


# -- presentation ---------------------------------------------------------------------------
def _mae_text(sc: Scenario, name: str) -> str:
    n = sc.normal.get(name)
    return f"{n.mae * 1e3:.3f}" if n is not None else "-"


def format_table(result: CompareResult) -> str:
    """Plain-text table of every scenario and strategy."""
    lines = [
        f"problem {result.problem}: window [{result.window.lower * 1e3:g}, "
        f"{result.window.upper * 1e3:g}] mm, weld {result.weld_duration_s:.1f} s, "
        f"{result.n_cycles} cycles of {result.options.cycle_s * 1e3:g} ms",
    ]
    head = (f"  {'strategy':<18}{'inside %':>9}{'max|e| mm':>11}{'rms mm':>9}{'settle mm':>11}"
            f"{'MAE_n mm':>10}")
    for sc in (result.main, *result.sensitivity):
        lines.append(f"{sc.name} ({sc.description}):")
        lines.append(head)
        for name, m in sc.metrics.items():
            lines.append(
                f"  {name:<18}{m.inside_window_fraction * 100:>9.1f}"
                f"{m.max_abs_lateral * 1e3:>11.2f}{m.rms_lateral * 1e3:>9.2f}"
                f"{m.settling_text():>11}{_mae_text(sc, name):>10}"
            )
        dcs = {k: m.direction_change for k, m in sc.metrics.items() if m.direction_change}
        if dcs:
            lines.append("  at the change of travel direction (max|e| mm, inside %):")
            for k, d in dcs.items():
                lines.append(f"    {k:<18}{d.max_abs_lateral * 1e3:>8.2f}"
                             f"{d.inside_window_fraction * 100:>8.1f}")
    if result.consistency is not None:
        c = result.consistency
        lines.append(
            f"simulator vs deviation (none, no noise/drift): max|e| "
            f"{c.simulator_max_abs_lateral * 1e3:.3f} vs {c.deviation_max_abs_lateral * 1e3:.3f}"
            f" mm ({c.relative_difference * 100:.2f} %)"
        )
    lines.append(f"plan {result.plan_time_s:.2f} s, simulation {result.sim_time_s:.3f} s")
    lines.extend(f"note: {n}" for n in result.notes)
    return "\n".join(lines)


def format_markdown(result: CompareResult) -> str:
    """Markdown report (compare.md); numbers through :mod:`rfsw_plan.numfmt`, no wall time."""
    out = [f"# Compensation comparison: {result.problem}", ""]
    w, o = result.window, result.options
    out.append(
        f"Weld window [{general(w.lower * 1e3)}, {general(w.upper * 1e3)}] mm; weld "
        f"{fixed(result.weld_duration_s, 1)} s; controller cycle {general(o.cycle_s * 1e3)} ms;"
        f" sensor {general(o.sensor.rate_hz)} Hz, delay "
        f"{general(o.sensor.delay_s * 1e3)} ms, noise {general(o.sensor.noise_force_N)}"
        f" N; force drift +-{general(o.variation.amplitude * 100)} %."
    )
    for sc in (result.main, *result.sensitivity):
        out += ["", f"## {sc.name}: {sc.description}", "",
                "| strategy | inside window [%] | max abs lateral [mm] | RMS [mm] "
                "| settling [mm] | MAE along the normal [mm] |",
                "|---|---:|---:|---:|---:|---:|"]
        for name, m in sc.metrics.items():
            out.append(
                f"| {name} | {fixed(m.inside_window_fraction * 100, 1)} | "
                f"{fixed(m.max_abs_lateral * 1e3, 2)} | {fixed(m.rms_lateral * 1e3, 2)} | "
                f"{m.settling_text()} | {_mae_text(sc, name)} |"
            )
    if result.consistency is not None:
        c = result.consistency
        out += ["", f"Simulator (`none`, no noise or drift) vs `deviation`: max abs lateral "
                f"{fixed(c.simulator_max_abs_lateral * 1e3, 3)} mm vs "
                f"{fixed(c.deviation_max_abs_lateral * 1e3, 3)} mm "
                f"({fixed(c.relative_difference * 100, 2)} % apart)."]
    out += [f"- {n}" for n in result.notes]
    return "\n".join(out) + "\n"


def plot_lateral(result: CompareResult, path: str | Path) -> None:
    """PNG (written atomically) of the lateral error against seam position, all strategies,
    with the window band.

    Top: the whole weld; bottom: the weld start (first 10 % or 20 mm), where the real-time
    strategies settle.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(9, 7.5))
    w = result.window
    L = max(r.s[r.weld][-1] - r.s[r.weld][0] for r in result.main.runs.values())
    zoom = max(0.1 * L, min(20e-3, L))
    for ax, xmax in zip(axes, (L, zoom), strict=True):
        for name, run in result.main.runs.items():
            m = run.weld
            s = run.s[m] - run.s[m][0]
            keep = s <= xmax
            ax.plot(s[keep] * 1e3, run.lateral_error[m][keep] * 1e3, label=name, lw=1.0)
        ax.axhspan(w.lower * 1e3, w.upper * 1e3, color="tab:green", alpha=0.15,
                   label="weld window")
        ax.set_xlabel("seam position from weld start [mm]")
        ax.set_ylabel("lateral pin error [mm]\n(+ advancing side)")
        ax.grid(True, alpha=0.3)
    axes[0].set_title(f"{result.problem}: {result.main.description}")
    axes[1].set_title("weld start")
    axes[0].legend(loc="best", fontsize=8)
    fig.tight_layout()
    write_figure(path, fig, dpi=110)
    plt.close(fig)


def parse_effect_arg(text: str) -> tuple[str, dict[str, float] | None]:
    """Parse ``NAME[=key=value,...]`` (or ``key:value``) into an effect label and parameters.

    Example: ``tilting_compliance:j3=c_t1=2e-7,c_t2=2e-7``; parameters in SI units.

    Raises:
        InputError: A parameter that is not ``key=number``.
    """
    name, _, rest = text.partition("=")
    name = name.strip()
    if not name:
        raise InputError("truth_effect", text, "no effect name", "NAME[=key=value,...]")
    if not rest.strip():
        return name, None
    params: dict[str, float] = {}
    for item in rest.split(","):
        cut = min((i for i in (item.find("="), item.find(":")) if i >= 0), default=-1)
        try:
            if cut < 0:
                raise ValueError
            params[item[:cut].strip()] = float(item[cut + 1:])
        except ValueError:
            raise InputError("truth_effect", text, f"bad parameter '{item}'",
                             "NAME[=key=value,...] with numeric values (SI)") from None
    return name, params


__all__ = [
    "PLANNED",
    "STRATEGIES",
    "CompareOptions",
    "CompareResult",
    "Consistency",
    "NormalError",
    "PlannedWaypoints",
    "Scenario",
    "check_filter_fits",
    "compare",
    "default_planner",
    "format_markdown",
    "format_table",
    "normal_error",
    "parse_effect_arg",
    "pick_hidden_effect",
    "planned_path",
    "planned_waypoints",
    "plot_lateral",
]
