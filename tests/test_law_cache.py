"""The fitted penetration law is cached in memory by the problem's inputs (issue 41): a task
rebuilt for the same problem (``check``, ``validate-weld``, the placement map) takes the law
fitted before, the same one a cold fit gives; a changed input fits again."""

from __future__ import annotations

import dataclasses

from rfsw_plan.process import deviation
from rfsw_plan.process.problem import load_problem

PROBLEM = "zk500_table6_seam"


def test_a_cached_law_is_the_cold_fit_and_a_changed_problem_fits_again(monkeypatch) -> None:
    monkeypatch.setattr(deviation, "_LAW_CACHE", type(deviation._LAW_CACHE)())
    fits: list[object] = []
    fit = deviation._fit_problem_law

    def counted(problem, coupling):
        fits.append(problem)
        return fit(problem, coupling)

    monkeypatch.setattr(deviation, "_fit_problem_law", counted)
    cold = deviation.problem_penetration_law(load_problem(PROBLEM))
    warm = deviation.problem_penetration_law(load_problem(PROBLEM))  # loaded again: equal inputs
    assert len(fits) == 1 and warm is cold
    pb = load_problem(PROBLEM)
    obs = pb.coupling.calibration
    softer = (dataclasses.replace(obs[0], penetration=obs[0].penetration * 0.9), *obs[1:])
    other = deviation.problem_penetration_law(dataclasses.replace(
        pb, coupling=dataclasses.replace(pb.coupling, calibration=softer)))
    assert len(fits) == 2 and other != cold
    deviation._LAW_CACHE.clear()
    assert deviation.problem_penetration_law(load_problem(PROBLEM)) == cold  # fitted afresh
    assert len(fits) == 3
