"""``solver = "full"`` (the NLP on every waypoint, every row family) plans every bundled
problem, and the default coarse-to-fine plan stays within 0.05 mm of its lateral pin errors and
0.5 % of its weakest lateral stiffness."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rfsw_plan.process.problem import bundled_problem_names

#: The default plan against the full NLP's: lateral pin error [m] and weakest weld waypoint's
#: lateral stiffness [share].
E_TOL = 0.05e-3
K_TOL = 0.005
FAST = ("zk500_table6_seam",)
#: Where the default plan's lateral errors are NOT within E_TOL of the full NLP's (measured:
#: 0.08-0.13 mm at the first waypoints of the travel-start force ramp, where the objective is
#: nearly flat in the lateral error; fanuc_butt_1700mm was 0.19 mm before issue 38's rows).
#: Strict: the test says so when one of them starts to hold.
LATERAL_APART = ("fanuc_butt_1700mm", "fanuc_laser_1400mm_yminus", "fanuc_laser_1400mm_yplus",
                 "kr600_curved_seam", "kr600_forming_contour")


def _compare(problem_name: str) -> None:
    from rfsw_plan.planning.api import options_from_problem, plan
    from rfsw_plan.process.problem import load_problem

    problem = load_problem(problem_name)
    opts = options_from_problem(problem)
    default = plan(problem, opts)
    full = plan(problem, replace(opts, solver="full"))
    assert full.verification.feasible and full.samples is not None and full.samples.ok
    assert len(full.q) == len(default.q)

    def weakest(r: object) -> float:
        return float(np.min(r.verification.prediction.lateral_stiffness[r.task.weld]))  # type: ignore[attr-defined]

    dk = abs(weakest(default) - weakest(full)) / weakest(full)
    assert dk <= K_TOL, f"weakest lateral stiffness {100 * dk:.3f} % off the full NLP's"
    de = float(np.max(np.abs(full.e_lat - default.e_lat)))
    if problem_name in LATERAL_APART:
        if de > E_TOL:
            pytest.xfail(f"default plan {de * 1e3:.4f} mm off the full NLP's (known)")
        pytest.fail(f"{problem_name} now holds {E_TOL * 1e3:g} mm: take it out of "
                    "LATERAL_APART")
    assert de <= E_TOL, f"default plan {de * 1e3:.4f} mm off the full NLP's"


@pytest.mark.parametrize("problem", FAST)
def test_full_nlp_plans_and_default_stays_close(problem: str) -> None:
    _compare(problem)


@pytest.mark.slow
@pytest.mark.parametrize("problem", [p for p in bundled_problem_names() if p not in FAST])
def test_full_nlp_plans_every_bundled_problem(problem: str) -> None:
    _compare(problem)
