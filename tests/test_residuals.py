"""Residual analysis: statistics, noise floor from repeats, feature tests, per-joint view."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError
from rfsw_plan.io.measurements import MeasurementSet
from rfsw_plan.validation.engine.residuals import (
    NoiseFloor,
    analyze_residuals,
    correlations,
    estimate_noise_floor,
    explained_share,
    repeat_groups,
    residual_features,
    scalar_basis,
)


def _data(model: ElastostaticModel, poses: int = 30, loads: int = 3, repeats: int = 2,
          noise: float = 2e-5, seed: int = 0,
          offset: Callable[[np.ndarray], np.ndarray] | None = None) -> MeasurementSet:
    """Poses x loads x repeats samples of the model plus noise (and an optional offset)."""
    rng = np.random.default_rng(seed)
    q = np.radians(np.column_stack([
        rng.uniform(-40, 40, poses), rng.uniform(-10, 35, poses), rng.uniform(-40, 20, poses),
        rng.uniform(-60, 60, poses), rng.uniform(60, 120, poses), rng.uniform(-90, 90, poses),
    ]))
    W = rng.normal(0, 2000.0, (poses, loads, 6))
    W[:, :, 3:] *= 0.05
    Q = np.repeat(q, loads * repeats, axis=0)
    F = np.repeat(W.reshape(poses * loads, 6), repeats, axis=0)
    pos = model.predict_position(Q, F) + rng.normal(0, noise, (len(Q), 3))
    t = np.arange(len(Q), dtype=np.float64) * 10.0
    if offset is not None:
        pos = pos + offset(t)
    pid = np.repeat(np.array([f"P{i}" for i in range(poses)]), loads * repeats)
    return MeasurementSet(Q, F, pos, t, pid, None, {"temperature_C": 20 + 1e-4 * t})


def test_repeat_groups_join_only_identical_pose_and_load(model: ElastostaticModel) -> None:
    d = _data(model, poses=5, loads=3, repeats=2)
    g = repeat_groups(d)
    assert g.shape == (30,)
    assert np.unique(g).size == 15
    assert np.all(g[0::2] == g[1::2])  # consecutive rows are the repeats


def test_noise_floor_from_repeats_recovers_the_noise(model: ElastostaticModel) -> None:
    sigma = 2e-5
    d = _data(model, poses=60, loads=3, repeats=3, noise=sigma, seed=1)
    res = d.position - model.predict_position(d.q, d.wrench)
    nf = estimate_noise_floor(d, res)
    assert nf.source == "repeats"
    assert nf.n_groups == 180
    assert nf.dof == 180 * 2 * 3
    assert nf.sigma == pytest.approx(sigma, rel=0.1)
    # Model error common to a group does not enter the repeat scatter.
    biased = res + np.repeat(np.random.default_rng(2).normal(0, 1e-3, (180, 3)), 3, axis=0)
    assert estimate_noise_floor(d, biased).sigma == pytest.approx(nf.sigma, rel=1e-9)


def test_given_noise_takes_precedence_and_bad_noise_is_rejected(model: ElastostaticModel
                                                                ) -> None:
    d = _data(model)
    res = d.position - model.predict_position(d.q, d.wrench)
    nf = estimate_noise_floor(d, res, 5e-5)
    assert (nf.source, nf.sigma, np.isinf(nf.dof)) == ("given", 5e-5, True)
    assert nf.repeats_sigma is not None
    with pytest.raises(InputError, match="noise"):
        estimate_noise_floor(d, res, -1.0)


def test_no_repeats_no_noise_gives_unknown_floor(model: ElastostaticModel) -> None:
    d = _data(model, repeats=1)
    res = d.position - model.predict_position(d.q, d.wrench)
    nf = estimate_noise_floor(d, res)
    assert nf.sigma is None and nf.source == "none" and not nf.known
    assert np.isnan(nf.above(1.0, 10))


def test_above_noise_p_values() -> None:
    nf = NoiseFloor(1e-5, "given", float("inf"))
    n = 600
    assert nf.above(n * (1e-5) ** 2, n) > 0.3  # exactly at the floor
    assert nf.above(n * (1.3e-5) ** 2, n) < 1e-6  # 30 % above with 600 values
    est = NoiseFloor(1e-5, "repeats", 20.0)  # an estimate on few dof is less conclusive
    assert est.above(n * (1.3e-5) ** 2, n) > nf.above(n * (1.3e-5) ** 2, n)


def test_explained_share_of_a_known_signal() -> None:
    rng = np.random.default_rng(4)
    x = rng.uniform(-1, 1, 2000)
    res = np.column_stack([0.5 * x**3, -x, np.full_like(x, np.nan)]) * 1e-4
    res[:, :2] += rng.normal(0, 1e-6, (2000, 2))
    r2, adj, p = explained_share(res, scalar_basis(x))
    assert r2 > 0.99 and adj > 0.99 and p < 1e-100
    r2n, _, pn = explained_share(res, scalar_basis(rng.uniform(size=2000)))
    assert r2n < 0.01 and pn > 1e-3


def test_drift_residual_points_at_time(model: ElastostaticModel) -> None:
    d = _data(model, offset=lambda t: np.outer(t / t.max(), [1e-4, 0, 2e-4]))
    batch = model.batch(d.q)
    tau = np.einsum("mak,ma->mk", batch.J, d.wrench)
    res = d.position - model.predict_position(d.q, d.wrench)
    corr = correlations(res, residual_features(d, batch.T[:, :3, 3], tau))
    assert corr[0].feature in ("time", "temperature_C")
    assert {c.feature for c in corr[:2]} == {"time", "temperature_C"}
    assert corr[0].significant and corr[0].r2 > 0.7
    # Noise alone correlates with nothing.
    clean = _data(model, seed=5)
    res0 = clean.position - model.predict_position(clean.q, clean.wrench)
    corr0 = correlations(res0, residual_features(clean, batch.T[:, :3, 3], tau))
    assert not any(c.significant for c in corr0)


def test_analysis_statistics_match_direct_computation(model: ElastostaticModel) -> None:
    d = _data(model, seed=6)
    pos = d.position.copy()
    pos[::7, 1] = np.nan  # some unmeasured cells
    d = MeasurementSet(d.q, d.wrench, pos, d.t, d.pose_id, None, d.extra)
    an = analyze_residuals(model, d)
    res = pos - model.predict_position(d.q, d.wrench)
    ok = np.isfinite(res)
    assert an.n_observations == int(ok.sum())
    assert an.rms == pytest.approx(np.sqrt(np.mean(res[ok] ** 2)))
    assert an.max_abs == pytest.approx(np.max(np.abs(res[ok])))
    assert an.percentiles[95.0] == pytest.approx(np.percentile(np.abs(res[ok]), 95))
    for a, st in enumerate(an.per_axis):
        v = res[:, a][np.isfinite(res[:, a])]
        assert st.n == v.size and st.rms == pytest.approx(np.sqrt(np.mean(v**2)))
    assert [s.name for s in an.per_direction] == ["along force", "across force"]
    assert len(an.per_joint) == 6
    js = an.to_json()
    assert js["rms_mm"] == pytest.approx(an.rms * 1e3)
    assert js["noise"]["source"] == "repeats"


def test_per_joint_breakdown_finds_extra_joint_motion(model: ElastostaticModel) -> None:
    d = _data(model, seed=7, noise=1e-6)
    batch = model.batch(d.q)
    tau = np.einsum("mak,ma->mk", batch.J, d.wrench)
    # Residual = joint 3 lost motion that follows the sign of its torque.
    res = batch.J[:, :3, 2] * (2e-5 * np.sign(tau[:, 2]))[:, None]
    res += np.random.default_rng(8).normal(0, 1e-6, res.shape)
    an = analyze_residuals(model, d, residual=res)
    shares = [j.r2_joint_motion for j in an.per_joint]
    assert int(np.argmax(shares)) == 2 and shares[2] > 0.95


def _cycle(model: ElastostaticModel, loads: list[float], poses: int = 60) -> MeasurementSet:
    """Per pose the load steps ``loads`` (x 3 kN along z) in time order; 0.03 mm noise, and a
    0.1 mm backlash step in every sample after the load cycle (the last zero load)."""
    rng = np.random.default_rng(4)
    q0 = np.radians([10.0, 20.0, -10.0, 30.0, 80.0, 0.0])
    W = np.array([0.0, 0, 3000, 0, 0, 0])
    F = np.array([s * W for _ in range(poses) for s in loads])
    Q = np.repeat(q0[None] + rng.normal(0, 0.2, (poses, 6)), len(loads), axis=0)
    after = np.array([k == len(loads) - 1 for _ in range(poses) for k in range(len(loads))])
    P = (model.predict_position(Q, F) + rng.normal(0, 3e-5, (len(F), 3))
         + 1e-4 * after[:, None])
    pid = np.repeat(np.array([f"P{i}" for i in range(poses)]), len(loads))
    return MeasurementSet(Q, F, P, np.arange(len(F)) * 1.0, pid)


def test_zero_load_readings_of_a_load_cycle_are_not_pooled(model: ElastostaticModel) -> None:
    # 0, +W, -W, 0: the two zero loads bracket a load cycle (different hysteresis states)
    # and are not repeats: no floor rather than an inflated one.
    d = _cycle(model, [0.0, 1.0, -1.0, 0.0])
    assert estimate_noise_floor(d, d.position - model.predict_position(d.q, d.wrench)
                                ).sigma is None
    # 0, 0, +W, -W, 0: the adjacent pair is a repeat; the floor is the true 0.03 mm.
    d = _cycle(model, [0.0, 0.0, 1.0, -1.0, 0.0])
    nf = estimate_noise_floor(d, d.position - model.predict_position(d.q, d.wrench))
    assert nf.source == "repeats" and nf.n_groups == 60
    assert nf.sigma == pytest.approx(3e-5, rel=0.15)


def test_force_noise_is_part_of_the_floor(model: ElastostaticModel) -> None:
    d = _data(model, poses=20, loads=3, repeats=1)
    res = d.position - model.predict_position(d.q, d.wrench)
    nf = estimate_noise_floor(d, res, 1e-5, model=model, force_noise_n=5.0)
    assert nf.device_sigma == 1e-5 and nf.force_sigma is not None and nf.force_sigma > 0
    assert nf.sigma == pytest.approx(np.hypot(1e-5, nf.force_sigma))
    assert nf.force_noise_source == "given"
