"""Effects library: every regressor against central finite differences, the physics of each
effect against an independent formula, and identification of a hidden effect from noise-free
synthetic data."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.elastostatics.compliance import complementary_stiffness, deflection_with_kc
from rfsw_plan.elastostatics.effects import (
    EFFECTS,
    ComplianceEffect,
    Effect,
    GeometricEffect,
    PoseBatch,
    WrenchEffect,
    make_effect,
)
from rfsw_plan.elastostatics.effects.complementary_stiffness import batch_complementary_stiffness
from rfsw_plan.elastostatics.effects.joint_backlash import TAU_EPS_NM
from rfsw_plan.elastostatics.effects.payload_gravity import GRAVITY
from rfsw_plan.elastostatics.effects.sensor_misalignment import rotation_and_right_jacobian
from rfsw_plan.elastostatics.effects.torque_dependent_stiffness import TAU_REF_NM
from rfsw_plan.elastostatics.identification import identify
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError, UnknownNameError
from rfsw_plan.io.measurements import MeasurementSet
from rfsw_plan.robot.kinematics import Robot, load_robot

NEW_LABELS = [
    "complementary_stiffness",
    "torque_dependent_stiffness:j2",
    "joint_backlash:j1",
    "payload_gravity",
    "sensor_misalignment",
    "force_sensor_bias",
    "kinematic_offsets",
]

#: Non-trivial parameter values at which regressors are checked (and truths for identification).
TRUTH: dict[str, dict[str, float]] = {
    "complementary_stiffness": {"gain": 1.0},
    "torque_dependent_stiffness:j2": {"d2": 4e-4, "d3": -2e-4},
    "joint_backlash:j1": {"b": 3e-4},
    "payload_gravity": {"m": 140.0, "m_rx": 3.0, "m_ry": -4.0, "m_rz": -35.0},
    "sensor_misalignment": {"phi_x": 0.03, "phi_y": -0.02, "phi_z": 0.04},
    "force_sensor_bias": {
        "b_fx": 150.0, "b_fy": -120.0, "b_fz": 200.0, "b_mx": 15.0, "b_my": -10.0, "b_mz": 8.0,
    },
    "kinematic_offsets": {
        "dq1": 2e-4, "dq2": -3e-4, "dq3": 1.5e-4, "dq4": 4e-4, "dq5": -2e-4, "dq6": 0.0,
        "dt_x": 3e-4, "dt_y": -2e-4, "dt_z": 5e-4,
    },
}


def _campaign_like(robot: Robot, m: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Joint values around a tool-down pose and wrenches of both signs, some zero."""
    rng = np.random.default_rng(seed)
    q0 = np.radians([0.0, 10.0, 10.0, 0.0, 60.0, 0.0])
    span = np.radians([40.0, 20.0, 20.0, 60.0, 25.0, 90.0])
    q = q0 + rng.uniform(-1.0, 1.0, (m, robot.nq)) * span
    F = np.zeros((m, 6))
    F[:, :3] = rng.normal(size=(m, 3)) * 2500.0
    F[:, 3:] = rng.normal(size=(m, 3)) * 100.0
    F[::5] = 0.0  # zero-load samples
    return q, F


@pytest.fixture(scope="module")
def zk500() -> Robot:
    return load_robot("zk500")


@pytest.fixture(scope="module")
def fanuc() -> Robot:
    return load_robot("fanuc_s900ib_400")


def _central_difference(f, theta: np.ndarray, h: np.ndarray) -> np.ndarray:
    cols = []
    for k in range(theta.size):
        tp, tm = theta.copy(), theta.copy()
        tp[k] += h[k]
        tm[k] -= h[k]
        cols.append((f(tp) - f(tm)) / (2.0 * h[k]))
    return np.stack(cols, axis=-1)


def _contribution_and_regressor(eff: Effect, batch: PoseBatch, F: np.ndarray):
    return (lambda th: eff.contribution(batch, F, th),
            lambda th: eff.contribution_regressor(batch, F, th))


def test_registry_holds_the_issue_table() -> None:
    expected = {"joint_compliance", "tilting_compliance", *(x.split(":")[0] for x in NEW_LABELS)}
    assert expected <= set(EFFECTS)
    for name, cls in EFFECTS.items():
        assert cls.name == name
        bases = (ComplianceEffect, WrenchEffect, GeometricEffect)
        assert sum(issubclass(cls, b) for b in bases) == 1
        assert cls.description.endswith(".") and len(cls.description) > 30


def test_registry_errors(zk500: Robot) -> None:
    with pytest.raises(UnknownNameError, match="joint_backlash"):
        make_effect(zk500, "backlash:j1")
    with pytest.raises(InputError, match="out of range"):
        make_effect(zk500, "joint_backlash:j7")
    with pytest.raises(InputError, match="needs a joint"):
        make_effect(zk500, "torque_dependent_stiffness")
    with pytest.raises(InputError, match="takes no joint"):
        make_effect(zk500, "payload_gravity:j2")
    with pytest.raises(InputError, match="unknown parameter"):
        make_effect(zk500, "payload_gravity", {"mass": 3.0})


@pytest.mark.parametrize("robot_name", ["zk500", "fanuc_s900ib_400"])
@pytest.mark.parametrize("label", NEW_LABELS)
def test_regressor_matches_finite_differences(robot_name: str, label: str) -> None:
    robot = load_robot(robot_name)
    q, F = _campaign_like(robot, 12, seed=hash(label) % 1000)
    batch = PoseBatch.from_q(robot, q)
    eff = make_effect(robot, label, TRUTH[label])
    rng = np.random.default_rng(3)
    theta = eff.params * (1.0 + 0.3 * rng.uniform(-1, 1, eff.params.size))
    f, A = _contribution_and_regressor(eff, batch, F)
    h = 1e-6 * np.maximum(np.abs(theta), 1e-3)
    fd = _central_difference(f, theta, h)
    an = A(theta)
    assert an.shape == (len(batch), 6, theta.size)
    scale = np.max(np.abs(an)) + 1e-30
    np.testing.assert_allclose(an, fd, rtol=0, atol=1e-6 * scale)
    if eff.linear_in_params:
        np.testing.assert_allclose(
            f(theta), np.einsum("map,p->ma", an, theta), rtol=0,
            atol=1e-12 * np.max(np.abs(f(theta))) + 1e-18,
        )
    assert np.all(np.isfinite(f(eff.prior())))


@pytest.mark.parametrize("robot_name", ["zk500", "fanuc_s900ib_400"])
def test_batch_kc_matches_robot_jacobian_derivatives(robot_name: str) -> None:
    robot = load_robot(robot_name)
    q, F = _campaign_like(robot, 5, seed=1)
    Kc = batch_complementary_stiffness(PoseBatch.from_q(robot, q), F)
    for i in range(len(q)):
        want = complementary_stiffness(robot.jacobian_derivatives(q[i]), F[i])
        np.testing.assert_allclose(Kc[i], want, atol=1e-9 * np.max(np.abs(want)))


def test_batch_kc_matches_finite_differences(fanuc: Robot) -> None:
    """Kc column k = d(J^T F)/dq_k at fixed F (seed 000 eq. 6), coupled FANUC chain."""
    q, F = _campaign_like(fanuc, 1, seed=2)
    Kc = batch_complementary_stiffness(PoseBatch.from_q(fanuc, q), F)[0]
    h = 1e-6
    for k in range(fanuc.nq):
        e = np.zeros(fanuc.nq)
        e[k] = h
        fd = (fanuc.jacobian(q[0] + e).T @ F[0] - fanuc.jacobian(q[0] - e).T @ F[0]) / (2 * h)
        np.testing.assert_allclose(Kc[:, k], fd, atol=1e-6 * np.max(np.abs(Kc)))


def test_complementary_stiffness_is_seed_000_eq_6(fanuc: Robot) -> None:
    q, F = _campaign_like(fanuc, 5, seed=4)
    batch = PoseBatch.from_q(fanuc, q)
    eff = make_effect(fanuc, "complementary_stiffness")
    got = eff.deflection(batch, F, eff.params)
    Kq = np.diag(fanuc.stiffness)
    for i in range(len(q)):
        Kc = complementary_stiffness(fanuc.jacobian_derivatives(q[i]), F[i])
        J = batch.J[i]
        want = deflection_with_kc(J, Kq, Kc, F[i]) - J @ np.linalg.solve(Kq, J.T @ F[i])
        np.testing.assert_allclose(got[i], want, atol=1e-12)
    assert np.all(got[np.all(F == 0, axis=1)] == 0)


def test_torque_dependent_stiffness_moves_along_its_joint(zk500: Robot) -> None:
    q, F = _campaign_like(zk500, 6, seed=5)
    batch = PoseBatch.from_q(zk500, q)
    eff = make_effect(zk500, "torque_dependent_stiffness:j3", {"d2": 1e-3, "d3": 2e-3})
    s = np.einsum("ma,ma->m", batch.J[:, :, 2], F) / TAU_REF_NM
    dq = 1e-3 * s * np.abs(s) + 2e-3 * s**3
    np.testing.assert_allclose(eff.deflection(batch, F, eff.params), batch.J[:, :, 2] * dq[:, None])
    # odd in the torque: reversing the load reverses the deflection
    np.testing.assert_allclose(eff.deflection(batch, -F, eff.params),
                               -eff.deflection(batch, F, eff.params))


def test_joint_frames_left_to_their_first_use_are_the_frames_gathered_with_the_poses(
        zk500: Robot) -> None:
    """A batch made without its joint frames (a model none of whose effects reads them)
    gathers them on first use: the poses, Jacobians and frames are those of a batch that
    gathered them with the poses, bit for bit, and a batch of its rows takes its source's
    rows (issue 41). A model with a spring effect gathers them with the poses."""
    q, _ = _campaign_like(zk500, 300, seed=12)
    eager = PoseBatch.from_q(zk500, q)
    lazy = PoseBatch.from_q(zk500, q, frames=False)
    assert lazy._frames is None
    assert eager.T.tobytes() == lazy.T.tobytes() and eager.J.tobytes() == lazy.J.tobytes()
    idx = np.array([5, 3, 3, 250])
    part = lazy.rows(idx)
    assert part._frames is None and lazy._frames is None
    assert part.frames.tobytes() == eager.frames[idx].tobytes()
    assert lazy._frames is not None  # the source gathered its own once, for its rows
    assert lazy.frames.tobytes() == eager.frames.tobytes()
    assert lazy.rows(slice(2, 9)).frames.tobytes() == eager.frames[2:9].tobytes()
    joints = ElastostaticModel(zk500)
    assert not joints.reads_frames() and joints.batch(q)._frames is None
    tilting = ElastostaticModel(zk500, [*joints.effects, make_effect(zk500,
                                                                     "tilting_compliance:j2")])
    assert tilting.reads_frames() and tilting.batch(q)._frames is not None
    assert ElastostaticModel(zk500, [*joints.effects, make_effect(
        zk500, "link_errors")]).batch(q)._frames is not None


@pytest.mark.parametrize("params", [{"d2": 1e-3, "d3": -2e-3}, {"d2": 0.0, "d3": 7e-4},
                                    {"d2": -0.0, "d3": 0.0}])
def test_torque_dependent_deflection_is_its_regressor_times_its_parameters(zk500: Robot,
                                                                           params) -> None:
    """The deflection summed column by column is the regressor contracted with (d2, d3) by
    einsum, bit for bit (issue 41: the same products and sums without the (m, 6, 2) array),
    on many poses and loads, with zero and negative-zero parameters, loads and Jacobian
    entries (where the sign of a zero is the only difference einsum could show)."""
    q, F = _campaign_like(zk500, 400, seed=11)
    F[::7] = 0.0
    F[1::7] *= -1.0
    batch = PoseBatch.from_q(zk500, q)
    J = batch.J.copy()
    J[::5, 3:, 1] = 0.0
    J[1::5, 3:, 1] = -0.0
    batch = PoseBatch(zk500, batch.q, batch.T, J, batch.frames)
    eff = make_effect(zk500, "torque_dependent_stiffness:j2", params)
    theta = np.asarray(eff.params)
    want = np.einsum("map,p->ma", eff.deflection_regressor(batch, F, theta), theta)
    assert eff.deflection(batch, F, theta).tobytes() == want.tobytes()


def test_backlash_follows_torque_sign_and_needs_both_signs(zk500: Robot) -> None:
    q, F = _campaign_like(zk500, 40, seed=6)
    batch = PoseBatch.from_q(zk500, q)
    eff = make_effect(zk500, "joint_backlash:j2", {"b": 4e-4})
    tau = np.einsum("ma,ma->m", batch.J[:, :, 1], F)
    big = np.abs(tau) > 10 * TAU_EPS_NM
    dX = eff.deflection(batch, F, eff.params)
    # far from zero torque the joint sits at +-b/2
    np.testing.assert_allclose(dX[big], batch.J[big][:, :, 1] * (2e-4 * np.sign(tau[big]))[:, None],
                               rtol=1e-6, atol=1e-12)
    assert eff.identifiable(batch, F) is None
    one_sign = F * np.sign(tau)[:, None]  # flips each load so tau_2 >= 0
    msg = eff.identifiable(batch, one_sign)
    assert msg is not None and "joint 2" in msg and "sign" in msg


def test_payload_gravity_wrench(zk500: Robot) -> None:
    q, F = _campaign_like(zk500, 5, seed=7)
    batch = PoseBatch.from_q(zk500, q)
    m, r_c = 120.0, np.array([0.01, -0.02, -0.3])
    eff = make_effect(zk500, "payload_gravity",
                      {"m": m, "m_rx": m * r_c[0], "m_ry": m * r_c[1], "m_rz": m * r_c[2]})
    np.testing.assert_allclose(eff.centre_of_mass(), r_c)
    dF = eff.delta_wrench(batch, F, eff.params)
    f = np.array([0.0, 0.0, -m * GRAVITY])
    for i in range(len(q)):
        arm = batch.T[i, :3, :3] @ r_c  # TCP -> centre of mass, base frame
        np.testing.assert_allclose(dF[i], np.concatenate([f, np.cross(arm, f)]), atol=1e-9)
    # the model adds it to the logged wrench, so it deflects the robot at zero process force
    model = ElastostaticModel(zk500, [eff])
    dX = model.deflection(q, np.zeros((5, 6)))
    assert np.all(np.linalg.norm(dX[:, :3], axis=1) > 1e-5)


def test_sensor_misalignment_rotates_the_logged_wrench(zk500: Robot) -> None:
    q, F = _campaign_like(zk500, 5, seed=8)
    batch = PoseBatch.from_q(zk500, q)
    phi = np.array([0.05, -0.03, 0.02])
    eff = make_effect(zk500, "sensor_misalignment", dict(zip(eff_names := ("phi_x", "phi_y",
                      "phi_z"), phi, strict=True)))
    assert eff.param_names() == eff_names
    true = F + eff.delta_wrench(batch, F, eff.params)
    np.testing.assert_allclose(np.linalg.norm(true[:, :3], axis=1),
                               np.linalg.norm(F[:, :3], axis=1), rtol=1e-12)
    R, _ = rotation_and_right_jacobian(phi)
    for i in range(len(q)):
        Rt = batch.T[i, :3, :3]
        np.testing.assert_allclose(true[i, :3], Rt @ R @ Rt.T @ F[i, :3], atol=1e-9)
    # R is a proper rotation and its right Jacobian matches finite differences of Log
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_force_sensor_bias_sign(zk500: Robot) -> None:
    q, _ = _campaign_like(zk500, 3, seed=9)
    batch = PoseBatch.from_q(zk500, q)
    b = np.array([100.0, -50.0, 30.0, 5.0, -2.0, 1.0])
    eff = make_effect(zk500, "force_sensor_bias", dict(zip(
        ("b_fx", "b_fy", "b_fz", "b_mx", "b_my", "b_mz"), b, strict=True)))
    # the sensor reads the bias at zero true load: logged = B b, so true = logged + dF = 0
    logged = np.stack([np.concatenate([Rt @ b[:3], Rt @ b[3:]]) for Rt in batch.T[:, :3, :3]])
    np.testing.assert_allclose(logged + eff.delta_wrench(batch, logged, eff.params), 0.0,
                               atol=1e-12)


def test_kinematic_offsets_are_first_order_fk(fanuc: Robot) -> None:
    q, _ = _campaign_like(fanuc, 4, seed=10)
    batch = PoseBatch.from_q(fanuc, q)
    rng = np.random.default_rng(11)
    dq0 = rng.normal(size=6) * 1e-5
    dt = rng.normal(size=3) * 1e-4
    eff = make_effect(fanuc, "kinematic_offsets", dict(zip(
        eff_names := eff_param_names(fanuc), np.concatenate([dq0, dt]), strict=True)))
    assert eff.param_names() == eff_names
    off = eff.offset(batch, eff.params)
    for i in range(len(q)):
        T = fanuc.fk(q[i] + dq0)
        true_tcp = T[:3, 3] + T[:3, :3] @ dt
        np.testing.assert_allclose(off[i, :3], true_tcp - batch.T[i, :3, 3], atol=1e-8)


def eff_param_names(robot: Robot) -> tuple[str, ...]:
    return (*(f"dq{j + 1}" for j in range(robot.nq)), "dt_x", "dt_y", "dt_z")


# -- identification of a hidden effect ---------------------------------------------------------
def _synthetic(truth: ElastostaticModel, m: int, seed: int) -> MeasurementSet:
    q, F = _campaign_like(truth.robot, m, seed)
    return MeasurementSet(q=q, wrench=F, position=truth.predict_position(q, F))


@pytest.mark.parametrize("label", NEW_LABELS)
def test_identify_recovers_hidden_effect(zk500: Robot, label: str) -> None:
    base = ElastostaticModel(zk500)
    truth = base.with_effect(label, TRUTH[label])
    data = _synthetic(truth, 60, seed=12)
    # start away from the truth (the Kc prior, gain 1, is the truth itself)
    start = {"gain": 0.0} if label == "complementary_stiffness" else None
    res = identify(base.with_effect(label, start), data, free=[label])
    assert res.rms_before > 1e-5  # the hidden effect is visible (> 10 um RMS)
    assert res.rms_after < 1e-9
    for est in res.estimates:
        want = TRUTH[label][est.name]
        if not est.identified:
            # only joint 6 (its axis passes through the TCP) may stay invisible
            assert (label, est.name) == ("kinematic_offsets", "dq6"), est
            continue
        assert est.value == pytest.approx(want, rel=1e-6, abs=1e-9 * max(1.0, abs(want)))


@pytest.mark.parametrize("label", ["payload_gravity", "sensor_misalignment",
                                   "torque_dependent_stiffness:j2"])
def test_identify_with_joint_compliance_free(zk500: Robot, label: str) -> None:
    """Bilinear (wrench effect x compliance) and joint-compliance-plus-effect fits."""
    base = ElastostaticModel(zk500)
    k_true = zk500.stiffness * np.array([1.1, 0.9, 1.2, 0.85, 1.05, 1.0])
    truth = ElastostaticModel(zk500, [type(base.effects[0])(zk500, None, {
        f"c{j + 1}": 1.0 / k for j, k in enumerate(k_true)})]).with_effect(label, TRUTH[label])
    data = _synthetic(truth, 80, seed=13)
    res = identify(base.with_effect(label), data, free=["joint_compliance", label])
    assert res.converged
    assert res.rms_after < 1e-9
    for est in res.estimates:
        if est.effect == label and est.identified:
            want = TRUTH[label][est.name]
            assert est.value == pytest.approx(want, rel=1e-6, abs=1e-9)
    ok = res.joint_identified
    np.testing.assert_allclose(res.stiffness[ok], k_true[ok], rtol=1e-6)


def test_kc_basis_is_cached_per_batch_and_gives_the_same_numbers(fanuc: Robot) -> None:
    from rfsw_plan.elastostatics.effects.complementary_stiffness import (
        complementary_stiffness_basis,
    )

    q, F = _campaign_like(fanuc, 4, seed=3)
    batch = PoseBatch.from_q(fanuc, q)
    assert not batch.cache
    first = batch_complementary_stiffness(batch, F)
    basis = complementary_stiffness_basis(batch)
    assert complementary_stiffness_basis(batch) is basis  # kept in the batch
    np.testing.assert_array_equal(batch_complementary_stiffness(batch, F), first)
    fresh = batch_complementary_stiffness(PoseBatch.from_q(fanuc, q), 2.0 * F)
    np.testing.assert_allclose(fresh, 2.0 * first, rtol=1e-12, atol=0)  # linear in F
