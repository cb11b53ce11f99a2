"""The NLP's row families are declared once, by name: the NLP, the fine projection and the
independent verification all follow the declarations (rfsw_plan.planning.rows)."""

from __future__ import annotations

from collections import OrderedDict
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.planning import nlp as nlp_module
from rfsw_plan.planning import rows, verify
from rfsw_plan.planning.layout import variable_layout
from rfsw_plan.planning.nlp import build_plan_nlp, solve_plan_nlp
from rfsw_plan.planning.rows import LINK_ROWS, POINT_ROWS, LinkRows, PointRows
from rfsw_plan.planning.verify import ROW_CHECKS, verify_plan
from rfsw_plan.process.plan_options import PlanOptions
from rfsw_plan.process.window import WeldWindow

DOCS = Path(__file__).resolve().parents[1] / "docs" / "dev" / "nlp-rows.md"


@pytest.fixture(scope="module")
def setup(zk500_case):
    model, task, _, mirror = zk500_case(7)
    return model, task, mirror, np.diff(mirror.offsets, axis=0)


def test_every_family_has_its_independent_check_or_says_why_not():
    families = (*POINT_ROWS, *LINK_ROWS)
    for f in families:
        assert (f.check in ROW_CHECKS) != bool(f.unchecked), f.name
    # Rows without a check only define auxiliary variables of the objective; a new one is a
    # decision, not an omission.
    assert {f.name for f in families if f.check is None} == {
        "stiffness_cap", "tolerated", "tolerated_link"}
    # The offset rate, not checked before, and the new offset speed have their checks.
    assert rows.checks()["offset_rate"] == "offset_rate"
    assert rows.checks()["offset_speed"] == "offset_speed"


def test_a_declaration_without_check_or_reason_is_refused(monkeypatch):
    with pytest.raises(TypeError, match="exactly one of check"):
        PointRows("toy", ("toy",), lambda s: s.error, lambda b: ((0.0, 1.0),))
    toy = LinkRows("toy", "q", lambda n: tuple(f"toy_q{j}" for j in range(n)),
                   lambda c: np.full(len(c.travel), 1.0), check="no_such_check")
    monkeypatch.setattr(rows, "LINK_ROWS", (*LINK_ROWS, toy))
    with pytest.raises(TypeError, match=r"toy.*no_such_check"):
        verify._require_declared_checks()


def test_built_nlp_has_the_declared_rows_in_order(setup):
    model, task, mirror, steps = setup
    nlp = build_plan_nlp(model, task, WeldWindow(), mirror.q, mirror.offsets, PlanOptions(),
                         compile_c=False, load_steps=steps)
    K, n = len(task), model.robot.nq
    per_point = [label for f in POINT_ROWS for label in f.labels]
    per_link = sum(variable_layout(n).width(v) for v in rows.link_variables())
    # lateral (window, robust, tolerated) and the rest of the weld envelope (depth, surface,
    # tilt, travel speed in and out) and the standstill (lateral, depth): 22 rows per waypoint.
    assert len(per_point) == 22 and per_link == n + 4
    names = nlp.constraint_names()
    # ... then n + 4 link rows per link, then the travel_speed link sum of every link.
    assert len(names) == nlp.lbg.size == 22 * K + (n + 4) * (K - 1) + (K - 1)
    assert names[:22] == [f"{c}[0]" for c in per_point]
    link0 = names[22 * K:22 * K + per_link]
    # The default offset speed never binds here (0.2 mm/mm x 3 mm/s < 10 mm/s): the offset
    # rows are the offset-rate rows, with the bounds they had before the speed was declared.
    assert link0 == [f"joint_step_q{j + 1}[0]" for j in range(n)] + [
        "offset_rate_lat[0]", "offset_rate_norm[0]", "offset_rate_along[0]",
        "tolerated_link[0]"]
    hi = nlp.ubg[22 * K:22 * K + (n + 4) * (K - 1)].reshape(K - 1, n + 4)
    o = PlanOptions()
    expected = (o.offset_rate * task.link_travel() * 1e3 + 1e-6)[:, None] + np.abs(steps) * 1e3
    np.testing.assert_array_equal(hi[:, n:n + 3], expected)
    np.testing.assert_array_equal(hi[:, :n], o.joint_step)


def test_offset_speed_row_bounds_the_offset_change_in_time(setup):
    """The new row family: |delta o| <= offset_speed x time (+ the load's own step) while
    moving. Tight, it binds (its rows carry its name and bound), the plan keeps it, and the
    independent check in verify catches a plan made without it."""
    model, task, mirror, steps = setup
    w = WeldWindow()
    # 0.002 mm/s: 0.013 mm per 6.3 s link, below what the plan takes (the depth row leaves
    # the normal offset 0.039 mm of its own; before that row, 0.25 mm)
    speed = 2e-6
    tight = PlanOptions(offset_speed=speed)
    nlp = build_plan_nlp(model, task, w, mirror.q, mirror.offsets, tight, compile_c=False,
                         load_steps=steps)
    K, n = len(task), model.robot.nq
    link0 = nlp.constraint_names()[22 * K:22 * K + n + 4]
    assert link0[n:n + 3] == ["offset_speed_lat[0]", "offset_speed_norm[0]",
                              "offset_speed_along[0]"]
    dt = np.diff(task.time)
    bound = (speed * dt * 1e3 + 1e-6)[:, None] + np.abs(steps) * 1e3
    np.testing.assert_allclose(nlp.ubg[22 * K:22 * K + (n + 4) * (K - 1)].reshape(
        K - 1, n + 4)[:, n:n + 3], bound,
                               rtol=1e-15)
    np.testing.assert_allclose(nlp.links.allowance["offsets"], np.repeat(
        (speed * dt)[:, None], 3, 1), rtol=1e-15)
    sol = solve_plan_nlp(nlp)
    assert sol.success, sol.status
    excess = np.abs(np.diff(sol.offsets, axis=0)) - np.abs(steps)
    assert np.all(excess <= speed * dt[:, None] + 2e-9)
    assert np.max(excess) > 0.99 * speed * dt[0]  # it binds
    ok = verify_plan(model, task, w, sol.q, sol.offsets, 0.2, options=tight,
                     reference_offsets=mirror.offsets)
    assert ok.feasible, ok.messages
    assert ok.skipped == ()
    # Without the bound the plan steps the normal offset by more than the load asks:
    # the independent check, given the tight speed, names the row and the waypoint.
    free = solve_plan_nlp(build_plan_nlp(model, task, w, mirror.q, mirror.offsets,
                                         PlanOptions(), compile_c=False, load_steps=steps))
    bad = verify_plan(model, task, w, free.q, free.offsets, 0.2, options=tight,
                      reference_offsets=mirror.offsets)
    assert not bad.feasible and bad.binding == "offset_speed_norm"
    assert bad.binding_margin < -0.01e-3  # 0.026 mm with the depth row (0.25 before it)
    assert any("offset_speed_norm: the offset changes" in m for m in bad.messages)
    # ... and the same plan passes the defaults, under which it was made.
    assert verify_plan(model, task, w, free.q, free.offsets, 0.2, options=PlanOptions(),
                       reference_offsets=mirror.offsets).feasible


def test_default_offset_speed_is_inactive_on_the_bundled_problems():
    """Welding at travel speed v, the offset-rate rows allow offset_rate x v; the default
    offset speed (10 mm/s) is above that on every bundled problem, so it changes no plan."""
    from rfsw_plan.process.problem import bundled_problem_names, load_problem

    names = bundled_problem_names()
    assert len(names) >= 8
    for name in names:
        pb = load_problem(name)
        o = pb.planning
        assert o.offset_speed == 10e-3
        assert o.offset_rate * pb.process.travel_speed < 0.5 * o.offset_speed, name


def test_a_new_point_row_is_one_declaration(monkeypatch, setup):
    """A toy row family appended to the declarations (normal pin error within +-0.5 mm) is
    built, bounded, named, split by name and differentiated correctly, with nothing else
    touched."""
    model, task, mirror, steps = setup
    toy = PointRows("toy_depth", ("toy_depth",), lambda s: s.normal_error,
                    lambda b: ((-0.5, 0.5),), check="window")
    monkeypatch.setattr(rows, "POINT_ROWS", (*POINT_ROWS, toy))
    for cache in ("_POINT_CACHE", "_SOLVER_CACHE", "_EVAL_CACHE"):
        monkeypatch.setattr(nlp_module, cache, OrderedDict())
    nlp = build_plan_nlp(model, task, WeldWindow(), mirror.q, mirror.offsets, PlanOptions(),
                         compile_c=False, load_steps=steps)
    K, n = len(task), model.robot.nq
    names = nlp.constraint_names()
    assert len(names) == nlp.lbg.size == 23 * K + (n + 4) * (K - 1) + (K - 1)
    at = [names.index(f"toy_depth[{k}]") for k in range(K)]
    assert at == [23 * k + 22 for k in range(K)]
    assert np.all(nlp.lbg[at] == -0.5) and np.all(nlp.ubg[at] == 0.5)
    x = nlp.x0
    g_rows, terms = nlp.point_rows(x)
    np.testing.assert_array_equal(g_rows["toy_depth"], terms["normal_error"])
    _, g = nlp.evaluate(x)
    np.testing.assert_allclose(g[at], terms["normal_error"][:, 0], atol=1e-12)
    # The stiffness cap still meets c_max, and IPOPT's assembled Jacobian is the NLP's own.
    import casadi as ca

    X = ca.MX.sym("x", x.size)
    _, gs = nlp.nlp_function(X, nlp.p)
    xr = x + np.random.default_rng(2).normal(0, 1e-2, x.size)
    J_ref = np.array(ca.densify(ca.Function("j", [X], [ca.jacobian(gs, X)])(xr)))
    J = np.array(ca.densify(nlp.solver.get_function("nlp_jac_g")(xr, nlp.p)[1]))
    np.testing.assert_allclose(J, J_ref, rtol=1e-9, atol=1e-9)


def test_the_docs_page_names_every_family():
    text = DOCS.read_text()
    for f in (*POINT_ROWS, *LINK_ROWS):
        assert f"`{f.name}`" in text, f.name


def test_offset_speed_option_reads_in_mm_per_s_and_refuses_nonsense():
    from rfsw_plan.exceptions import InputError
    from rfsw_plan.process.plan_options import options_from_table

    assert options_from_table({"offset_speed_mm_s": 2.5}).offset_speed == pytest.approx(2.5e-3)
    with pytest.raises(InputError, match="offset_speed_mm_s"):
        options_from_table({"offset_speed_mm_s": 0.0})
    with pytest.raises(InputError, match="offset_speed"):
        PlanOptions(offset_speed=-1.0)


def test_travel_speed_rows_bound_the_pin_travel_along_the_seam_chord(setup):
    """The travel_speed rows of the two ends of each weld link add up to the pin's travel
    along the seam chord less the seam's travel (scaled by h_min / h), the turn of the chord
    included: on a seam bent sideways, the independent check's deviation (numeric model,
    chords of the seam points) is what the rows hold, and a speed tolerance below it fails
    the check on that link."""
    from dataclasses import replace

    from rfsw_plan.planning.nlp import shortest_weld_link

    model, task, mirror, steps = setup
    fr, m = task.frames, task.n_start
    # The weld bent sideways along l: 2 mm at its end (radius about 0.2 m at 6.3 mm links).
    bend = np.zeros(len(task))
    bend[m:] = 2e-3 * ((fr.s[m:] - fr.s[m]) / (fr.s[-1] - fr.s[m])) ** 2
    bent = replace(task, frames=replace(fr, p=fr.p + bend[:, None] * fr.l),
                   target=task.target + bend[:, None] * fr.l)
    w = WeldWindow()
    nlp = build_plan_nlp(model, bent, w, mirror.q, mirror.offsets, PlanOptions(),
                         compile_c=False, load_steps=steps)
    h_min = shortest_weld_link(bent)
    names = nlp.constraint_names()
    # The two rows at each waypoint are free; each weld link's sum of them is bounded.
    i_in, i_out = names.index(f"travel_speed_in[{m + 1}]"), names.index(f"travel_speed_out[{m}]")
    assert nlp.lbg[i_in] == nlp.lbg[i_out] == -np.inf and nlp.ubg[i_in] == np.inf
    i_sum = names.index(f"travel_speed[{m}]")
    assert nlp.ubg[i_sum] == pytest.approx(0.5 * w.speed_tol * h_min * 1e3)
    assert nlp.lbg[i_sum] == -nlp.ubg[i_sum]
    g_rows, _ = nlp.point_rows(nlp.x0)
    ts = g_rows["travel_speed"]  # (K, 2): in, out [mm]
    _, g = nlp.evaluate(nlp.x0)
    assert g[i_sum] == pytest.approx(ts[m + 1, 0] + ts[m, 1], abs=1e-12)
    h = np.diff(fr.s)[m:]
    rows_dev = (ts[m + 1:, 0] + ts[m:-1, 1]) * 1e-3 * h / h_min  # [m]
    # Independently: the numeric pin, the chords of the bent seam points.
    pred = verify.predict(model, bent, mirror.q, 0.0)
    q = pred.T[m:, :3, 3] + pred.dX[:, :3][m:] - bent.frames.p[m:]
    dp = np.diff(bent.frames.p[m:], axis=0)
    chord = np.linalg.norm(dp, axis=1)
    dev = np.einsum("ki,ki->k", np.diff(q, axis=0), dp / chord[:, None]) + chord - h
    np.testing.assert_allclose(rows_dev, dev, atol=1e-9)
    assert np.max(np.abs(dev) / h) > 1e-4  # the bend moves the pin's travel
    # The check judges the same quantity: a tolerance below the worst link fails it there.
    k = int(np.argmax(np.abs(dev) / h))
    tight = replace(w, speed_tol=0.5 * float(np.abs(dev[k]) / h[k]))
    bad = verify_plan(model, bent, tight, mirror.q, mirror.offsets, 0.2)
    check = verify.ROW_CHECKS["travel_speed"](verify.CheckInput(
        model=model, task=bent, window=tight, q=mirror.q, offsets=mirror.offsets,
        prediction=pred, robust_hard=False, joint_step=None, kappa_max=np.inf, options=None,
        reference_offsets=None))
    assert check is not None and check[0][0] == "travel_speed"
    assert check[0][1][m + k] == pytest.approx(-tight.speed_tol, rel=1e-6)
    assert not bad.feasible and any("travel_speed" in msg for msg in bad.messages)
