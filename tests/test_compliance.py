"""Elastostatics: eq. 11 deflection, Cartesian stiffness, Kc, nu_p, kappa_f, effect regressors."""

from __future__ import annotations

import itertools

import casadi as ca
import numpy as np
import pytest

from rfsw_plan.elastostatics.compliance import (
    cartesian_compliance,
    cartesian_stiffness,
    complementary_stiffness,
    deflection,
    deflection_with_kc,
    dexterity,
    directional_stiffness,
    kc_influence_index,
)
from rfsw_plan.elastostatics.effects import JointCompliance, PoseBatch, TiltingCompliance
from rfsw_plan.elastostatics.model import ElastostaticModel, load_model
from rfsw_plan.planning.symbolic import symbolic_cartesian_compliance, symbolic_chain
from rfsw_plan.robot.kinematics import Robot, load_robot

ROBOTS = ["zk500", "fanuc_s900ib_400", "kuka_kr600_r2830"]


def random_q(robot: Robot, m: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = robot.description
    lo = d.lower + 0.1 * (d.upper - d.lower)
    hi = d.upper - 0.1 * (d.upper - d.lower)
    return rng.uniform(lo, hi, size=(m, robot.nq))


def random_wrench(rng: np.random.Generator, m: int | None = None) -> np.ndarray:
    shape = (6,) if m is None else (m, 6)
    F = rng.normal(size=shape)
    F[..., :3] *= 3000.0  # N
    F[..., 3:] *= 200.0  # N m
    return F


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request: pytest.FixtureRequest) -> Robot:
    return load_robot(request.param)


def test_deflection_is_eq11(robot: Robot) -> None:
    rng = np.random.default_rng(10)
    Q = random_q(robot, 8, seed=10)
    F = random_wrench(rng, 8)
    _, J = robot.batch_fk_jacobian(Q)
    Cq = robot.joint_compliance
    dX = deflection(J, Cq, F)
    assert dX.shape == (8, 6)
    for i in range(8):
        explicit = J[i] @ np.linalg.inv(np.linalg.inv(Cq)) @ J[i].T @ F[i]
        np.testing.assert_allclose(dX[i], explicit, rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(deflection(J[i], Cq, F[i]), dX[i], rtol=1e-14, atol=0)
        np.testing.assert_allclose(cartesian_compliance(J[i], Cq) @ F[i], dX[i], rtol=1e-12,
                                   atol=1e-18)


def test_cartesian_stiffness_inverts_compliance(robot: Robot) -> None:
    q = random_q(robot, 1, seed=11)[0]
    J = robot.jacobian(q)
    Kq = np.diag(robot.stiffness)
    Cq = np.diag(1.0 / robot.stiffness)
    K_X = cartesian_stiffness(J, Kq)
    C_X = cartesian_compliance(J, Cq)
    np.testing.assert_allclose(K_X @ C_X, np.eye(6), atol=1e-8)


def test_complementary_stiffness_is_derivative_of_joint_torques(robot: Robot) -> None:
    """Kc[:, k] = d(J(q)^T F)/dq_k (seed 000 eq. 6), checked by central differences."""
    rng = np.random.default_rng(12)
    h = 1e-6
    for q in random_q(robot, 3, seed=12):
        F = random_wrench(rng)
        Kc = complementary_stiffness(robot.jacobian_derivatives(q), F)
        for k in range(robot.nq):
            dq = np.zeros(robot.nq)
            dq[k] = h
            fd = (robot.jacobian(q + dq).T @ F - robot.jacobian(q - dq).T @ F) / (2 * h)
            np.testing.assert_allclose(Kc[:, k], fd, rtol=1e-6, atol=1e-5)


def test_kc_deflection_matches_nonlinear_equilibrium() -> None:
    """(Kq - Kc)^-1 J^T F is the first-order joint deflection of K dq = J(q0 + dq)^T F."""
    r = load_robot("zk500")
    q0 = np.radians([-80.0, 40.0, 20.0, 10.0, 30.0, 15.0])
    F = np.array([1000.0, -1500.0, 4800.0, 50.0, -30.0, 20.0])
    Kq = np.diag(r.stiffness) / 20.0  # soft joints: a visible geometric effect
    J = r.jacobian(q0)
    dq = np.linalg.solve(Kq, J.T @ F)
    for _ in range(100):  # fixed point of K dq = J(q0 + dq)^T F
        dq = np.linalg.solve(Kq, r.jacobian(q0 + dq).T @ F)
    Kc = complementary_stiffness(r.jacobian_derivatives(q0), F)
    dq_kc = np.linalg.solve(Kq - Kc, J.T @ F)
    dq_lin = np.linalg.solve(Kq, J.T @ F)
    err_kc = np.linalg.norm(dq_kc - dq)
    err_lin = np.linalg.norm(dq_lin - dq)
    assert err_kc < 0.05 * err_lin
    dX = deflection_with_kc(J, Kq, Kc, F)
    np.testing.assert_allclose(dX, J @ dq_kc, rtol=1e-12)


def test_nu_p_definition_and_scaling(robot: Robot) -> None:
    rng = np.random.default_rng(13)
    q = random_q(robot, 1, seed=13)[0]
    F = random_wrench(rng)
    J = robot.jacobian(q)
    Kq = np.diag(robot.stiffness)
    dJ = robot.jacobian_derivatives(q)
    Kc = complementary_stiffness(dJ, F)
    a = np.linalg.norm((J @ np.linalg.inv(Kq - Kc) @ J.T @ F)[:3])
    b = np.linalg.norm((J @ np.linalg.inv(Kq) @ J.T @ F)[:3])
    nu = kc_influence_index(J, Kq, Kc, F)
    assert nu == pytest.approx(abs(a - b) / max(a, b), rel=1e-12)
    assert 0.0 <= nu < 1.0
    # Kc is linear in F and the deflection too: nu_p is first order in |F|.
    F_small = F / 100.0
    nu_small = kc_influence_index(J, Kq, complementary_stiffness(dJ, F_small), F_small)
    assert nu_small == pytest.approx(nu / 100.0, rel=0.05)


def test_dexterity_at_least_one_and_grows_towards_singularity() -> None:
    r = load_robot("zk500")
    for q in random_q(r, 20, seed=14):
        assert dexterity(r.jacobian(q)) >= 1.0 - 1e-12
    assert dexterity(np.eye(6)) == pytest.approx(1.0)
    q = np.radians([-80.0, 40.0, 20.0, 10.0, 30.0, 15.0])
    values = []
    for q5 in (0.3, 1e-2, 1e-4, 1e-6):  # wrist singularity at q5 = 0
        q[4] = q5
        values.append(dexterity(r.jacobian(q)))
    assert all(b > 10 * a for a, b in itertools.pairwise(values))
    assert values[-1] > 1e5
    assert dexterity(np.zeros((6, 6))) == float("inf")


def test_directional_stiffness_is_force_over_displacement(robot: Robot) -> None:
    rng = np.random.default_rng(15)
    Q = random_q(robot, 4, seed=15)
    _, J = robot.batch_fk_jacobian(Q)
    C = cartesian_compliance(J, robot.joint_compliance)
    dirs = rng.normal(size=(4, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    k = directional_stiffness(C, dirs)
    assert k.shape == (4,)
    for i in range(4):
        f = 1000.0
        F = np.concatenate([f * dirs[i], np.zeros(3)])
        along = deflection(J[i], robot.joint_compliance, F)[:3] @ dirs[i]
        assert k[i] == pytest.approx(f / along, rel=1e-12)
        assert directional_stiffness(C[i], dirs[i]) == pytest.approx(k[i], rel=1e-14)


def test_joint_compliance_regressor_vs_fd(robot: Robot) -> None:
    rng = np.random.default_rng(16)
    batch = PoseBatch.from_q(robot, random_q(robot, 5, seed=16))
    F = random_wrench(rng, 5)
    eff = JointCompliance(robot)
    th = eff.params
    W = eff.deflection_regressor(batch, F, th)
    for k in range(th.size):
        h = 1e-3 * th[k]
        tp, tm = th.copy(), th.copy()
        tp[k] += h
        tm[k] -= h
        fd = (eff.deflection(batch, F, tp) - eff.deflection(batch, F, tm)) / (2 * h)
        np.testing.assert_allclose(W[:, :, k], fd, rtol=1e-6,
                                   atol=1e-9 * np.max(np.abs(W[:, :, k])))
    # Regressor is seed 000 eq. 14: column k = J_k (J_k^T F).
    Jk = batch.J[0][:, 2]
    np.testing.assert_allclose(W[0][:, 2], Jk * (Jk @ F[0]), rtol=1e-12)


def _tilted_tcp_twist_fd(robot: Robot, q: np.ndarray, joint: int, axis_local: np.ndarray,
                         eps: float = 1e-7) -> np.ndarray:
    """TCP twist of a small rotation of joint ``joint``'s frame about a local axis (FD)."""
    import pinocchio as pin

    frames = robot.joint_frames(q)
    Ti = frames[joint]
    T = robot.fk(q)
    rel = np.linalg.inv(Ti) @ T
    out = []
    for s in (eps, -eps):
        Rt = np.eye(4)
        Rt[:3, :3] = pin.exp3(s * axis_local)
        out.append(Ti @ Rt @ rel)
    v = (out[0][:3, 3] - out[1][:3, 3]) / (2 * eps)
    w = pin.log3(out[0][:3, :3] @ out[1][:3, :3].T) / (2 * eps)
    return np.concatenate([v, w])


def test_tilting_compliance_twists_and_regressor_vs_fd() -> None:
    r = load_robot("kuka_kr600_r2830")
    rng = np.random.default_rng(17)
    Q = random_q(r, 3, seed=17)
    batch = PoseBatch.from_q(r, Q)
    F = random_wrench(rng, 3)
    for j in range(r.nq):
        eff = TiltingCompliance(r, j)
        tw = eff.tilt_twists(batch)
        local = eff.joint_springs()
        np.testing.assert_allclose(local @ local.T, np.eye(2), atol=1e-12)
        np.testing.assert_allclose(local @ r.geometry.axes[j], 0.0, atol=1e-12)
        for m in range(3):
            for t in range(2):
                fd = _tilted_tcp_twist_fd(r, Q[m], j, local[t])
                np.testing.assert_allclose(tw[m, :, t], fd, atol=1e-6)
        th = eff.params
        W = eff.deflection_regressor(batch, F, th)
        for k in range(2):
            h = 1e-3 * th[k]
            tp, tm = th.copy(), th.copy()
            tp[k] += h
            tm[k] -= h
            fd = (eff.deflection(batch, F, tp) - eff.deflection(batch, F, tm)) / (2 * h)
            np.testing.assert_allclose(W[:, :, k], fd, rtol=1e-6,
                                       atol=1e-9 * np.max(np.abs(W[:, :, k])))
        C = eff.cartesian_compliance(batch, th)
        np.testing.assert_allclose(np.einsum("mab,mb->ma", C, F), eff.deflection(batch, F, th),
                                   rtol=1e-10, atol=1e-16)


def test_model_with_tilting_matches_symbolic_compliance() -> None:
    model = load_model("kuka_kr600_r2830")
    assert any(isinstance(e, TiltingCompliance) for e in model.effects)
    ch = symbolic_chain(model.robot)
    C_sym, skipped = symbolic_cartesian_compliance(model, ch)
    assert skipped == []
    f = ca.Function("C", [ch.q], [C_sym])
    Q = random_q(model.robot, 6, seed=18)
    C_num = model.cartesian_compliance(model.batch(Q))
    rng = np.random.default_rng(18)
    F = random_wrench(rng, 6)
    dX = model.deflection(Q, F)
    for i, q in enumerate(Q):
        Cs = np.asarray(f(q))
        scale = np.max(np.abs(Cs))
        np.testing.assert_allclose(C_num[i] / scale, Cs / scale, rtol=0, atol=1e-9)
        np.testing.assert_allclose(dX[i], Cs @ F[i], rtol=1e-9, atol=1e-15)


def test_tilting_adds_to_joint_compliance() -> None:
    model = load_model("kuka_kr600_r2830")
    base = ElastostaticModel(model.robot, [JointCompliance(model.robot)])
    q = random_q(model.robot, 1, seed=19)[0]
    F = np.array([0.0, 0.0, 5000.0, 0.0, 0.0, 0.0])
    d_all, d_base = model.deflection(q, F), base.deflection(q, F)
    assert np.linalg.norm(d_all[:3]) > np.linalg.norm(d_base[:3])


def test_fast_joint_path_equals_effect_path(robot: Robot) -> None:
    """ElastostaticModel's joint-only shortcut gives the JointCompliance effect's numbers."""
    model = ElastostaticModel(robot, [JointCompliance(robot)])
    assert model.is_linear_joint_model()
    rng = np.random.default_rng(20)
    Q = random_q(robot, 7, seed=20)
    F = random_wrench(rng, 7)
    batch = model.batch(Q)
    ref = model.joint_compliance.deflection(batch, F, model.joint_compliance.params)
    np.testing.assert_allclose(model.deflection(Q, F), ref, rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(model.deflection(Q[2], F[2]), ref[2], rtol=1e-12, atol=1e-18)
    np.testing.assert_allclose(model.deflection_batch(batch, F), ref, rtol=1e-12, atol=1e-18)
