"""The planning NLP: inspectable build, exact derivatives, CasADi vs numeric model, solve."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.planning.nlp import (
    ABS_EPS,
    GLOBALS,
    POINT_CONSTRAINTS,
    build_plan_nlp,
    n_par,
    nlp_prediction,
    point_functions,
    point_layout,
    solve_plan_nlp,
)
from rfsw_plan.planning.rows import link_sum_families
from rfsw_plan.planning.verify import predict, verify_plan
from rfsw_plan.process.plan_options import PlanOptions
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.robot.kinematics import load_robot


@pytest.fixture(scope="module")
def setup(zk500_case):
    model, task, taught, mirror = zk500_case(7)
    nlp = build_plan_nlp(model, task, WeldWindow(), mirror.q, mirror.offsets, PlanOptions(),
                         compile_c=False)
    return model, task, taught, mirror, nlp


def test_build_is_inspectable_without_solving(setup):
    _, task, _, mirror, nlp = setup
    K, n = len(task), 6
    assert nlp.x0.shape == (K * (n + 5) + 1,)
    assert len(nlp.constraint_names()) == nlp.lbg.shape[0] == nlp.ubg.shape[0]
    assert nlp.constraint_names()[6] == "window[0]"
    parts = nlp.unpack(nlp.x0)
    np.testing.assert_allclose(parts["q"], mirror.q)
    np.testing.assert_allclose(parts["offsets"], mirror.offsets)
    # The mirror warm start satisfies every constraint (up to the IK tolerance).
    assert all(v < 1e-3 for _, v in nlp.violations(nlp.x0, 1e-9))


def test_casadi_prediction_matches_numeric_model(setup):
    model, task, taught, _, nlp = setup
    x = nlp.pack(taught.q, np.zeros((len(task), 3)))
    ours = nlp_prediction(nlp, x)
    pred = predict(model, task, taught.q, 0.2)
    np.testing.assert_allclose(ours[:, 0], pred.e_lat, atol=1e-10)
    np.testing.assert_allclose(ours[:, 1], pred.e_norm, atol=1e-10)
    np.testing.assert_allclose(ours[:, 2], pred.e_along, atol=1e-10)
    # Untouched by offsets, the loaded pin lags the TCP along the track (traverse force).
    assert np.all(pred.e_along < -1e-3)
    _, terms, _ = nlp.point_values(x)
    # worst case: the smooth |.| over-estimates the numeric r by at most 3 eps (3 components)
    over = terms[:, 1] * 1e-3 - pred.worst
    assert np.all(over >= 0) and np.all(over <= 3 * ABS_EPS * 1e-3)
    np.testing.assert_allclose(1e6 / terms[:, 0], pred.lateral_stiffness, rtol=1e-9)


@pytest.mark.parametrize(("robot_name", "coupled"), [
    ("zk500", False), ("kuka_kr600_r2830", False),
    ("zk500", True)])  # the coupled axial law's depth centring term
def test_point_derivatives_match_finite_differences(robot_name, coupled):
    model = ElastostaticModel(load_robot(robot_name))
    pf = point_functions(model, compile_c=False, coupled=coupled)
    rng = np.random.default_rng(4)
    n = model.robot.nq
    w = np.concatenate([rng.uniform(-1, 1, n), rng.normal(0, 2, 3), rng.uniform(0, 1, 2)])
    q = w[:n]
    R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    wrench = np.concatenate([rng.normal(0, 2e3, 3), rng.normal(0, 50, 3)])
    par = point_layout(n).pack(1, {
        "target": model.robot.fk(q)[:3, 3] + rng.normal(0, 1e-3, 3),  # target near the TCP
        "t": R[:, 0], "l": R[:, 1], "n": R[:, 2],  # orthonormal
        "wrench": wrench, "force_spread": 0.2 * np.abs(R.T @ wrench[:3]),
        "correction": rng.normal(0, 0.1, 3), "det_sign": 1.0, "det_floor": 0.01,
        "det_value": 0.3, "q_lin": q + 0.01, "det_grad": rng.normal(0, 0.1, n),
        "weld": 1.0,  # weld waypoint: the stiffness-cap row is on
        "depth_on": 1.0,  # in the plate: the depth row is on
        "surface_on": 0.0,
        "standing": 1.0, "stand_at": -0.275,  # standing in the plate: the standstill row is on
        "standing_full": 1.0,  # ... at full depth: the standing depth row is on
        "depth_at": 0.15,  # the coupled law's depth centre (unused without it)
        # a weld waypoint between two links: the seam chords (scaled) and their offsets [mm]
        "travel_in": rng.normal(0, 0.5, 3), "travel_out": rng.normal(0, 0.5, 3),
        "travel_at": rng.normal(0, 1e-3, 2),
        "t_along": [0.0, 0.9998, 0.02],  # the in-plane tangent (the frame's t tilted)
    })[0]
    assert par.size == n_par(n)
    glob = GLOBALS.pack(1, {
        "w_stiffness": 1, "w_worst": 1, "w_robust": 10, "w_centre": 0.1, "w_depth": 0.1,
        "compliance_ref": 3.0, "centre": -0.275, "half_width": 0.975, "inv_k": 0.1,
        "w_proximity": 1e-3, "mean_share": 0.5})[0]
    lam = rng.normal(0, 1, len(POINT_CONSTRAINTS))
    J = np.asarray(pf.jac(w, par))
    grad = np.asarray(pf.grad(w, par, glob)).ravel()
    H = np.asarray(pf.hess(w, par, glob, 0.7, lam))
    H = np.triu(H) + np.triu(H, 1).T
    h = 1e-6

    def g_of(x):
        return np.asarray(pf.fg(x, par, glob)[1]).ravel()

    def phi_of(x):
        return float(pf.fg(x, par, glob)[0])

    def lag_grad(x):
        return 0.7 * np.asarray(pf.grad(x, par, glob)).ravel() + np.asarray(pf.jac(x, par)).T @ lam

    for i in range(len(w)):
        e = np.zeros_like(w)
        e[i] = h
        np.testing.assert_allclose(J[:, i], (g_of(w + e) - g_of(w - e)) / (2 * h), rtol=1e-5,
                                   atol=1e-5)
        assert grad[i] == pytest.approx((phi_of(w + e) - phi_of(w - e)) / (2 * h), rel=1e-5,
                                        abs=1e-6)
        np.testing.assert_allclose(H[:, i], (lag_grad(w + e) - lag_grad(w - e)) / (2 * h),
                                   rtol=1e-4, atol=1e-4)


def test_solve_keeps_verified_error_in_window(setup):
    model, task, taught, _, nlp = setup
    sol = solve_plan_nlp(nlp)
    assert sol.success, sol.status
    w = WeldWindow()
    ver = verify_plan(model, task, w, sol.q, sol.offsets, 0.2, joint_step=0.35,
                      kappa_max=200)
    assert ver.feasible, ver.messages
    # The predicted pin is on every seam point along the track; the along-track offset is
    # the lag the traverse force winds up (about 4.7 mm on the ZK-500).
    assert np.max(np.abs(ver.along_error)) < 1e-9
    fr, o = task.frames, sol.offsets
    t_dot = np.einsum("ki,ki->k", fr.t, ver.prediction.dX[:, :3] + o[:, :1] * fr.l
                      + o[:, 1:2] * fr.n)
    np.testing.assert_allclose(o[:, 2], -t_dot, atol=1e-9)  # o_along t cancels the lag
    assert np.min(sol.offsets[:, 2]) > 3e-3
    e = ver.prediction.e_lat
    assert np.all(e >= w.lower + 1e-4 - 1e-9) and np.all(e <= w.upper - 1e-4 + 1e-9)
    # Uncompensated the same waypoints are ~4.9 mm off (seed 001).
    e0 = predict(model, task, taught.q, 0.0).e_lat
    assert np.min(e0) > 4.0e-3 and np.max(e0) == pytest.approx(4.9e-3, abs=0.1e-3)
    # The robust excess sigma is what leaves the window under +-20 % force.
    r = ver.prediction.worst
    # (the NLP's smooth worst case is conservative by at most 3 eps)
    exact = np.maximum(0, np.maximum(w.lower - (e - r), e + r - w.upper))
    assert np.all(sol.sigma >= exact - 1e-6)
    assert np.all(sol.sigma <= exact + 3 * ABS_EPS * 1e-3 + 1e-6)
    assert np.max(sol.sigma) > 1e-4  # +-20 % really leaves the window somewhere


def test_the_along_track_row_keeps_the_pin_at_the_weld_speed_in_the_plate(planned_result):
    """The along-track error is measured along the seam tangent in the plate's plane
    (``along_tangents``: unit, normal to the plate, 2 deg from the frame tangent, which tilts
    with the tool on zk500_table6_seam). There the coupled axial law centres the depth along
    the tilted tool axis; on the frame tangent, perpendicular to that axis, the along_track row
    let the pin lag by up to 0.20 % of the weld speed; in the plate it keeps the written pin
    within 0.05 % (0.013 % measured)."""
    from rfsw_plan.planning.verify import along_tangents

    res = planned_result("zk500_table6_seam")
    task = res.task
    tp = along_tangents(task)
    np.testing.assert_allclose(np.linalg.norm(tp, axis=1), 1.0, atol=1e-12)
    assert np.max(np.abs(np.einsum("ki,ki->k", tp, task.plate_normal))) < 1e-12
    tilt = np.rad2deg(np.arccos(np.clip(np.einsum("ki,ki->k", tp, task.frames.t), -1, 1)))
    np.testing.assert_allclose(tilt, 2.0, atol=1e-6)
    lo, hi = res.summary()["envelope"]["pin_speed_deviation_pct"]
    assert max(-lo, hi) < 0.05, (lo, hi)


def test_robust_hard_reports_infeasible_when_stiffness_cannot_buy_the_margin(setup):
    model, task, _, mirror, _ = setup
    opts = PlanOptions(robust_hard=True, max_iter=60)
    nlp = build_plan_nlp(model, task, WeldWindow(), mirror.q, mirror.offsets, opts,
                         compile_c=False)
    sol = solve_plan_nlp(nlp)
    # +-20 % of seed 001's forces moves the pin by ~1.2 mm > half the window (0.975 mm).
    assert not sol.success
    ver = verify_plan(model, task, WeldWindow(), sol.q, sol.offsets, 0.2, robust_hard=True)
    assert not ver.feasible


def test_kr600_stiffness_weight_turns_the_tool_and_raises_min_lateral_stiffness():
    """Issue 4 §8 on the bundled kr600_curved_seam (offset FSW head, problem settings): when the
    user trades robustness for stiffness (``robust_first = false``), the stiffness objective
    turns the tool about its axis and raises the weakest waypoint's lateral stiffness, compared
    with a zero weight; both plans verify."""
    from rfsw_plan.planning.api import options_from_problem, plan
    from rfsw_plan.process.problem import load_problem

    pb = load_problem("kr600_curved_seam")
    default = PlanOptions().w_stiffness
    assert default > 0 and options_from_problem(pb).w_stiffness == default
    out = {w: plan(pb, options_from_problem(pb, {"w_stiffness": w, "robust_first": False}),
                   spacing=20e-3)
           for w in (0.0, default)}
    for r in out.values():
        assert r.verification.feasible and r.baselines[2].inside_fraction == 1.0
    weld = out[0.0].task.weld
    turn = np.abs(out[default].tool_rotation[weld] - out[0.0].tool_rotation[weld])
    turn = np.minimum(turn % (2 * np.pi), 2 * np.pi - turn % (2 * np.pi))
    assert np.max(turn) > np.deg2rad(10.0)
    k0 = out[0.0].baselines[2].min_lateral_stiffness
    k1 = out[default].baselines[2].min_lateral_stiffness
    assert k1 > 1.02 * k0


def test_seam_reference_taught_ignores_load_independent_and_sensor_only_effects():
    """Issue 4 / seam reference: the planner pushes the modelled wrench through
    process_deflection. With payload gravity (load independent) and a sensor misalignment
    (sensor only) in the model, a taught seam plans exactly as the base model; an absolute seam
    also sees the gravity sag, and the plan compensates it."""
    from dataclasses import replace

    from rfsw_plan.planning.api import plan
    from rfsw_plan.process.problem import load_problem

    pb = load_problem("zk500_table6_seam")
    assert pb.seam_reference == "taught"
    base = ElastostaticModel(load_robot("zk500"))
    full = base.with_effect("payload_gravity").with_effect(
        "sensor_misalignment", {"phi_x": 0.05, "phi_z": -0.03})
    r0, r1 = plan(pb, model=base), plan(pb, model=full)
    assert r1.task.reference == "taught"
    np.testing.assert_allclose(r1.e_lat, r0.e_lat, atol=1e-9)
    np.testing.assert_allclose(r1.q, r0.q, atol=1e-9)
    assert r1.skipped_effects == ("payload_gravity",)  # sensor-only: dropped, not corrected
    # The same joints on an absolute seam: e_lat moves by the lateral gravity sag.
    K = len(r1.task)
    sag = full.process_deflection(r1.q, np.zeros((K, 6)), "absolute")[:, :3]
    assert np.min(np.linalg.norm(sag, axis=1)) > 0.5e-3
    lat_sag = np.einsum("ki,ki->k", r1.task.frames.l, sag)
    e_abs = predict(full, replace(r1.task, reference="absolute"), r1.q).e_lat
    np.testing.assert_allclose(e_abs - r1.e_lat, lat_sag, atol=1e-12)
    assert np.max(np.abs(lat_sag)) > 0.1e-3
    # Planned on the absolute seam, the lateral offsets take the sag out.
    r2 = plan(replace(pb, seam_reference="absolute"), model=full)
    assert r2.task.reference == "absolute" and r2.verification.feasible
    np.testing.assert_allclose(r2.offsets[:, 0] - r1.offsets[:, 0], -lat_sag,
                               atol=0.05 * np.max(np.abs(lat_sag)))


def test_assembled_constraint_jacobian_matches_the_nlp_definition(setup):
    """IPOPT's Jacobian (per-waypoint blocks + the constant link rows) is the derivative of
    the NLP's own constraint function (CasADi's AD through the virtual machine)."""
    import casadi as ca

    nlp = setup[4]
    X = ca.MX.sym("x", nlp.x0.size)
    _, g = nlp.nlp_function(X, nlp.p)
    x = nlp.x0 + np.random.default_rng(7).normal(0, 1e-2, nlp.x0.size)
    J_ref = np.array(ca.densify(ca.Function("j", [X], [ca.jacobian(g, X)])(x)))
    J = np.array(ca.densify(nlp.solver.get_function("nlp_jac_g")(x, nlp.p)[1]))
    assert J.shape == J_ref.shape
    np.testing.assert_allclose(J, J_ref, rtol=1e-9, atol=1e-9)


def test_assembled_hessian_matches_the_nlp_definition(setup):
    """IPOPT's Hessian of the Lagrangian (per-waypoint blocks, the smoothing term, and the
    link sums' multipliers passed to the point rows they add) is the second derivative of the
    NLP's own objective and constraints (CasADi's AD through the virtual machine)."""
    import casadi as ca

    nlp = setup[4]
    X = ca.MX.sym("x", nlp.x0.size)
    f, g = nlp.nlp_function(X, nlp.p)
    rng = np.random.default_rng(8)
    x = nlp.x0 + rng.normal(0, 1e-2, nlp.x0.size)
    lam = rng.normal(0, 1, nlp.lbg.size)
    L = 0.7 * f + ca.dot(ca.DM(lam), g)
    H_ref = np.array(ca.densify(ca.Function("h", [X], [ca.hessian(L, X)[0]])(x)))
    H = np.array(ca.densify(nlp.solver.get_function("nlp_hess_l")(x, nlp.p, 0.7, lam)))
    np.testing.assert_allclose(np.triu(H), np.triu(H_ref), rtol=1e-8, atol=1e-8)


def test_single_thread_blas_is_scoped():
    from rfsw_plan.planning.casadi_ import casadi_blas as _casadi_blas
    from rfsw_plan.planning.casadi_ import single_thread_blas

    lib = _casadi_blas()
    if lib is None:
        pytest.skip("CasADi without its bundled OpenBLAS")
    lib.openblas_set_num_threads(2)
    with single_thread_blas():
        assert lib.openblas_get_num_threads() == 1
    assert lib.openblas_get_num_threads() == 2


#: How the docstrings (and the rows page) write the NLP's sizes, and which size each states:
#: ``var``: variables per waypoint - n, ``link``: rows per link - n, ``point``: rows per
#: waypoint, ``terms``: terms of the point function.
SHAPE_PATTERNS = (
    (r"K \(n \+ (\d+)\) \+ 1", "var"),
    (r"\(n \+ (\d+),", "var"),
    (r", n \+ (\d+)\)", "var"),
    (r"n \+ (\d+) variables", "var"),
    (r"g \((\d+),\)", "point"),
    (r"g \(K, (\d+)\)", "point"),
    (r"\((\d+), n \+ \d+\)", "point"),
    (r"(\d+) K \+ \(n \+ \d+\)", "point"),
    (r"\((\d+) K,\)", "point"),
    (r"\((\d+) rows", "point"),
    (r"\(n \+ (\d+)\)\(K - 1\)", "link"),
    (r"\(K - 1\) \(n \+ (\d+)\)", "link"),
    (r"n \+ (\d+) rows", "link"),
    (r"terms \((\d+),\)", "terms"),
    (r"terms \(K, (\d+)\)", "terms"),
)


def _documented_shapes() -> list[tuple[str, str, int]]:
    """(where, kind, number) for every size the planner's docstrings and rows page state."""
    import ast
    import re
    from pathlib import Path

    import rfsw_plan.planning as planning

    root = Path(planning.__file__).parent
    texts = []
    for name in ("nlp", "coarse", "rows", "layout", "verify"):
        tree = ast.parse((root / f"{name}.py").read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef):
                doc = ast.get_docstring(node)
                if doc:
                    texts.append((f"{name}.{getattr(node, 'name', '<module>')}", doc))
    page = root.parents[1] / "docs" / "dev" / "nlp-rows.md"
    texts.append(("docs/dev/nlp-rows.md", page.read_text()))
    found = []
    for where, text in texts:
        flat = " ".join(text.split())
        for pattern, kind in SHAPE_PATTERNS:
            found += [(where, kind, int(m)) for m in re.findall(pattern, flat)]
    return found


def test_documented_shapes_match_the_built_nlp(setup):
    """Every size the docstrings state (variables per waypoint, rows per waypoint and per
    link, terms) is the built NLP's: the next stale ``g (12,)`` or ``n + 4`` fails here."""
    from rfsw_plan.planning.layout import TERMS

    model, task, _, _, nlp = setup
    K, n = len(task), model.robot.nq
    point = len(POINT_CONSTRAINTS)
    sums = len(link_sum_families())  # the link sums (travel_speed), one per link each
    link = (nlp.lbg.size - point * K) // (K - 1) - sums
    actual = {"var": nlp.n_w - n, "point": point, "link": link - n, "terms": TERMS.size}
    assert nlp.x0.size == K * nlp.n_w + 1
    found = _documented_shapes()
    assert len(found) >= 12, found  # the shapes are still written where this test looks
    wrong = [(where, kind, v, actual[kind]) for where, kind, v in found if v != actual[kind]]
    assert not wrong, wrong
    # The stale forms this test was written for are caught.
    import re

    for stale, kind in (("g (12,)", "point"), ("dense (12, n + 4)", "var"),
                        ("shape (K (n + 4) + 1,)", "var"), ("12 K + (n + 3)(K - 1)", "link")):
        hits = [int(m) for p, k in SHAPE_PATTERNS if k == kind for m in re.findall(p, stale)]
        assert hits and any(h != actual[kind] for h in hits), stale


def test_dense_calls_are_the_plain_calls() -> None:
    """Issue 41: ``call_dense`` (CasADi's buffers, no ``DM`` conversions) gives the numbers of
    the plain call bit for bit, mapped over waypoints and for a sparse output (the fallback);
    a wrong input size is refused."""
    import casadi as ca

    from rfsw_plan.planning.nlp import call_dense

    x = ca.SX.sym("x", 3)
    p = ca.SX.sym("p", 2)
    f = ca.Function("f", [x, p], [ca.vertcat(ca.sin(x) * p[0], p[1] * ca.sumsqr(x)),
                                  ca.exp(x[0]) + p[1]])
    fm = f.map(50)
    rng = np.random.default_rng(5)
    X, P = rng.normal(size=(50, 3)), rng.normal(size=(50, 2))
    for got, ref in zip(call_dense(fm, X, P), fm(X.T, P.T), strict=True):
        np.testing.assert_array_equal(got, np.asarray(ref).T)
    sparse = ca.Function("s", [x], [ca.diag(x)])  # a sparse output: the plain call
    np.testing.assert_array_equal(call_dense(sparse, X[0])[0], np.diag(X[0]))
    with pytest.raises(ValueError, match="input 0"):
        call_dense(fm, X[:10], P)
