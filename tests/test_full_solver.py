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
#: In the default run: zk500_table6_seam (the demo) and fanuc_laser_1400mm_yplus, the problem
#: whose plans were furthest apart before both NLPs bounded the offsets' change the same way
#: (0.13 mm at the first weld waypoint, issue 38), a few seconds each.
FAST = ("zk500_table6_seam", "fanuc_laser_1400mm_yplus")


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
    print(f"{problem_name}: default {de * 1e3:.4f} mm and {100 * dk:.3f} % of the weakest "
          f"lateral stiffness off the full NLP's ({default.source}, {full.source})")
    assert de <= E_TOL, f"default plan {de * 1e3:.4f} mm off the full NLP's"


@pytest.mark.parametrize("problem", FAST)
def test_full_nlp_plans_and_default_stays_close(problem: str) -> None:
    _compare(problem)


#: Every other bundled problem, kr600_forming_contour (12 mm corners) included: its full NLP's
#: plan failed the sample check's pin speed at s = 62 mm (+5.08 % against 5 %) while the NLP's
#: travel_speed rows bounded the change of t . (pin - p) and left out the turn of the seam
#: (kappa x offset); they now bound the pin's travel along the seam chord (issue 38).
@pytest.mark.slow
@pytest.mark.parametrize("problem", [p for p in bundled_problem_names() if p not in FAST])
def test_full_nlp_plans_every_bundled_problem(problem: str) -> None:
    _compare(problem)
