"""Joint-stiffness identification (seed 000 eq. 13-15): truth recovery and honest uncertainty."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.elastostatics.effects import JointCompliance
from rfsw_plan.elastostatics.identification import axis_variances, identify, residuals, rms
from rfsw_plan.elastostatics.model import ElastostaticModel, load_model
from rfsw_plan.exceptions import IdentificationError
from rfsw_plan.io.measurements import MeasurementSet
from rfsw_plan.robot.kinematics import Robot


def truth_model(robot: Robot, seed: int) -> tuple[ElastostaticModel, np.ndarray]:
    """A joint-compliance model whose stiffness differs from the robot file by 0.5x..2x."""
    rng = np.random.default_rng(seed)
    k_true = robot.stiffness * rng.uniform(0.5, 2.0, robot.nq)
    params = {f"c{j + 1}": 1.0 / k for j, k in enumerate(k_true)}
    return ElastostaticModel(robot, [JointCompliance(robot, None, params)]), k_true


def synthetic(
    model: ElastostaticModel, m: int, seed: int, noise_m: float = 0.0, sigma_col: bool = False
) -> MeasurementSet:
    """m loaded poses in the middle of the joint ranges, forces ~3 kN, measured positions."""
    rng = np.random.default_rng(seed)
    d = model.robot.description
    mid, half = (d.lower + d.upper) / 2, (d.upper - d.lower) / 2
    Q = rng.uniform(mid - 0.5 * half, mid + 0.5 * half, size=(m, model.robot.nq))
    F = np.zeros((m, 6))
    F[:, :3] = rng.normal(size=(m, 3)) * 3000.0
    pos = model.predict_position(Q, F) + rng.normal(size=(m, 3)) * noise_m
    sigma = np.full(m, noise_m) if sigma_col else None
    return MeasurementSet(Q, F, pos, sigma=sigma, source="synthetic")


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_noise_free_returns_truth(method: str) -> None:
    prior = load_model("zk500")
    truth, k_true = truth_model(prior.robot, seed=1)
    data = synthetic(truth, 30, seed=2)
    res = identify(prior, data, method=method)  # type: ignore[arg-type]
    ident = res.joint_identified
    assert ident[:5].all()
    np.testing.assert_allclose(res.stiffness[ident], k_true[ident], rtol=1e-6)
    assert res.rms_after < 1e-12 < res.rms_before
    assert np.isfinite(res.condition_number) and res.condition_number >= 1.0
    assert res.method == method
    # The returned model predicts the data.
    assert rms(residuals(res.model, data)) < 1e-12


def test_wls_with_sigma_column_returns_truth() -> None:
    prior = load_model("zk500")
    truth, k_true = truth_model(prior.robot, seed=3)
    data = synthetic(truth, 30, seed=4)
    data = MeasurementSet(data.q, data.wrench, data.position,
                          sigma=np.linspace(1e-5, 5e-5, 30), source="synthetic")
    res = identify(prior, data, method="wls")
    np.testing.assert_allclose(res.stiffness[:5], k_true[:5], rtol=1e-6)


def test_joint6_is_unidentifiable_from_positions_and_keeps_prior() -> None:
    prior = load_model("zk500")
    truth, _ = truth_model(prior.robot, seed=5)
    res = identify(prior, synthetic(truth, 30, seed=6))
    assert not res.joint_identified[5]
    assert res.stiffness[5] == pytest.approx(prior.stiffness[5], rel=1e-12)
    assert np.isnan(res.stiffness_std[5])
    (est,) = [e for e in res.unidentified() if e.name == "c6"]
    assert est.effect == "joint_compliance"
    assert "does not move the measured TCP" in est.note
    assert [e.name for e in res.unidentified()] == ["c6"]


def test_noisy_data_truth_within_reported_uncertainty() -> None:
    """|error| < 4 sigma for every identified joint, and the z-scores have unit variance."""
    prior = load_model("zk500")
    z: list[float] = []
    for seed in range(20):
        truth, k_true = truth_model(prior.robot, seed=100 + seed)
        data = synthetic(truth, 40, seed=200 + seed, noise_m=2e-5)  # 20 um noise
        res = identify(prior, data)
        ident = res.joint_identified
        err = np.abs(res.stiffness - k_true)[ident]
        assert np.all(err < 4.0 * res.stiffness_std[ident]), (seed, err / res.stiffness_std[ident])
        c_true = 1.0 / k_true
        for j, e in enumerate(res.estimates):
            if e.identified:
                z.append((e.value - c_true[j]) / e.std_error)
        assert res.sigma == pytest.approx(2e-5, rel=0.3)
        assert res.rms_after < res.rms_before
    zs = np.asarray(z)
    assert zs.size == 20 * 5
    # chi^2 with 100 dof: mean of z^2 is 1 +- 0.14 (1 sigma); +-0.45 is > 3 sigma.
    assert 0.55 < float(np.mean(zs**2)) < 1.45
    assert abs(float(np.mean(zs))) < 0.4


def test_noisy_wls_feasible_gls_within_uncertainty() -> None:
    prior = load_model("zk500")
    truth, k_true = truth_model(prior.robot, seed=7)
    data = synthetic(truth, 60, seed=8, noise_m=2e-5)
    res = identify(prior, data, method="wls")
    ident = res.joint_identified
    assert np.all(np.abs(res.stiffness - k_true)[ident] < 4.0 * res.stiffness_std[ident])


def test_too_few_samples_raise() -> None:
    prior = load_model("zk500")
    data = synthetic(prior, 1, seed=9)  # 3 observations for 6 compliances
    with pytest.raises(IdentificationError, match="cannot identify 6 parameters"):
        identify(prior, data)


def test_no_measured_axis_and_wrong_joint_count_raise() -> None:
    prior = load_model("zk500")
    data = synthetic(prior, 10, seed=10)
    blank = MeasurementSet(data.q, data.wrench, np.full_like(data.position, np.nan))
    with pytest.raises(IdentificationError, match="no measured"):
        identify(prior, blank)
    short = MeasurementSet(data.q[:, :5], data.wrench, data.position)
    with pytest.raises(IdentificationError, match="5 joints"):
        identify(prior, short)


def test_partially_measured_axes_still_identify() -> None:
    """Blank cells (NaN) are skipped; x and z alone still identify joints 1-5."""
    prior = load_model("zk500")
    truth, k_true = truth_model(prior.robot, seed=11)
    data = synthetic(truth, 40, seed=12)
    pos = data.position.copy()
    pos[:, 1] = np.nan
    res = identify(prior, MeasurementSet(data.q, data.wrench, pos))
    assert res.n_observations == 80
    ident = res.joint_identified
    np.testing.assert_allclose(res.stiffness[ident], k_true[ident], rtol=1e-6)


def test_identified_stiffness_is_always_positive() -> None:
    """Data from another robot: every joint kept or identified is > 0 (re-checked each pass)."""
    zk = load_model("zk500")
    data = synthetic(zk, 30, seed=13, noise_m=2e-5)
    kuka = load_model("kuka_kr600_r2830")
    res = identify(kuka, data, free=["joint_compliance"])
    assert np.all(res.stiffness > 0)
    for e in res.estimates:
        assert e.value > 0, e
    assert any("not positive" in e.note for e in res.estimates)


def test_axis_variances_blank_and_exact_axes_get_finite_positive_values() -> None:
    res = np.array([[1e-5, 0.0, np.nan], [-3e-5, 0.0, np.nan], [np.nan, 0.0, np.nan]])
    var = axis_variances(res)
    np.testing.assert_allclose(var, [5e-10, 5e-10, 5e-10])  # x: (1 + 9)e-10 / 2
    np.testing.assert_array_equal(axis_variances(np.zeros((4, 3))), np.ones(3))
    np.testing.assert_array_equal(axis_variances(np.full((2, 3), np.nan)), np.ones(3))


@pytest.mark.filterwarnings("error")
def test_wls_without_sigma_on_an_exact_fit_keeps_equal_weights() -> None:
    """The prior is the truth: every residual is exactly zero, no division by zero."""
    prior = load_model("zk500")
    data = synthetic(prior, 30, seed=14)
    res = identify(prior, data, method="wls")
    ident = res.joint_identified
    assert ident[:5].all()
    np.testing.assert_allclose(res.stiffness[ident], prior.stiffness[ident], rtol=1e-9)
    assert np.all(np.isfinite(res.stiffness_std[ident]))
    assert res.rms_after < 1e-12


@pytest.mark.filterwarnings("error")
def test_wls_without_sigma_with_a_blank_axis_returns_truth() -> None:
    """A never-measured axis (y blank everywhere) gives no empty-slice mean in the weights."""
    prior = load_model("zk500")
    truth, k_true = truth_model(prior.robot, seed=15)
    data = synthetic(truth, 40, seed=16)
    pos = data.position.copy()
    pos[:, 1] = np.nan
    res = identify(prior, MeasurementSet(data.q, data.wrench, pos), method="wls")
    assert res.n_observations == 80
    ident = res.joint_identified
    np.testing.assert_allclose(res.stiffness[ident], k_true[ident], rtol=1e-6)
