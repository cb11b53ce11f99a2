"""Real-time strategies: seed 000 averaging, seed 002 MAF + self-incrementing PID, hybrid."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.exceptions import InputError
from rfsw_plan.realtime.base import ControllerInputs, NoCompensation
from rfsw_plan.realtime.capped_pid import FilteredCappedPID
from rfsw_plan.realtime.force_feedback import (
    ExponentialAverageCompensation,
    ForceFeedbackFilteredCorrection,
)
from rfsw_plan.realtime.hybrid import HybridResidual
from rfsw_plan.realtime.simulator import WeldRun

DT = 0.004


def make_inputs(
    K: int = 1500,
    k_on: int = 100,
    step: tuple[float, float, float] = (1e-3, 5e-3, -2e-3),
    noise: float = 0.0,
    planned: tuple[float, float, float] = (0.0, 0.0, 0.0),
    seed: int = 1,
) -> ControllerInputs:
    """Synthetic controller inputs: model deflection jumps to ``step`` [m] at cycle k_on/2.

    Lateral direction +y, travel +x; the compensation is active from k_on on.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(K, dtype=np.float64) * DT
    phase = np.where(np.arange(K) < k_on, "dwell", "weld")
    dX = np.zeros((K, 6))
    dX[k_on // 2:, :3] = step
    dX[:, :3] += noise * rng.standard_normal((K, 3))
    dXp = np.zeros((K, 6))
    dXp[:, :3] = planned
    lat = np.tile([0.0, 1.0, 0.0], (K, 1))
    return ControllerInputs(
        t=t, dt=DT, phase=phase, active=phase == "weld", s=np.zeros(K), lateral=lat,
        q=np.zeros((K, 6)), jacobian=np.zeros((K, 6, 6)), force_measured=np.zeros((K, 6)),
        force_planned=np.zeros((K, 6)), model_deflection=dX, model_deflection_planned=dXp,
    )


def loop(strategy: ExponentialAverageCompensation, inputs: ControllerInputs) -> np.ndarray:
    strategy.reset(inputs)
    return np.array([strategy.step(k, inputs) for k in range(len(inputs))])


@pytest.mark.parametrize("update", [None, 0.02, 0.25])
@pytest.mark.parametrize("percent", [0.0, 50.0, 90.0])
def test_seed000_vectorised_run_equals_step_loop(update: float | None, percent: float) -> None:
    inp = make_inputs(noise=2e-4)
    st = ForceFeedbackFilteredCorrection(percent, update)
    np.testing.assert_allclose(st.run(inp),
                               loop(ForceFeedbackFilteredCorrection(percent, update), inp),
                               atol=1e-15)


def test_seed000_is_lateral_only_and_converges_to_minus_model_lateral() -> None:
    inp = make_inputs()
    corr = ForceFeedbackFilteredCorrection(50.0, None).run(inp)
    assert np.all(corr[:, [0, 2]] == 0.0)  # travel and normal untouched
    assert np.all(corr[:100] == 0.0)  # inactive before the weld
    np.testing.assert_allclose(corr[-1], [0.0, -5e-3, 0.0], atol=1e-12)


def test_seed000_average_halves_the_gap_per_update() -> None:
    """50 %: after j updates the remaining gap is 0.5^j of the step (exponential average)."""
    inp = make_inputs()
    corr = ForceFeedbackFilteredCorrection(50.0, None).run(inp)[:, 1]
    gap = corr[100:110] + 5e-3
    np.testing.assert_allclose(gap, 5e-3 * 0.5 ** np.arange(1, 11), rtol=1e-12)


def test_seed000_slower_update_settles_later() -> None:
    inp = make_inputs()
    fast = ForceFeedbackFilteredCorrection(50.0, None).run(inp)[:, 1]
    slow = ForceFeedbackFilteredCorrection(50.0, 0.25).run(inp)[:, 1]
    k_fast = np.argmax(np.abs(fast + 5e-3) < 0.1e-3)
    k_slow = np.argmax(np.abs(slow + 5e-3) < 0.1e-3)
    assert k_slow > k_fast + 100  # > 0.4 s later
    # Held between updates: piecewise constant with steps every 0.25 s / 4 ms ~ 62 cycles.
    changes = np.flatnonzero(np.diff(slow) != 0)
    assert np.all(np.diff(changes) >= 62)


def test_seed000_averaging_reduces_noise() -> None:
    inp = make_inputs(noise=0.3e-3)
    raw = ForceFeedbackFilteredCorrection(0.0, None).run(inp)[800:, 1]
    avg = ForceFeedbackFilteredCorrection(50.0, None).run(inp)[800:, 1]
    # Exponential average with a = 0.5 divides the white-noise variance by (1+a)/(1-a) = 3.
    ratio = np.var(avg) / np.var(raw)
    assert 0.25 < ratio < 0.42


@pytest.mark.parametrize("percent", [-1.0, 100.0, 150.0])
def test_seed000_rejects_bad_percentage(percent: float) -> None:
    with pytest.raises(InputError, match="average_percent"):
        ForceFeedbackFilteredCorrection(percent)


def test_seed000_rejects_bad_update_period() -> None:
    with pytest.raises(InputError, match="update_period_s"):
        ForceFeedbackFilteredCorrection(50.0, 0.0)


def test_seed002_converges_in_every_direction_without_overshoot() -> None:
    inp = make_inputs(K=2000)
    xa = FilteredCappedPID().run(inp)
    np.testing.assert_allclose(xa[-1], [-1e-3, -5e-3, 2e-3], atol=2e-6)
    # Direction y moves monotonically toward -5 mm (no overshoot beyond 2 %).
    assert np.min(xa[:, 1]) > -5e-3 * 1.02
    assert np.all(xa[:100] == 0.0)


def test_seed002_increment_is_capped() -> None:
    inp = make_inputs(K=600, step=(0.0, 50e-3, 0.0))
    st = FilteredCappedPID(max_rate=10e-3)
    xa = st.run(inp)[:, 1]
    assert np.max(np.abs(np.diff(xa))) <= 10e-3 * DT * (1 + 1e-9)
    # A big error saturates the rate: the cap is actually reached.
    assert np.max(np.abs(np.diff(xa))) > 0.99 * 10e-3 * DT


def test_seed002_moving_average_delays_the_response() -> None:
    """A longer MAF reacts later to the same step (320 vs 32 samples)."""
    inp = make_inputs(K=800, k_on=10, step=(0.0, 5e-3, 0.0))
    long = FilteredCappedPID(maf_samples=320).run(inp)[:, 1]
    short = FilteredCappedPID(maf_samples=32).run(inp)[:, 1]
    k_long = np.argmax(long < -2.5e-3)
    k_short = np.argmax(short < -2.5e-3)
    assert k_long > k_short


def test_seed002_filter_longer_than_weld_is_rejected() -> None:
    inp = make_inputs(K=120, k_on=100)  # 20 active cycles = 80 ms < 160 ms
    with pytest.raises(InputError, match="longer than the weld"):
        FilteredCappedPID().run(inp)


@pytest.mark.parametrize("kw", [{"algorithm_step_s": 0.0}, {"maf_samples": 0},
                                {"max_rate": -1.0}, {"derivative_filter": 0.0}])
def test_seed002_rejects_bad_parameters(kw: dict[str, float]) -> None:
    with pytest.raises(InputError):
        FilteredCappedPID(**kw)  # type: ignore[arg-type]


def test_hybrid_corrects_only_the_residual() -> None:
    inp = make_inputs(step=(0.0, 5e-3, 0.0), planned=(0.0, 4e-3, 0.0))
    corr = HybridResidual(50.0).run(inp)
    # Residual at the end: 5 - 4 = 1 mm lateral -> correction -1 mm.
    np.testing.assert_allclose(corr[-1], [0.0, -1e-3, 0.0], atol=1e-12)
    same = make_inputs(step=(0.0, 4e-3, 0.0), planned=(0.0, 4e-3, 0.0))
    late = HybridResidual(50.0).run(same)[-500:]
    np.testing.assert_allclose(late, 0.0, atol=1e-15)


def test_no_compensation_is_zero() -> None:
    inp = make_inputs()
    assert np.all(NoCompensation().run(inp) == 0.0)
    assert np.all(NoCompensation().step(5, inp) == 0.0)


def _straight_run(e: np.ndarray) -> WeldRun:
    k = e.size
    s = np.linspace(0.0, 0.1, k)
    zeros = np.zeros((k, 3))
    travel = np.tile([1.0, 0.0, 0.0], (k, 1))
    return WeldRun(strategy="x", path="p", t=s / 3e-3, s=s, phase=np.full(k, "weld"),
                   lateral_error=e, pin=zeros, seam=zeros, travel=travel, correction=zeros,
                   sim_time_s=0.0)


def test_settling_distance_and_never_settled() -> None:
    from rfsw_plan.process.window import WeldWindow
    from rfsw_plan.realtime.metrics import weld_metrics

    e = np.where(np.linspace(0.0, 0.1, 101) < 0.02, 3e-3, 0.0)  # outside for the first 20 mm
    m = weld_metrics(_straight_run(e), WeldWindow())
    assert m.settled and m.settling == pytest.approx(0.02, abs=1.1e-3)
    assert m.settling_text() == f"{m.settling * 1e3:.1f}"
    never = weld_metrics(_straight_run(np.full(101, 3e-3)), WeldWindow())
    assert not never.settled and never.settling_text() == "never"
    assert never.to_dict()["settled"] is False
