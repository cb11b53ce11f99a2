"""Spring effects evaluated together (vectorised batch, one-Jacobian single pose) agree with
the effects' own per-effect equations (seed 002 eq. 2)."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.elastostatics.effects import PoseBatch, TiltingCompliance
from rfsw_plan.elastostatics.model import ElastostaticModel, load_model
from rfsw_plan.elastostatics.springs import (
    JointSprings,
    SpringChain,
    chain_spring_deflection,
    spring_compliance,
    spring_deflection,
    spring_twists,
)


def _model(name: str) -> ElastostaticModel:
    """The robot's model with tilting compliance on every joint (distinct values)."""
    model = load_model(name)
    for j in range(model.robot.nq):
        label = f"tilting_compliance:j{j + 1}"
        if not model.has(label):
            model = model.with_effect(label, {"c_t1": 1e-7 * (j + 1), "c_t2": 3e-7 / (j + 1)})
    return model


def _poses(model: ElastostaticModel, m: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    d = model.robot.description
    Q = rng.uniform(d.lower, d.upper, size=(m, model.robot.nq))
    F = rng.normal(size=(m, 6)) * np.array([3000.0, 3000.0, 3000.0, 100.0, 100.0, 100.0])
    return Q, F


# fanuc_s900ib_400 has a coupled (non-identity) G; the KUKA has tilting effects in its file.
ROBOTS = ["kuka_kr600_r2830", "fanuc_s900ib_400", "zk500"]


@pytest.mark.parametrize("name", ROBOTS)
def test_grouped_springs_match_the_per_effect_sum(name: str) -> None:
    model = _model(name)
    assert model.is_spring_model()
    Q, F = _poses(model, 20, seed=1)
    batch = model.batch(Q)
    want = sum(e.deflection(batch, F, e.params) for e in model.effects)
    C_want = sum(e.cartesian_compliance(batch, e.params) for e in model.effects)
    tol = 1e-12 * np.max(np.abs(want))
    np.testing.assert_allclose(model.deflection_batch(batch, F), want, rtol=0, atol=tol)
    np.testing.assert_allclose(model.deflection(Q, F), want, rtol=0, atol=tol)
    np.testing.assert_allclose(model.cartesian_compliance(batch), C_want, rtol=0,
                               atol=1e-12 * np.max(np.abs(C_want)))
    # One pose takes the single-Jacobian path.
    single = np.stack([model.deflection(Q[i], F[i]) for i in range(len(Q))])
    np.testing.assert_allclose(single, want, rtol=0, atol=tol)


def test_batch_path_matches_the_effect_by_effect_sum_on_random_kuka_poses() -> None:
    model = load_model("kuka_kr600_r2830")  # joint compliance + six tilting effects (file)
    assert model.is_spring_model() and len(model.effects) == 7
    Q, F = _poses(model, 50, seed=6)
    batch = PoseBatch.from_q(model.robot, Q)
    want = sum(e.deflection(batch, F, e.params) for e in model.effects)
    tol = 1e-12 * np.max(np.abs(want))
    np.testing.assert_allclose(model.deflection(Q, F), want, rtol=0, atol=tol)
    # Chunk boundaries: the same with tiny chunks, and one wrench broadcast to every pose.
    robot = model.robot
    springs = model.springs()
    c = model.joint_compliance.params
    robot.BATCH_CHUNK = 7  # instance attribute shadows the class constant
    try:
        np.testing.assert_allclose(chain_spring_deflection(robot, Q, F, c, springs), want,
                                   rtol=0, atol=tol)
        one = sum(e.deflection(batch, np.tile(F[0], (len(Q), 1)), e.params)
                  for e in model.effects)
        np.testing.assert_allclose(chain_spring_deflection(robot, Q, F[0], c, springs), one,
                                   rtol=0, atol=tol)
    finally:
        del robot.BATCH_CHUNK
    # No springs: the joint compliance alone.
    joint = model.effects[0].deflection(batch, F, c)
    np.testing.assert_allclose(chain_spring_deflection(robot, Q, F, c, []), joint, rtol=0,
                               atol=1e-12 * np.max(np.abs(joint)))


@pytest.mark.parametrize("name", ["kuka_kr600_r2830", "fanuc_s900ib_400"])
def test_batch_path_handles_springs_about_any_axis(name: str) -> None:
    model = load_model(name)
    rng = np.random.default_rng(7)
    axes = rng.normal(size=(3, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    springs = [JointSprings(1, axes, np.array([1e-7, 2e-7, 3e-7])),
               JointSprings(4, axes[:1], np.array([5e-7])),
               JointSprings(1, np.eye(3)[1:], np.array([4e-7, 6e-7]))]
    Q, F = _poses(model, 9, seed=8)
    batch = PoseBatch.from_q(model.robot, Q)
    c = model.joint_compliance.params
    want = spring_deflection(batch, springs, F) + model.effects[0].deflection(batch, F, c)
    np.testing.assert_allclose(chain_spring_deflection(model.robot, Q, F, c, springs), want,
                               rtol=0, atol=1e-12 * np.max(np.abs(want)))


def test_spring_functions_match_tilting_compliance() -> None:
    model = _model("kuka_kr600_r2830")
    Q, F = _poses(model, 7, seed=2)
    batch = PoseBatch.from_q(model.robot, Q)
    tilts = [e for e in model.effects if isinstance(e, TiltingCompliance)]
    springs = [JointSprings(int(e.joint or 0), e.joint_springs(), e.params) for e in tilts]
    np.testing.assert_allclose(
        spring_twists(batch, springs), np.concatenate([e.tilt_twists(batch) for e in tilts], 2),
        rtol=0, atol=1e-14)
    want = sum(e.deflection(batch, F, e.params) for e in tilts)
    np.testing.assert_allclose(spring_deflection(batch, springs, F), want, rtol=0,
                               atol=1e-12 * np.max(np.abs(want)))
    C = spring_compliance(batch, springs)
    np.testing.assert_allclose(C, C.transpose(0, 2, 1), rtol=0, atol=1e-12 * np.max(np.abs(C)))
    np.testing.assert_allclose(np.matmul(C, F[:, :, None])[:, :, 0], want, rtol=0,
                               atol=1e-12 * np.max(np.abs(want)))
    assert not spring_deflection(batch, [], F).any()
    assert not spring_compliance(batch, []).any()


@pytest.mark.parametrize("name", ["kuka_kr600_r2830", "fanuc_s900ib_400"])
def test_spring_chain_jacobian_is_the_robot_jacobian_plus_the_twists(name: str) -> None:
    model = _model(name)
    robot = model.robot
    tilts = [e for e in model.effects if isinstance(e, TiltingCompliance)][::-1]  # any order
    chain = SpringChain(robot, [(int(e.joint or 0), e.joint_springs()) for e in tilts])
    Q, _ = _poses(model, 3, seed=3)
    batch = PoseBatch.from_q(robot, Q)
    for i in range(len(Q)):
        Jx = chain.jacobian(Q[i])
        np.testing.assert_allclose(Jx[:, chain.real] @ robot.coupling, batch.J[i], atol=1e-12)
        twists = np.concatenate([e.tilt_twists(batch)[i] for e in tilts], axis=1)
        np.testing.assert_allclose(Jx[:, chain.spring_v], twists, atol=1e-12)


def test_changed_parameters_and_effects_are_picked_up_by_the_single_pose_path() -> None:
    model = _model("zk500")
    Q, F = _poses(model, 1, seed=4)
    before = model.deflection(Q[0], F[0])
    model.effects[2].params = model.effects[2].params * 3.0  # as identification does
    batch = model.batch(Q)
    np.testing.assert_allclose(model.deflection(Q[0], F[0]),
                               model.deflection_batch(batch, F)[0], rtol=1e-12)
    assert not np.allclose(model.deflection(Q[0], F[0]), before, rtol=1e-9, atol=0)
    fewer = ElastostaticModel(model.robot, model.effects[:3])
    np.testing.assert_allclose(fewer.deflection(Q[0], F[0]),
                               fewer.deflection_batch(fewer.batch(Q), F)[0], rtol=1e-12)


def test_a_model_with_a_non_spring_effect_is_not_a_spring_model() -> None:
    model = _model("zk500").with_effect("payload_gravity")
    assert not model.is_spring_model()
    Q, F = _poses(model, 2, seed=5)
    batch = model.batch(Q)
    np.testing.assert_allclose(model.deflection(Q[0], F[0]), model.deflection_batch(batch, F)[0],
                               rtol=1e-12)
