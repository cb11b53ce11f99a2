"""The effect contract: three abstract bases with enforced methods, and a new effect is one
class that the numeric model, identification and the planner's symbolic compliance pick up
without any other edit (issue 10 item 2)."""

from __future__ import annotations

from collections.abc import Iterator

import casadi as ca
import numpy as np
import pytest

from rfsw_plan import MeasurementSet
from rfsw_plan.elastostatics.effects import (
    EFFECTS,
    ComplianceEffect,
    JointCompliance,
    PoseBatch,
    WrenchEffect,
    make_effect,
)
from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.identification import identify
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.planning.symbolic import symbolic_cartesian_compliance, symbolic_chain
from rfsw_plan.robot.kinematics import Robot, load_robot

#: Bending axis of the new spring effect, in the joint frame (not normal to the joint axis on
#: purpose: any fixed axis is a valid spring).
BEND_AXIS = np.array([0.6, 0.0, 0.8])
#: Hose pull direction of the new wrench effect, base frame.
PULL_DIR = np.array([0.0, 0.6, -0.8])


@pytest.fixture
def new_effects() -> Iterator[tuple[type[ComplianceEffect], type[WrenchEffect]]]:
    """Two effects defined here and nowhere else; removed from the registry afterwards."""

    class LinkBending(ComplianceEffect):
        """Joint N's link bends about one fixed axis of its frame: a rotational spring."""

        name = "test_link_bending"
        description = "A test spring: the link bends about one axis fixed in the joint frame."
        per_joint = True

        def param_names(self) -> tuple[str, ...]:
            return ("c_b",)

        def prior(self) -> FloatArray:
            return np.array([1e-7])

        def plausible_params(self, batch: PoseBatch, wrench: FloatArray,
                             rng: np.random.Generator) -> dict[str, float]:
            return {"c_b": 1e-7 * rng.uniform(0.5, 2.0)}

        def joint_springs(self) -> FloatArray:
            return BEND_AXIS[None, :] / np.linalg.norm(BEND_AXIS)

        def _twist(self, batch: PoseBatch) -> FloatArray:
            assert self.joint is not None
            R = batch.frames[:, self.joint, :3, :3]
            u = R @ self.joint_springs()[0]
            r = batch.T[:, :3, 3] - batch.frames[:, self.joint, :3, 3]
            return np.concatenate([np.cross(u, r), u], axis=1)  # (m, 6)

        def deflection_regressor(self, batch: PoseBatch, wrench: FloatArray,
                                 theta: FloatArray) -> FloatArray:
            j = self._twist(batch)
            return (j * np.einsum("ma,ma->m", j, wrench)[:, None])[:, :, None]

        def deflection(self, batch: PoseBatch, wrench: FloatArray,
                       theta: FloatArray) -> FloatArray:
            return self.deflection_regressor(batch, wrench, theta)[:, :, 0] * float(theta[0])

        def cartesian_compliance(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
            j = self._twist(batch)
            return float(theta[0]) * np.einsum("ma,mb->mab", j, j)

    class HosePull(WrenchEffect):
        """A supply hose pulls on the spindle with a constant force (base frame)."""

        name = "test_hose_pull"
        description = "A test wrench: the spindle's supply hose pulls with a constant force."

        def param_names(self) -> tuple[str, ...]:
            return ("f",)

        def prior(self) -> FloatArray:
            return np.array([0.0])

        def plausible_params(self, batch: PoseBatch, wrench: FloatArray,
                             rng: np.random.Generator) -> dict[str, float]:
            return {"f": rng.uniform(50.0, 300.0)}

        def wrench_regressor(self, batch: PoseBatch, wrench: FloatArray,
                             theta: FloatArray) -> FloatArray:
            out = np.zeros((len(batch), 6, 1))
            out[:, :3, 0] = PULL_DIR
            return out

        def delta_wrench(self, batch: PoseBatch, wrench: FloatArray,
                         theta: FloatArray) -> FloatArray:
            return self.wrench_regressor(batch, wrench, theta)[:, :, 0] * float(theta[0])

    try:
        yield LinkBending, HosePull
    finally:
        EFFECTS.pop(LinkBending.name, None)
        EFFECTS.pop(HosePull.name, None)


@pytest.fixture(scope="module")
def robot() -> Robot:
    return load_robot("zk500")


def _samples(robot: Robot, m: int, seed: int) -> tuple[FloatArray, FloatArray]:
    rng = np.random.default_rng(seed)
    d = robot.description
    lo, hi = np.asarray(d.lower), np.asarray(d.upper)
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    q = mid + 0.4 * half * rng.uniform(-1, 1, (m, robot.nq))
    F = np.concatenate([rng.uniform(-3000, 3000, (m, 3)), rng.uniform(-300, 300, (m, 3))], 1)
    return q, F


def test_the_bases_enforce_their_methods(robot: Robot) -> None:
    class Incomplete(ComplianceEffect):
        def param_names(self) -> tuple[str, ...]:
            return ("x",)

        def prior(self) -> FloatArray:
            return np.zeros(1)

        def deflection(self, batch: PoseBatch, wrench: FloatArray,
                       theta: FloatArray) -> FloatArray:
            return np.zeros((len(batch), 6))

    with pytest.raises(TypeError, match="deflection_regressor, plausible_params"):
        Incomplete(robot)  # type: ignore[abstract]
    assert "Incomplete" not in {c.__name__ for c in EFFECTS.values()}


def test_a_new_spring_effect_is_used_by_model_identification_and_nlp(
    robot: Robot, new_effects: tuple[type[ComplianceEffect], type[WrenchEffect]]
) -> None:
    LinkBending, _ = new_effects
    label = f"{LinkBending.name}:j2"
    assert EFFECTS[LinkBending.name] is LinkBending
    c_b = 4e-7  # [rad/(N m)]
    truth = ElastostaticModel(robot, [make_effect(robot, label, {"c_b": c_b})])
    assert truth.is_spring_model()

    # Numeric model, single pose and batch, against the spring written out from Pinocchio.
    q, F = _samples(robot, 40, seed=1)
    c = truth.joint_compliance.params
    for k in (0, 7):
        T, J = robot.fk_jacobian(q[k])
        frame = robot.joint_frames(q[k])[1]
        u = frame[:3, :3] @ (BEND_AXIS / np.linalg.norm(BEND_AXIS))
        j = np.concatenate([np.cross(u, T[:3, 3] - frame[:3, 3]), u])
        want = J @ (c * (J.T @ F[k])) + c_b * j * (j @ F[k])
        np.testing.assert_allclose(truth.deflection(q[k], F[k]), want, rtol=1e-9)
        np.testing.assert_allclose(truth.deflection(q, F)[k], want, rtol=1e-9)

    # Identification recovers its parameter from positions the truth predicts.
    data = MeasurementSet(q, F, truth.predict_position(q, F), source="synthetic")
    prior = ElastostaticModel(robot, [make_effect(robot, label)])
    res = identify(prior, data, free=[label])
    (est,) = res.estimates
    assert est.identified and est.effect == label
    assert est.value == pytest.approx(c_b, rel=1e-6)
    assert res.converged and res.iterations == 1  # linear: one least-squares step

    # The planner's symbolic compliance includes it (nothing left to the outer loop).
    ch = symbolic_chain(robot)
    C_sym, skipped = symbolic_cartesian_compliance(truth, ch)
    assert skipped == []
    f = ca.Function("C", [ch.q], [C_sym])
    C_num = truth.cartesian_compliance(truth.batch(q[:5]))
    for k in range(5):
        np.testing.assert_allclose(np.array(f(q[k])), C_num[k], rtol=1e-9,
                                   atol=1e-12 * np.max(np.abs(C_num[k])))


def test_a_new_wrench_effect_is_used_by_model_identification_and_nlp(
    robot: Robot, new_effects: tuple[type[ComplianceEffect], type[WrenchEffect]]
) -> None:
    _, HosePull = new_effects
    f_hose = 250.0  # [N]
    truth = ElastostaticModel(robot, [make_effect(robot, HosePull.name, {"f": f_hose})])
    q, F = _samples(robot, 30, seed=2)
    plain = ElastostaticModel(robot, [JointCompliance(robot)])
    F_true = F + f_hose * np.concatenate([PULL_DIR, np.zeros(3)])
    np.testing.assert_allclose(truth.deflection(q, F), plain.deflection(q, F_true), rtol=1e-12)
    assert truth.has_load_independent_part()  # it moves the TCP at zero logged wrench

    data = MeasurementSet(q, F, truth.predict_position(q, F), source="synthetic")
    prior = ElastostaticModel(robot, [make_effect(robot, HosePull.name)])
    res = identify(prior, data, free=[HosePull.name])
    assert res.estimates[0].value == pytest.approx(f_hose, rel=1e-6)

    # Not a spring: the planner leaves it to its outer correction loop, by label.
    _, skipped = symbolic_cartesian_compliance(truth, symbolic_chain(robot))
    assert skipped == [HosePull.name]
