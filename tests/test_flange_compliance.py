"""The flange (tool-stack) compliance: its regressor against finite differences, its physics
against an independent series-spring formula, and identification from noise-free data."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.elastostatics.effects import PoseBatch, make_effect
from rfsw_plan.elastostatics.identification import identify
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError
from rfsw_plan.io.measurements import MeasurementSet
from rfsw_plan.robot.kinematics import Robot, load_robot

#: A soft stack: 20 / 25 / 10 kN/mm [m/N].
SOFT = {"c_x": 5e-8, "c_y": 4e-8, "c_z": 1e-7}


@pytest.fixture(scope="module")
def zk500() -> Robot:
    return load_robot("zk500")


def _poses(robot: Robot, m: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = np.radians([-90.0, 20.0, 20.0, 0.0, 50.0, 0.0]) + rng.uniform(-0.4, 0.4, (m, robot.nq))
    F = np.hstack([rng.normal(size=(m, 3)) * 3000.0, rng.normal(size=(m, 3)) * 80.0])
    return q, F


def test_regressor_matches_finite_differences(zk500: Robot) -> None:
    q, F = _poses(zk500, 9, 1)
    batch = PoseBatch.from_q(zk500, q)
    eff = make_effect(zk500, "flange_compliance", SOFT)
    theta = eff.params * np.linspace(0.7, 1.3, 3)
    A = eff.deflection_regressor(batch, F, theta)
    h = 1e-3 * theta
    fd = np.stack([(eff.deflection(batch, F, theta + h[k] * np.eye(3)[k])
                    - eff.deflection(batch, F, theta - h[k] * np.eye(3)[k])) / (2 * h[k])
                   for k in range(3)], axis=-1)
    np.testing.assert_allclose(A, fd, rtol=0, atol=1e-9 * np.max(np.abs(A)))
    C = eff.cartesian_compliance(batch, theta)
    np.testing.assert_allclose(np.einsum("mij,mj->mi", C, F), eff.deflection(batch, F, theta),
                               rtol=1e-12, atol=1e-15)


def test_springs_along_the_tool_frame(zk500: Robot) -> None:
    """Independent formula: the force in the tool frame, stretched per axis, back to the base;
    no rotation, and a moment alone does nothing."""
    q, F = _poses(zk500, 5, 2)
    batch = PoseBatch.from_q(zk500, q)
    eff = make_effect(zk500, "flange_compliance", SOFT)
    got = eff.deflection(batch, F, eff.params)
    c = np.array(list(SOFT.values()))
    for k in range(len(q)):
        R = batch.T[k, :3, :3]
        np.testing.assert_allclose(got[k, :3], R @ (c * (R.T @ F[k, :3])), rtol=1e-12)
    np.testing.assert_allclose(got[:, 3:], 0.0, atol=0.0)
    moment_only = np.hstack([np.zeros((5, 3)), F[:, 3:]])
    np.testing.assert_allclose(eff.deflection(batch, moment_only, eff.params), 0.0, atol=0.0)


def test_axial_force_loads_only_the_axial_spring(zk500: Robot) -> None:
    """A force along the tool axis through the TCP moves the TCP by c_z F along the axis."""
    q, _ = _poses(zk500, 3, 3)
    batch = PoseBatch.from_q(zk500, q)
    eff = make_effect(zk500, "flange_compliance", SOFT)
    n = batch.T[:, :3, 2]
    W = np.hstack([4842.58 * n, np.zeros((3, 3))])
    dX = eff.deflection(batch, W, eff.params)
    np.testing.assert_allclose(dX[:, :3], SOFT["c_z"] * 4842.58 * n, rtol=1e-12)
    np.testing.assert_allclose(dX[:, 3:], 0.0, atol=1e-18)


def test_identification_recovers_the_stack_from_noise_free_data(zk500: Robot) -> None:
    q, F = _poses(zk500, 40, 4)
    truth = ElastostaticModel(zk500).with_effect("flange_compliance", SOFT)
    batch = truth.batch(q)
    dX = truth.deflection_batch(batch, F)
    data = MeasurementSet(q=q, wrench=F, position=batch.T[:, :3, 3] + dX[:, :3])
    start = ElastostaticModel(zk500).with_effect("flange_compliance")
    res = identify(start, data, free=["flange_compliance"])
    got = {e.name: e.value for e in res.estimates if e.effect == "flange_compliance"}
    for k, v in SOFT.items():
        assert got[k] == pytest.approx(v, rel=1e-5), k


def test_bad_parameters_are_named(zk500: Robot) -> None:
    eff = make_effect(zk500, "flange_compliance", {"c_z": -1e-7})
    with pytest.raises(InputError, match=r"flange_compliance\.c_z"):
        eff.check_params()
    with pytest.raises(InputError, match="unknown parameter"):
        make_effect(zk500, "flange_compliance", {"k_z": 1e8})
