"""The top-level Python API: what a user types after ``import rfsw_plan``."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import rfsw_plan


def test_import_does_not_load_casadi() -> None:
    code = "import sys, rfsw_plan; sys.exit(1 if 'casadi' in sys.modules else 0)"
    assert subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


@pytest.mark.usefixtures("stored_plans")  # the session's plan of it (conftest), by this name
def test_plan_returns_a_verified_typed_result() -> None:
    result = rfsw_plan.plan("zk500_table6_seam")
    assert isinstance(result, rfsw_plan.PlanResult)
    assert result.verification.feasible
    window = result.window
    e = result.verification.prediction.e_lat[result.task.weld]
    assert np.all((e >= window.lower) & (e <= window.upper))


def test_model_predicts_the_seed_001_deflection_scale() -> None:
    model = rfsw_plan.load_model("zk500")
    problem = rfsw_plan.load_problem("zk500_table6_seam")
    assert problem.robot.name == "zk500_seed001"  # Table 3 re-identified (issue 28)
    q = np.radians([-82.58, 41.65, 18.67, 0.0, 29.68, 15.42])
    dX = model.deflection(q, [-1415.0, -795.2, 4835.5, 0.0, 0.0, 0.0])
    assert 3e-3 < np.linalg.norm(dX[:3]) < 10e-3
