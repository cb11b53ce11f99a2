"""Force/deflection co-simulation (seed 001 Fig. 8) against a closed-form solve."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError
from rfsw_plan.process.cosim import PenetrationLaw, cosimulate
from rfsw_plan.process.presets import process_preset
from rfsw_plan.process.seam import Seam
from rfsw_plan.process.taught import joints_at, taught_path
from rfsw_plan.robot.kinematics import load_robot


@pytest.fixture(scope="module")
def setup():
    robot = load_robot("zk500")
    model = ElastostaticModel(robot)
    assert model.is_linear_joint_model()
    seam = Seam(np.array([[0.26952, -2.07091, 0.66315], [0.2781, -1.9576, 0.66405]]),
                tilt=np.deg2rad(2.0))
    fr = seam.frames(0.02)
    Q = taught_path(robot, fr, np.deg2rad([-96.24, 3.91, 25.45, -2.10, 57.17, 2.90]), np.pi)
    sch = process_preset("seed001_aa6061_5mm").schedule(fr, 0.5)
    Qt = joints_at(sch.s, fr.s, Q)
    return model, sch, Qt


def test_fixed_point_matches_direct_linear_solve(setup) -> None:
    """Linear law f = k_p p and linear robot delta_n = a + c f give
    f = k_p (d_c - a) / (1 + k_p c) in closed form."""
    model, sch, Qt = setup
    law = PenetrationLaw(stiffness=1.0e6, ref_penetration=0.0, ref_force=0.0)
    d_c = sch.depth * (8.0 / 4.8)
    res = cosimulate(model, Qt, sch, law, commanded_depth=d_c, relaxation=0.6, tol=1e-6)
    assert res.all_converged
    assert np.max(res.iterations) < 60 and np.max(res.residual) < 1e-6
    # Direct solve from the (linear) model: a = delta_n(f_n = 0), c = d delta_n / d f_n.
    fr = sch.frames

    def delta(fn: np.ndarray) -> np.ndarray:
        F = sch.force_seam.copy()
        F[:, 2] = fn
        dX = model.deflection(Qt, np.hstack([fr.to_base(F), sch.moment_base]))
        return np.einsum("ki,ki->k", dX[:, :3], fr.n)

    a = delta(np.zeros(len(sch)))
    c = delta(np.ones(len(sch))) - a
    f_direct = law.stiffness * (d_c - a) / (1.0 + law.stiffness * c)
    contact = f_direct > 0
    assert contact.sum() > 10
    np.testing.assert_allclose(res.axial_force[contact], f_direct[contact], atol=1e-4)
    np.testing.assert_allclose(res.penetration, d_c - delta(res.axial_force), atol=1e-12)
    # Robot compliance takes up part of the commanded depth: less force than a rigid robot.
    weld = sch.mask("weld")
    assert np.all(res.axial_force[weld] < law.stiffness * d_c[weld])


def test_non_contraction_is_reported_not_hidden(setup) -> None:
    model, sch, Qt = setup
    law = PenetrationLaw(stiffness=2.0e7, ref_penetration=0.0, ref_force=0.0)
    res = cosimulate(model, Qt, sch, law, relaxation=1.0, max_iter=30)
    assert not res.all_converged
    assert "converged" in res.summary()
    ok = cosimulate(model, Qt, sch, law, relaxation=0.08, max_iter=400)
    assert ok.all_converged


def test_law_and_options() -> None:
    law = PenetrationLaw(1e6, 4.8e-3, 4842.58)
    np.testing.assert_allclose(law.force(np.array([4.8e-3, 5.8e-3, -1.0])),
                               [4842.58, 5842.58, 0.0])
    with pytest.raises(InputError):
        PenetrationLaw(0.0, 0.0, 0.0)
