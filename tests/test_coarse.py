"""The coarse-to-fine solve gives the full NLP's plan: every fine row holds, same objective.

For each bundled problem (at a spacing with more weld waypoints than the coarse NLP has), the
planner's default (coarse NLP, exact fine projection) and ``solver = "full"`` (the NLP on every
waypoint) are solved from the same branch and warm start; both are checked against every row
of the same fine NLP at IPOPT's tolerance, and the objectives compared.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.planning.api import choose_branch, options_from_problem, solve_plan
from rfsw_plan.planning.baselines import mirror_compensation
from rfsw_plan.planning.coarse import ROW_TOL, interpolate_offsets, subsample_task
from rfsw_plan.planning.nlp import build_plan_nlp
from rfsw_plan.planning.verify import verify_plan
from rfsw_plan.process.problem import load_problem
from rfsw_plan.process.task import task_from_schedule
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.robot.kinematics import load_robot

#: Bundled problems and the weld waypoints to plan them with (None: the problem's spacing).
#: The kr600 (the longest full NLP, ~7 s) runs under ``-m slow``.
CASES = [("zk500_table6_seam", 200), ("fanuc_butt_1700mm", None),
         pytest.param("kr600_curved_seam", None, marks=pytest.mark.slow)]


def _setup(name: str, n_weld: int | None):
    problem = load_problem(name)
    opts = options_from_problem(problem)
    model = ElastostaticModel(load_robot(problem.robot))
    spacing = problem.seam.length / (n_weld - 1) if n_weld else problem.spacing
    frames = problem.seam.frames(spacing)
    task = task_from_schedule(frames, problem.process.schedule(frames, 0.05, approach=False),
                              opts.max_start_waypoints, problem.seam_reference)
    q_seed = np.asarray(opts.q_seed) if opts.q_seed is not None else problem.q_seed()
    choice = choose_branch(model, task, q_seed, opts, problem.window)
    start, rotation = choice.taught, choice.rotation
    warm = mirror_compensation(model, task, start.q, rotation)
    return problem, opts, model, task, warm


@pytest.mark.parametrize(("name", "n_weld"), CASES)
def test_coarse_to_fine_is_the_full_nlp_plan(name: str, n_weld: int | None) -> None:
    problem, opts, model, task, warm = _setup(name, n_weld)
    assert len(task) - task.n_start > opts.coarse_waypoints  # the coarse path is exercised
    fast = solve_plan(model, task, problem.window, warm, replace(opts, solver="coarse"))
    full = solve_plan(model, task, problem.window, warm, replace(opts, solver="full"))
    assert fast.method == "coarse" and full.method == "full"
    # Every row of the fine NLP holds at the same tolerance as IPOPT's, for both.
    assert fast.nlp.violations(fast.x, ROW_TOL) == []
    assert full.nlp.violations(full.x, ROW_TOL) == []
    lo, hi = model.robot.description.lower, model.robot.description.upper
    assert np.all((fast.q >= lo) & (fast.q <= hi))
    # The fine NLP's objective within 0.5 % of its optimum (the fast path cannot beat it).
    gap = (fast.objective - full.objective) / abs(full.objective)
    assert -1e-6 < gap < 5e-3, gap
    # The independent numeric verification passes for both, every declared row included.
    for sol in (fast, full):
        ver = verify_plan(model, task, problem.window, sol.q, sol.offsets,
                          opts.force_uncertainty, opts.robust_hard,
                          opts.joint_step * (1 + 1e-6), opts.kappa_max, opts.length_scale,
                          options=opts, reference_offsets=warm.offsets)
        assert ver.feasible and ver.skipped == (), ver.messages


@pytest.mark.parametrize("speed", [None, 0.1e-3])
def test_offset_interpolation_keeps_the_fine_offset_rows(speed: float | None) -> None:
    """Where the coarse offsets leave the mirror faster than the fine rows allow, the fine
    offsets still change by at most |mirror change| + allowance per fine link, the allowance
    being the fine NLP's: offset_rate x travel, or, with a tight offset speed (0.1 mm/s at
    3 mm/s travel: the speed binds on every weld link), offset_speed x time."""
    _, opts, _, task, warm = _setup("zk500_table6_seam", 200)
    if speed is not None:
        opts = replace(opts, offset_speed=speed)
    _, idx = subsample_task(task, 20)
    rng = np.random.default_rng(3)
    m = warm.offsets
    # Coarse offsets that use the coarse rows' whole allowance |dm| + rate S, with random sign.
    ds, dt = task.link_travel(), task.link_times()
    allowance = np.repeat((opts.offset_rate * ds + np.where(
        ds <= 1e-12, opts.offset_speed_stationary * dt, 0.0))[:, None], 3, 1)
    if speed is not None:
        allowance = np.minimum(allowance, np.where(ds <= 1e-12, np.inf, speed * dt)[:, None])
        assert np.all(allowance[task.n_start:] < opts.offset_rate * ds[task.n_start:, None])
    cum = np.vstack([np.zeros((1, 3)), np.cumsum(allowance, axis=0)])
    o_c = m[idx].copy()
    for j in range(task.n_start, len(idx) - 1):
        a, b = idx[j], idx[j + 1]
        allow = np.abs(m[b] - m[a]) + (cum[b] - cum[a])
        o_c[j + 1] = o_c[j] + rng.choice([-1.0, 1.0], 3) * allow
    fine = interpolate_offsets(task, idx, o_c, m, allowance)
    np.testing.assert_allclose(fine[idx], o_c, atol=1e-12)
    bound = np.abs(np.diff(m, axis=0)) + allowance
    assert np.all(np.abs(np.diff(fine, axis=0))[task.n_start:] <= bound[task.n_start:] + 1e-12)
    # The fine NLP's own offset rows hold: the interpolation used its declared allowance.
    nlp = build_plan_nlp(ElastostaticModel(load_robot("zk500")), task, WeldWindow(), warm.q,
                         warm.offsets, opts, compile_c=False, load_steps=np.diff(m, axis=0))
    np.testing.assert_array_equal(nlp.links.allowance["offsets"], allowance)
    x = nlp.stack({"q": warm.q, "offsets": fine * 1e3, "sigma": 0.0, "tolerated": 0.0})
    assert not [v for v in nlp.violations(x, ROW_TOL) if v[0].startswith("offset_")]


def test_the_fine_projections_newton_steps_reuse_the_pose_they_returned(planned_result,
                                                                        monkeypatch) -> None:
    """project_fine moves only the targets between its Newton solves: the next solve starts
    from the evaluation of the joint values the last one returned (``_newton_ik``'s ``last``)
    and returns the joint values and evaluation of one that evaluates them again, bit for bit
    (issue 41); a changed array or other orientations are evaluated afresh."""
    from rfsw_plan.planning import coarse
    from rfsw_plan.process.frames import tcp_orientation

    res = planned_result("zk500_table6_seam")
    model, task = res.model, res.task
    R = tcp_orientation(task.frames, res.tool_rotation)
    T = model.robot.batch_fk_jacobian(res.q)[0]
    q1, ok, last = coarse._newton_ik(model, T[:, :3, 3] + 1e-5, R, res.q)
    assert ok and last is not None
    moved = T[:, :3, 3] - 2e-5
    calls: list[int] = []
    fk = model.robot.batch_fk_jacobian
    monkeypatch.setattr(model.robot, "batch_fk_jacobian", lambda Q: calls.append(1) or fk(Q))
    fresh = coarse._newton_ik(model, moved, R, q1)
    n_fresh, calls[:] = len(calls), []
    again = coarse._newton_ik(model, moved, R, q1, last=last)
    assert fresh[1] and len(calls) == n_fresh - 1
    assert fresh[0].tobytes() == again[0].tobytes()
    assert fresh[2] is not None and again[2] is not None
    assert all(a.tobytes() == b.tobytes() for a, b in zip(fresh[2], again[2], strict=True))
    calls.clear()
    coarse._newton_ik(model, moved, R.copy(), q1, last=last)  # other orientations
    assert len(calls) == n_fresh
    other = q1 + 1e-9  # other joint values
    calls.clear()
    coarse._newton_ik(model, moved, R, other)
    n_other, calls[:] = len(calls), []
    coarse._newton_ik(model, moved, R, other, last=last)
    assert len(calls) == n_other
