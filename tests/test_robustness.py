"""The plan is never beaten by its own baseline (issue 24, :mod:`rfsw_plan.planning.robustness`).

On the same waypoints the written plan tolerates at least the mirror baseline's force
uncertainty (less 0.1 percentage point), for a requested +-10 % and +-20 %, and asking for less
never gives a less robust plan. The mission case is zk500_table6_seam (the issue's numbers:
at +-10 % the plan held +-9.68 % and the mirror +-12 %); every bundled problem is checked at
its own request in the default run, and at +-10 % and +-20 % under ``-m slow``; the placed
problems are checked in ``tests/test_placement.py`` and the property seams in
``tests/test_plan_property.py``.

The tolerated uncertainty is the whole envelope's (issue 38: lateral error, depth, tilt and
pin speed at the vertices of the force box, :func:`rfsw_plan.planning.verify.robust_claim`).
On zk500 (position control, seed 001 forces) the depth limits: the pin's deep side has 0.2 mm
and the axial deflection changes by about 8.9 mm per unit of force uncertainty on the robot's
model (joint 2's torque-dependent stiffness makes the local compliance about 2.5 times the
secant one), so the envelope holds about +-2.1 %; the mirror (depth error 0) is then written.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import rfsw_plan.planning.api as api
from rfsw_plan.planning.robustness import DOMINANCE_TOL, ROBUST_CEILING, nlp_options
from rfsw_plan.process.problem import load_problem

BUNDLED = sorted(p.stem for p in (Path(__file__).resolve().parents[1] / "problems").glob(
    "*.toml"))
REQUESTED = (0.1, 0.2)


def plan_at(name: str | Path, u: float, lateral_only: bool = False,
            **overrides: object) -> api.PlanResult:
    """Plan a bundled problem at +-u; ``lateral_only`` opens the depth, tilt and speed
    tolerances wide, so that the lateral error alone decides the claim (on zk500 the depth
    limits the NLP's plan and the mirror alike at about +-2 %, and the lateral trade these
    tests are about would not show)."""
    pb = load_problem(name)
    if lateral_only:
        pb = dataclasses.replace(pb, window=dataclasses.replace(
            pb.window, depth_shallow=5e-3, depth_deep=5e-3, speed_tol=0.5,
            tilt_tol=float(np.deg2rad(5))))
    return api.plan(pb, dataclasses.replace(pb.planning, force_uncertainty=u, **overrides))


#: An offset rate [m/m] that lets the offsets leave the mirror's (the problems use 0.05-0.2):
#: where a test needs an NLP that spends the window and ends below the mirror.
FREE_OFFSET_RATE = 1.0


def assert_dominates(res: api.PlanResult) -> None:
    """The acceptance inequality, with the numbers in the message."""
    tol = res.tolerated_by_strategy
    assert tol["nlp"] >= tol["mirror"] - DOMINANCE_TOL, (
        f"{res.problem_name} at +-{100 * res.options.force_uncertainty:g} %: plan holds "
        f"{100 * tol['nlp']:.3f} %, mirror {100 * tol['mirror']:.3f} %")
    assert tol["nlp"] >= tol["none"] - DOMINANCE_TOL


def test_zk500_plan_dominates_mirror_at_10_and_20_percent_and_is_monotone() -> None:
    out = {u: plan_at("zk500_table6_seam", u) for u in REQUESTED}
    for res in out.values():
        assert_dominates(res)
        lv = res.tolerated_by_quantity
        assert res.tolerated_force_uncertainty == min(lv.values())
        # Position control with the coupled axial law ([process.coupling]): the material's
        # response is spread, and the axial force changes about 1 / (1 + k_p c) = 1 / 2.8 of
        # it, so the depth holds about +-5.9 % at the planned depth where the force box gave
        # +-2.1 %; the NLP plans with the law and centres the weld's depth in its window, which
        # (with the offsets following the mirror's change at the ramp) holds about +-7.2 %; the
        # pin speed at the weld start limits first.
        assert res.claim_force_model["name"] == "coupled axial law"
        assert min(lv, key=lambda q: lv[q]) in ("speed", "depth")
        assert lv["depth"] == pytest.approx(0.072, abs=3e-3)
        assert lv["lateral"] > 2 * lv["depth"]
    # Asking for less never gives a less robust plan.
    assert out[0.1].tolerated_force_uncertainty >= out[0.2].tolerated_force_uncertainty - 1e-6
    assert out[0.1].verdict().word == out[0.2].verdict().word == "HOLDS NOMINALLY"


def test_trading_robustness_for_stiffness_is_explicit_and_said() -> None:
    """robust_first=false is the old planner: it holds the requested +-10 % at the waypoints
    and spends the rest of the window, ending below the mirror (the issue's +-9.68 %); the
    verdict says so. With offsets free to leave the mirror's (offset_rate 1 mm/mm): at the
    problem's 0.05 mm/mm they follow the mirror's closely enough that even the old planner
    holds more than the mirror (+-14.5 % against +-12.3 %, since both NLPs bound the change
    of the offsets' departure from the mirror's, issue 38)."""
    res = plan_at("zk500_table6_seam", 0.1, lateral_only=True, robust_first=False,
                  offset_rate=FREE_OFFSET_RATE)
    tol = res.tolerated_by_strategy
    assert tol["nlp"] < tol["mirror"] - DOMINANCE_TOL
    v = res.verdict()
    assert "robust_first=false" in v.traded and f"+-{100 * tol['mirror']:.3g} %" in v.traded


def test_the_robust_first_nlp_does_not_depend_on_the_request_below_the_ceiling() -> None:
    pb = load_problem("zk500_table6_seam")
    opts = {u: nlp_options(dataclasses.replace(pb.planning, force_uncertainty=u))
            for u in (0.05, 0.1, 0.2, ROBUST_CEILING)}
    assert len(set(opts.values())) == 1
    hard = nlp_options(dataclasses.replace(pb.planning, robust_hard=True))
    assert not hard.robust_hard  # the requested window is checked hard after the solve


def test_a_plan_less_robust_than_the_mirror_falls_back_to_the_mirror(monkeypatch) -> None:
    """If the NLP ends below the mirror (here: made to pursue only the request), the mirror
    fixed point is verified, timed and written instead, and says so."""
    monkeypatch.setattr(api, "nlp_options", lambda o: o)
    res = plan_at("zk500_table6_seam", 0.02, lateral_only=True, offset_rate=FREE_OFFSET_RATE)
    assert res.source == "mirror" and "mirror baseline" in res.solver_status
    assert_dominates(res)
    assert res.samples is not None and res.samples.ok
    assert res.status == "verified"  # not the NLP's optimum; the mirror holds +-2 %


@pytest.mark.parametrize("name", BUNDLED)
def test_every_bundled_plan_at_its_own_request_dominates_its_baselines(
        name: str, planned_result) -> None:
    """The default run's case of the check below: each bundled problem as written (its own
    force uncertainty), planned once per session for every test that reads it."""
    assert_dominates(planned_result(name))


@pytest.mark.slow
@pytest.mark.parametrize("u", REQUESTED)
@pytest.mark.parametrize("name", BUNDLED)
def test_every_bundled_plan_dominates_its_baselines(name: str, u: float) -> None:
    assert_dominates(plan_at(name, u))
