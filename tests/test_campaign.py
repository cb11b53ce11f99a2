"""Simulated load campaigns: poses, loads, truth model, hidden effects, CLI."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.elastostatics.approach import approach_directions, load_changes
from rfsw_plan.elastostatics.effects import EFFECTS, PoseBatch
from rfsw_plan.elastostatics.identification import identify, residuals, rms
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError, UnknownNameError
from rfsw_plan.io.measurements import read_measurements
from rfsw_plan.robot.kinematics import load_robot
from rfsw_plan.validation.campaign.simulation import (
    AMBIENT_C,
    FORCE_RANGE_N,
    LIMIT_MARGIN_DEG,
    THERMAL_DRIFT,
    TOOL_DOWN_DEG,
    campaign_poses,
    campaign_wrenches,
    parse_hidden,
    run_campaign,
    simulate_campaign,
)

LIBRARY_HIDDEN = [
    "torque_dependent_stiffness:j2",
    "tilting_compliance:j3",
    "joint_backlash:j1",
    "payload_gravity",
    "sensor_misalignment",
    "force_sensor_bias",
    "kinematic_offsets",
]


def test_poses_look_like_a_load_campaign() -> None:
    robot = load_robot("fanuc_s900ib_400")
    data = simulate_campaign(robot, poses=30, loads_per_pose=4, noise_mm=0.0, seed=1)
    assert len(data) == 120 and data.n_joints == 6
    T, _ = robot.batch_fk_jacobian(data.q)
    tool_z = T[:, :3, 2]
    assert np.all(-tool_z[:, 2] >= np.cos(np.radians(TOOL_DOWN_DEG)) - 1e-12)  # tool down
    assert np.all(T[:, 0, 3] > 0.3)  # in front of the robot
    margin = np.radians(LIMIT_MARGIN_DEG) - 1e-9
    assert np.all(data.q >= robot.description.lower + margin)
    assert np.all(data.q <= robot.description.upper - margin)
    # every joint is varied across the campaign
    spread = np.degrees(np.ptp(data.q, axis=0))
    assert np.all(spread > 20.0), spread
    # pose ids and time stamps
    assert data.pose_id is not None and data.t is not None
    assert len(set(data.pose_id.tolist())) == 30
    assert np.all(np.diff(data.t) > 0)


def test_wrench_pattern_per_pose() -> None:
    W = campaign_wrenches(50, 7, np.random.default_rng(2)).reshape(50, 7, 6)
    # zero load read twice in a row (an adjacent repeat at the same load step), then loads
    assert np.all(W[:, 0] == 0) and np.all(W[:, 1] == 0)
    np.testing.assert_array_equal(W[:, 2], -W[:, 3])  # +W / -W pairs
    f = np.linalg.norm(W[:, 2:, :3], axis=2)
    assert np.all((f >= FORCE_RANGE_N[0]) & (f <= FORCE_RANGE_N[1]))
    assert campaign_wrenches(3, 1, np.random.default_rng(0)).shape == (3, 6)
    assert np.all(campaign_wrenches(3, 2, np.random.default_rng(0))[1::2] != 0)


def test_every_joint_torque_changes_sign_within_each_pose() -> None:
    robot = load_robot("zk500")
    data = simulate_campaign(robot, poses=10, loads_per_pose=6, noise_mm=0.0, seed=3)
    _, J = robot.batch_fk_jacobian(data.q)
    tau = np.einsum("mak,ma->mk", J, data.wrench).reshape(10, 6, 6)
    loaded = tau[:, 1:-1]
    assert np.all((loaded.max(axis=1) > 0) & (loaded.min(axis=1) < 0))


def test_noise_free_campaign_is_the_truth_model() -> None:
    res = run_campaign("zk500", [("payload_gravity", {"m": 150.0, "m_rz": -37.5})],
                       poses=8, loads_per_pose=5, noise_mm=0.0, seed=4)
    truth = res.truth
    assert truth.labels == ["joint_compliance", "payload_gravity"]
    assert res.hidden["payload_gravity"] == {"m": 150.0, "m_rx": 0.0, "m_ry": 0.0, "m_rz": -37.5}
    d = res.data
    np.testing.assert_allclose(d.position, truth.predict_position(d.q, d.wrench), atol=1e-15)
    # the base model misses the spindle weight even at zero load
    zero = np.all(d.wrench == 0, axis=1)
    base = ElastostaticModel(truth.robot)
    miss = d.position[zero] - base.predict_position(d.q[zero], d.wrench[zero])
    assert np.all(np.linalg.norm(miss, axis=1) > 1e-5)


def test_noise_level_and_reproducibility() -> None:
    a = run_campaign("zk500", [], poses=60, loads_per_pose=5, noise_mm=0.02, seed=5)
    b = simulate_campaign("zk500", [], poses=60, loads_per_pose=5, noise_mm=0.02, seed=5)
    np.testing.assert_array_equal(a.data.position, b.position)
    c = simulate_campaign("zk500", [], poses=60, loads_per_pose=5, noise_mm=0.02, seed=6)
    assert not np.allclose(a.data.q, c.q)
    r = a.data.position - a.truth.predict_position(a.data.q, a.data.wrench)
    assert np.std(r) * 1e3 == pytest.approx(0.02, rel=0.1)  # 900 samples: +-2.4 % 1-sigma
    assert a.hidden == {} and a.contribution_rms_mm == {}


@pytest.mark.parametrize("label", LIBRARY_HIDDEN)
def test_randomised_hidden_effect_is_visible_and_identifiable(label: str) -> None:
    """The hidden effect stands out of the noise, and fitting it brings the held-out error
    to the noise floor (what the validator's diagnosis relies on)."""
    noise = 0.01
    res = run_campaign("zk500", [(label, None)], poses=40, loads_per_pose=6, noise_mm=noise,
                       seed=7)
    assert res.contribution_rms_mm[label] >= 10 * noise * 0.99
    data = res.data
    assert data.pose_id is not None
    train = np.isin(data.pose_id, np.unique(data.pose_id)[:30])
    base = ElastostaticModel(res.truth.robot)
    before = identify(base, data.subset(train), free=["joint_compliance"]).model
    after = identify(base.with_effect(label), data.subset(train),
                     free=["joint_compliance", label]).model
    rms_before = rms(residuals(before, data.subset(~train))) * 1e3
    rms_after = rms(residuals(after, data.subset(~train))) * 1e3
    assert rms_after <= 1.2 * noise, (rms_before, rms_after)
    assert rms_before >= 1.5 * noise, (rms_before, rms_after)


@pytest.mark.parametrize("robot_name", ["zk500", "fanuc_s900ib_400", "kuka_kr600_r2830"])
def test_every_effect_draws_complete_finite_in_range_non_zero_plausible_params(
    robot_name: str
) -> None:
    """The effect contract's plausible_params, for every registered effect on every joint:
    all parameters, finite, physically possible, and an effect that is not a no-op on the
    campaign (a hidden effect of size zero would hide nothing)."""
    robot = load_robot(robot_name)
    rng = np.random.default_rng(3)
    q = np.repeat(campaign_poses(robot, 12, rng), 4, axis=0)
    wrench = campaign_wrenches(12, 4, rng)
    # With the samples' history, as run_campaign has it (approach, load changes at a pose).
    batch = PoseBatch.from_q(robot, q, approach_directions(q),
                             load_change=load_changes(q, wrench))
    for cls in EFFECTS.values():
        for joint in range(robot.nq) if cls.per_joint else [None]:
            eff = cls(robot, joint)
            params = eff.plausible_params(batch, wrench, rng)
            assert tuple(params) == eff.param_names(), eff.label
            for k, v in params.items():
                lo, hi = eff.param_range(k)
                assert np.isfinite(v) and lo <= v <= hi, (eff.label, k, v, lo, hi)
            theta = cls(robot, joint, params).params
            assert np.any(theta != 0), eff.label
            assert np.max(np.abs(eff.contribution(batch, wrench, theta))) > 0, eff.label


@pytest.mark.parametrize("label", ["device_registration", "marker_offset"])
def test_hidden_setup_effect_is_not_a_silent_no_op(label: str) -> None:
    """A randomised hidden registration error or marker offset moves the measured points
    (before the effect contract both had an all-zero prior and hid nothing)."""
    noise = 0.01
    res = run_campaign("zk500", [label], poses=20, loads_per_pose=4, noise_mm=noise, seed=4)
    assert any(v != 0 for v in res.hidden[label].values())
    assert res.contribution_rms_mm[label] >= 10 * noise * 0.99


def test_complementary_stiffness_keeps_its_physical_gain() -> None:
    res = run_campaign("fanuc_s900ib_400", ["complementary_stiffness"], poses=20,
                       loads_per_pose=4, noise_mm=0.001, seed=8)
    assert res.hidden["complementary_stiffness"] == {"gain": 1.0}
    assert res.contribution_rms_mm["complementary_stiffness"] > 0.01  # soft FANUC wrist


def test_thermal_drift_is_outside_the_library_and_follows_time() -> None:
    assert THERMAL_DRIFT not in EFFECTS
    res = run_campaign("zk500", [f"{THERMAL_DRIFT}=rate_mm_per_h:1.0,dir_x:0,dir_y:0,dir_z:1"],
                       poses=20, loads_per_pose=4, noise_mm=0.0, seed=9)
    d = res.data
    assert d.t is not None
    assert res.truth.labels == ["joint_compliance"]
    r = d.position - res.truth.predict_position(d.q, d.wrench)
    np.testing.assert_allclose(r[:, 2], 1e-3 * d.t / 3600.0, atol=1e-15)
    np.testing.assert_allclose(r[:, :2], 0.0, atol=1e-15)
    temp = d.extra["temperature_C"]
    assert np.corrcoef(temp, d.t)[0, 1] > 0.95  # 0.8 K rise against 0.05 K noise
    assert temp[-1] - temp[0] > 0.5
    # without the drift the temperature only cycles around the ambient value
    calm = simulate_campaign("zk500", [], poses=20, loads_per_pose=4, noise_mm=0.0, seed=9)
    assert np.all(np.abs(calm.extra["temperature_C"] - AMBIENT_C) < 0.5)


def test_two_hidden_effects() -> None:
    res = run_campaign("zk500", ["payload_gravity", "joint_backlash:j2=b:3e-4"], poses=10,
                       loads_per_pose=4, noise_mm=0.01, seed=10)
    assert res.truth.labels == ["joint_compliance", "payload_gravity", "joint_backlash:j2"]
    assert res.hidden["joint_backlash:j2"] == {"b": 3e-4}
    assert set(res.contribution_rms_mm) == {"payload_gravity", "joint_backlash:j2"}


def test_parse_hidden() -> None:
    assert parse_hidden("payload_gravity=m:150, m_rz:-37.5", 6) == (
        "payload_gravity", {"m": 150.0, "m_rz": -37.5})
    assert parse_hidden("joint_backlash:j2", 6) == ("joint_backlash:j2", None)
    assert parse_hidden("thermal_drift=rate_mm_per_h:0.5", 6) == (
        "thermal_drift", {"rate_mm_per_h": 0.5})
    with pytest.raises(UnknownNameError, match="thermal_drift"):
        parse_hidden("gear_wear", 6)
    with pytest.raises(InputError, match="out of range"):
        parse_hidden("joint_backlash:j7", 6)
    with pytest.raises(InputError, match="not a number"):
        parse_hidden("payload_gravity=m:heavy", 6)
    with pytest.raises(InputError, match="name:value"):
        parse_hidden("payload_gravity=m=150", 6)


def test_campaign_input_errors() -> None:
    with pytest.raises(InputError, match="more than once"):
        run_campaign("zk500", ["payload_gravity", "payload_gravity"], poses=2)
    with pytest.raises(InputError, match="already in the model"):
        run_campaign("kuka_kr600_r2830", ["tilting_compliance:j2"], poses=2)
    with pytest.raises(InputError, match="unknown parameter"):
        run_campaign("zk500", ["payload_gravity=mass:3"], poses=2)
    with pytest.raises(InputError, match="unknown parameter"):
        run_campaign("zk500", ["thermal_drift=speed:3"], poses=2)
    with pytest.raises(InputError):
        run_campaign("zk500", [], poses=0)
    with pytest.raises(InputError):
        run_campaign("zk500", [], poses=2, loads_per_pose=0)
    with pytest.raises(InputError):
        run_campaign("zk500", [], poses=2, noise_mm=-1.0)


def test_cli_writes_a_readable_measurement_file(tmp_path, capsys) -> None:
    out = tmp_path / "campaign.csv"
    truth = tmp_path / "truth.toml"
    code = main(["simulate-campaign", "--robot", "zk500", "--hidden",
                 "payload_gravity=m:120,m_rz:-30", "--hidden", "joint_backlash:j1",
                 "--poses", "6", "--loads-per-pose", "5", "--noise-mm", "0.01", "--seed", "3",
                 "-o", str(out), "--save-truth", str(truth)])
    assert code == 0
    text = capsys.readouterr().out
    assert "payload_gravity" in text and "joint_backlash:j1" in text
    data = read_measurements(out, n_joints=6)
    assert len(data) == 30 and "temperature_C" in data.extra
    ref = run_campaign("zk500", ["payload_gravity=m:120,m_rz:-30", "joint_backlash:j1"],
                       poses=6, loads_per_pose=5, noise_mm=0.01, seed=3)
    np.testing.assert_allclose(data.position, ref.data.position, atol=1e-8)  # 1e-6 mm in file
    np.testing.assert_allclose(data.q, ref.data.q, atol=1e-9)
    from rfsw_plan.elastostatics.model import load_model

    assert load_model(truth).labels == ref.truth.labels


@pytest.mark.parametrize("hidden, message", [
    ("warp_drive", "unknown hidden effect 'warp_drive'; known:"),
    ("torque_dependent_stiffness:j8", "out of range"),
])
def test_cli_bad_hidden_is_one_line(tmp_path, capsys, hidden: str, message: str) -> None:
    code = main(["simulate-campaign", "--robot", "zk500", "--hidden", hidden, "-o",
                 str(tmp_path / "x.csv")])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "x.csv").exists()
