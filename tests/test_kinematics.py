"""Kinematics: Pinocchio, the vectorised batch and the CasADi chain agree; Jacobians vs FD."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from rfsw_plan.exceptions import InputError
from rfsw_plan.planning.symbolic import kinematics_function, symbolic_chain
from rfsw_plan.robot.description import bundled_robot_names
from rfsw_plan.robot.ik import solve_ik
from rfsw_plan.robot.kinematics import Robot, load_robot

DATA = Path(__file__).parent / "data"
ROBOTS = ["zk500", "fanuc_s900ib_400", "kuka_kr600_r2830"]
#: The URDF fixture turns joint 4 about -z: q_urdf = SIGN * q_mdh.
URDF_SIGN = np.array([1.0, 1.0, 1.0, -1.0, 1.0, 1.0])


def random_q(robot: Robot, m: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = robot.description
    return rng.uniform(d.lower, d.upper, size=(m, robot.nq))


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request: pytest.FixtureRequest) -> Robot:
    return load_robot(request.param)


def test_bundled_robots_are_the_three_seed_robots() -> None:
    assert set(ROBOTS) <= set(bundled_robot_names())


def test_pinocchio_casadi_batch_agree(robot: Robot) -> None:
    Q = random_q(robot, 25, seed=1)
    f = kinematics_function(robot)
    Tb, Jb, Fb = robot.batch_fk_jacobian_frames(Q)
    for i, q in enumerate(Q):
        T, J = robot.fk_jacobian(q)
        p_s, R_s, J_s = (np.asarray(x) for x in f(q))
        np.testing.assert_allclose(p_s.ravel(), T[:3, 3], rtol=0, atol=1e-9)
        np.testing.assert_allclose(R_s, T[:3, :3], rtol=0, atol=1e-9)
        np.testing.assert_allclose(J_s, J, rtol=0, atol=1e-9)
        np.testing.assert_allclose(Tb[i], T, rtol=0, atol=1e-9)
        np.testing.assert_allclose(Jb[i], J, rtol=0, atol=1e-9)
        np.testing.assert_allclose(Fb[i], robot.joint_frames(q), rtol=0, atol=1e-9)


def test_symbolic_joint_frames_match_pinocchio(robot: Robot) -> None:
    import casadi as ca

    ch = symbolic_chain(robot)
    f = ca.Function("frames", [ch.q], [*ch.joint_R, *ch.joint_o])
    q = random_q(robot, 1, seed=2)[0]
    out = [np.asarray(x) for x in f(q)]
    frames = robot.joint_frames(q)
    n = robot.nq
    for i in range(n):
        np.testing.assert_allclose(out[i], frames[i, :3, :3], atol=1e-9)
        np.testing.assert_allclose(out[n + i].ravel(), frames[i, :3, 3], atol=1e-9)


def test_batch_single_row_and_large_batch_chunks(robot: Robot) -> None:
    """Chunking in the batch path must not change any number (m > BATCH_CHUNK)."""
    Q = random_q(robot, robot.BATCH_CHUNK + 7, seed=3)
    T, J = robot.batch_fk_jacobian(Q)
    for i in (0, robot.BATCH_CHUNK - 1, robot.BATCH_CHUNK, Q.shape[0] - 1):
        T1, J1 = robot.fk_jacobian(Q[i])
        np.testing.assert_allclose(T[i], T1, atol=1e-12)
        np.testing.assert_allclose(J[i], J1, atol=1e-12)
    T0, J0 = robot.batch_fk_jacobian(Q[5])  # 1-D input is one pose
    np.testing.assert_allclose(T0[0], T[5], atol=1e-15)
    np.testing.assert_allclose(J0[0], J[5], atol=1e-15)


def _fd_twist_jacobian(robot: Robot, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences of the TCP pose: [dp/dq; log3(R+ R-^T)/(2h)], base frame."""
    n = robot.nq
    J = np.empty((6, n))
    for k in range(n):
        dq = np.zeros(n)
        dq[k] = h
        Tp, Tm = robot.fk(q + dq), robot.fk(q - dq)
        J[:3, k] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        J[3:, k] = pin.log3(Tp[:3, :3] @ Tm[:3, :3].T) / (2 * h)
    return J


def test_tcp_jacobian_vs_finite_differences(robot: Robot) -> None:
    for q in random_q(robot, 5, seed=4):
        J = robot.jacobian(q)
        J_fd = _fd_twist_jacobian(robot, q)
        np.testing.assert_allclose(J, J_fd, rtol=0, atol=1e-8)


def test_jacobian_derivatives_vs_finite_differences(robot: Robot) -> None:
    h = 1e-6
    for q in random_q(robot, 4, seed=5):
        dJ = robot.jacobian_derivatives(q)
        for k in range(robot.nq):
            dq = np.zeros(robot.nq)
            dq[k] = h
            fd = (robot.jacobian(q + dq) - robot.jacobian(q - dq)) / (2 * h)
            np.testing.assert_allclose(dJ[k], fd, rtol=0, atol=1e-7, err_msg=f"dJ/dq{k + 1}")


def test_fanuc_coupling_is_the_parallelogram() -> None:
    """Seed 000 eq. 2/4: motor 3 sets the forearm's absolute angle, whatever q2 is."""
    r = load_robot("fanuc_s900ib_400")
    assert not np.allclose(r.coupling, np.eye(6))
    q = np.radians([10.0, 0.0, 20.0, 30.0, -40.0, 50.0])
    R3 = r.joint_frames(q)[2, :3, :3]
    for q2 in (-40.0, -10.0, 35.0, 60.0):
        q_b = q.copy()
        q_b[1] = np.radians(q2)
        np.testing.assert_allclose(r.joint_frames(q_b)[2, :3, :3], R3, atol=1e-12)
    # The controller Jacobian is the chain Jacobian times G.
    Jc = pin.computeFrameJacobian(
        r.model, r.data, r.chain_q(q), r.tcp_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    )
    np.testing.assert_allclose(r.jacobian(q), Jc @ r.coupling, atol=1e-12)


@pytest.mark.parametrize("axis_only", [False, True])
def test_ik_converges_from_nearby_seed(robot: Robot, axis_only: bool) -> None:
    rng = np.random.default_rng(6)
    d = robot.description
    lo = d.lower + 0.3 * (d.upper - d.lower)
    hi = d.upper - 0.3 * (d.upper - d.lower)
    for _ in range(4):
        q_true = rng.uniform(lo, hi)
        target = robot.fk(q_true)
        res = solve_ik(robot, target, q_true + rng.normal(0.0, 0.05, robot.nq),
                       axis_only=axis_only)
        assert res.converged, res
        T = robot.fk(res.q)
        np.testing.assert_allclose(T[:3, 3], target[:3, 3], atol=1e-6)
        np.testing.assert_allclose(T[:3, 2], target[:3, 2], atol=1e-6)
        if not axis_only:
            np.testing.assert_allclose(T[:3, :3], target[:3, :3], atol=1e-6)


def test_urdf_plus_stiffness_file_matches_mdh_description() -> None:
    urdf = load_robot(DATA / "zk500_urdf.toml")
    mdh = load_robot("zk500")
    assert urdf.nq == 6
    np.testing.assert_array_equal(urdf.stiffness, mdh.stiffness)
    Q = random_q(mdh, 10, seed=7)
    Tb, Jb = urdf.batch_fk_jacobian(Q * URDF_SIGN)
    for i, q in enumerate(Q):
        T_u, J_u = urdf.fk_jacobian(q * URDF_SIGN)
        T_m, J_m = mdh.fk_jacobian(q)
        np.testing.assert_allclose(T_u, T_m, atol=1e-9)
        np.testing.assert_allclose(J_u * URDF_SIGN, J_m, atol=1e-9)
        np.testing.assert_allclose(Tb[i], T_u, atol=1e-9)
        np.testing.assert_allclose(Jb[i], J_u, atol=1e-9)
    f = kinematics_function(urdf)
    p_s, _, J_s = (np.asarray(x) for x in f(Q[0] * URDF_SIGN))
    np.testing.assert_allclose(p_s.ravel(), mdh.fk(Q[0])[:3, 3], atol=1e-9)
    np.testing.assert_allclose(J_s * URDF_SIGN, mdh.jacobian(Q[0]), atol=1e-9)


def test_urdf_jacobian_derivatives_vs_fd() -> None:
    """Non-z joint axes (RY, RevoluteUnaligned) go through the same derivative code."""
    r = load_robot(DATA / "zk500_urdf.toml")
    q = random_q(r, 1, seed=8)[0]
    dJ = r.jacobian_derivatives(q)
    h = 1e-6
    for k in range(6):
        dq = np.zeros(6)
        dq[k] = h
        fd = (r.jacobian(q + dq) - r.jacobian(q - dq)) / (2 * h)
        np.testing.assert_allclose(dJ[k], fd, atol=1e-7)


def test_urdf_with_unknown_tip_link_names_it(tmp_path: Path) -> None:
    text = (DATA / "zk500_urdf.toml").read_text().replace('tip_link = "flange"',
                                                          'tip_link = "flang"')
    text = text.replace('urdf = "zk500_like.urdf"', f'urdf = "{DATA / "zk500_like.urdf"}"')
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    with pytest.raises(InputError, match=r"tip_link.*flang.*flange"):
        load_robot(bad)


def test_bare_urdf_asks_for_stiffness_file() -> None:
    with pytest.raises(InputError, match="stiffness"):
        load_robot(DATA / "zk500_like.urdf")


def test_batch_frame_of_a_prismatic_joint_is_before_its_slide() -> None:
    """The batch joint frames (PoseBatch.frames) put a prismatic joint's origin before its
    slide (where its link placement ends; tests/test_link_errors.py needs exactly that), and
    differ from Pinocchio's oMi by q_i along the joint axis there and nowhere else."""
    robot = load_robot("tiago_arm")
    slide = robot.geometry.prismatic
    assert slide.any()
    Q = random_q(robot, 6, seed=3)
    _, _, F = robot.batch_fk_jacobian_frames(Q)
    for i, q in enumerate(Q):
        oMi = robot.joint_frames(q)
        np.testing.assert_allclose(F[i][:, :3, :3], oMi[:, :3, :3], rtol=0, atol=1e-9)
        np.testing.assert_allclose(F[i][~slide], oMi[~slide], rtol=0, atol=1e-9)
        for j in np.flatnonzero(slide):
            step = oMi[j, :3, 3] - F[i][j, :3, 3]
            np.testing.assert_allclose(step, robot.chain_q(q)[j] * oMi[j, :3, 2], atol=1e-9)
