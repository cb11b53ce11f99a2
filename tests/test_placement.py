"""Placement maps and placement optimisation (issue 14)."""

from __future__ import annotations

import json
import multiprocessing
import re
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.cli.commands import place as place_cli
from rfsw_plan.cli.main import main
from rfsw_plan.exceptions import InputError
from rfsw_plan.placement.geometry import Placement, PlacementGrid, place_task, rot_z
from rfsw_plan.placement.ik import solve_poses
from rfsw_plan.placement.job import PLACE_FILES, PlaceRun
from rfsw_plan.placement.map import (
    compute_map,
    evaluate_given,
    map_input,
    seed_schedule,
    taught_given,
)
from rfsw_plan.placement.optimise import (
    evaluate_candidate,
    move_problem,
    place,
    results_table,
    sample_errors,
    tolerated_uncertainty,
)
from rfsw_plan.placement.session import MapRequest, map_problem
from rfsw_plan.planning.api import options_from_problem, plan
from rfsw_plan.planning.baselines import mirror_compensation, no_compensation
from rfsw_plan.planning.robustness import DOMINANCE_TOL
from rfsw_plan.planning.verify import predict, verify_plan, verify_samples
from rfsw_plan.process.problem import load_problem
from rfsw_plan.robot.kinematics import load_robot


def test_batch_ik_reaches_fk_poses_from_nearby_seeds():
    robot = load_robot("kuka_kr600_r2830")
    rng = np.random.default_rng(1)
    lo, hi = robot.description.lower, robot.description.upper
    q = lo + (hi - lo) * (0.3 + 0.4 * rng.random((200, robot.nq)))
    T, J = robot.batch_fk_jacobian(q)
    regular = np.linalg.svd(J)[1][:, -1] > 0.05  # away from singularities (seam poses are)
    q, T = q[regular], T[regular]
    seed = q + rng.normal(0.0, 0.05, q.shape)
    ik = solve_poses(robot, T[:, :3, :3], T[:, :3, 3], seed)
    assert ik.converged.all()
    T2, _ = robot.batch_fk_jacobian(ik.q)
    assert np.max(np.abs(T2[:, :3, 3] - T[:, :3, 3])) < 1e-7
    assert np.max(np.abs(T2[:, :3, :3] - T[:, :3, :3])) < 1e-6


@pytest.mark.parametrize("name", ["zk500_table6_seam", "kr600_curved_seam"])
def test_map_indices_agree_with_the_planner_prediction(name):
    """The vectorised map at the given placement equals the planner's numeric model on the
    taught path: uncompensated deviation and lateral compliance; the one-step mirror tolerance
    equals the closed form on the converged mirror fixed point to 1e-3."""
    pr = load_problem(name)
    mi = map_input(pr)
    q0 = taught_given(mi)
    assert q0 is not None
    g = evaluate_given(mi, q0)
    pred = predict(mi.model, mi.task, q0, 0.0)
    sl = mi.task.weld
    # The taught path reaches its poses to 1e-7 m (IK tolerance): 1e-4 mm.
    assert g["max_abs_uncompensated_lateral_mm"] == pytest.approx(
        np.max(np.abs(pred.e_lat)) * 1e3, abs=1e-4)
    assert g["lateral_compliance_max_mm_per_kN"] == pytest.approx(
        np.max(pred.lateral_compliance[sl]) * 1e6, rel=1e-9)
    mirror = mirror_compensation(mi.model, mi.task, q0, mi.options.tool_rotation)
    u_fix, _ = tolerated_uncertainty(mi.model, mi.task, mirror.q, mi.window)
    assert g["tolerated_uncertainty_mirror"] == pytest.approx(u_fix, abs=1e-3)


def test_map_is_invariant_to_turning_the_placement_about_the_base_axis():
    """Joint 1 turns about the base's vertical axis: a placement turned about that axis (anchor
    and yaw by the same angle) has the same indices (the metamorphic check of the seeds)."""
    pr = load_problem("fanuc_butt_1700mm")
    mi = map_input(pr)
    a = mi.anchor
    grid = PlacementGrid(np.array([a[0]]), np.array([a[1]]), np.deg2rad([0.0, 30.0]),
                         np.array([a[2]]))
    m0 = compute_map(mi, grid, progress_desc=None)
    phi = np.deg2rad(25.0)
    b = rot_z(phi) @ a
    grid2 = PlacementGrid(np.array([b[0]]), np.array([b[1]]), np.deg2rad([0.0, 30.0]) + phi,
                          np.array([a[2]]))
    m1 = compute_map(mi, grid2, progress_desc=None)
    assert (m0.status == "ok").all() and (m1.status == "ok").all()
    for attr in ("compliance_max", "compliance_mean", "deviation", "tolerated_mirror",
                 "kappa_f"):
        np.testing.assert_allclose(getattr(m1, attr), getattr(m0, attr), rtol=1e-6)
    np.testing.assert_allclose(m1.q_path[..., 1:], m0.q_path[..., 1:], atol=1e-6)


def test_seed_schedule_solves_every_placement_once_after_its_seed():
    shape = (7, 5, 4, 2)
    levels = seed_schedule(shape, np.deg2rad([-90.0, 0.0, 90.0, 180.0]))
    done = np.zeros(int(np.prod(shape)), dtype=bool)
    coords = np.stack(np.unravel_index(np.arange(done.size), shape), axis=1)
    for k, (idx, parent) in enumerate(levels):
        assert not done[idx].any()
        if k == 0:
            assert (parent == -1).all() and (coords[idx, 2] == 1).all()  # yaw 0 = the given
        else:
            assert done[parent].all()
            if k >= shape[2]:  # the fine levels seed within the same yaw
                assert (coords[parent, 2] == coords[idx, 2]).all()
        done[idx] = True
    assert done.all()


@pytest.mark.parametrize("name", ["zk500_table6_seam", "kr600_curved_seam"])
def test_map_equals_each_placement_mapped_alone(name):
    """The coarse-to-fine seeds only change where the IK starts: every placement of a map has
    the indices of the same placement mapped on its own (seeded from the given placement's
    taught path) wherever that one is feasible; the map never loses a feasible placement."""
    pr = load_problem(name)
    mi = map_input(pr, max_weld=15)
    a = mi.anchor
    grid = PlacementGrid(a[0] + np.linspace(-0.3, 0.3, 4), a[1] + np.linspace(-0.3, 0.3, 3),
                         np.deg2rad([-90.0, 0.0, 45.0, 180.0]), np.array([a[2]]))
    m = compute_map(mi, grid, progress_desc=None)
    both = 0
    for i in range(grid.size):
        x, y, z, yaw = m.placements[i]
        one = compute_map(mi, PlacementGrid(np.array([x]), np.array([y]), np.array([yaw]),
                                            np.array([z])), progress_desc=None)
        if one.status[0] != "ok":
            continue
        assert m.status[i] == "ok", (i, m.status[i])
        both += 1
        for attr in ("compliance_max", "compliance_mean", "deviation", "tolerated_mirror",
                     "tolerated_centred", "kappa_f", "nu_p"):
            np.testing.assert_allclose(getattr(m, attr)[i], getattr(one, attr)[0], rtol=1e-5,
                                       err_msg=f"{attr} at placement {i}")
    assert both >= grid.size // 2


def test_place_task_moves_points_frames_and_moment_rigidly():
    pr = load_problem("kr600_curved_seam")
    mi = map_input(pr)
    pl = Placement(1.0, 0.5, 0.9, np.deg2rad(40.0))
    t2 = place_task(mi.task, mi.anchor, pl)
    R = rot_z(pl.yaw)
    d0 = np.diff(mi.task.frames.p, axis=0)
    np.testing.assert_allclose(np.diff(t2.frames.p, axis=0), d0 @ R.T, atol=1e-12)
    np.testing.assert_allclose(t2.frames.l, mi.task.frames.l @ R.T, atol=1e-12)
    np.testing.assert_allclose(t2.force_seam, mi.task.force_seam)


# -- proof on the bundled problems ---------------------------------------------------------------

@pytest.mark.usefixtures("stored_plans")  # the given placement's plan: the session's
@pytest.mark.parametrize("name", ["zk500_table6_seam",
                                  pytest.param("fanuc_butt_1700mm", marks=pytest.mark.slow),
                                  pytest.param("kr600_curved_seam", marks=pytest.mark.slow)])
def test_place_finds_a_placement_at_least_as_robust_and_it_plans_from_its_file(
        name, tmp_path, capsys):
    """Coarse default-region map, two candidates: the chosen placement tolerates at least the
    given placement's force uncertainty; the written problem file loads, plans and verifies at
    every waypoint and every in-material sample of the timed trajectory; if the requested
    +-20 % is not reached the output says which joint's compliance dominates."""
    out = tmp_path / name
    code = main(["place", name, "-o", str(out), "--grid", "7,7,4", "--candidates", "2",
                 "--force-uncertainty", "0.2",
                 "--waypoints", "25", "--json"])
    assert code == 0
    d = json.loads(capsys.readouterr().out)
    chosen, given = d["chosen"], d["given"]
    assert chosen["tolerated_uncertainty"] >= given["tolerated_uncertainty"] - 1e-9
    assert given["status"].startswith(("optimal", "verified"))
    if not d["requested_reached"]:
        assert chosen["dominant_compliance"].startswith(("q", "other"))
        assert chosen["dominant_compliance"] in d["verdict"]
    placed = load_problem(out / f"{name}_placed.toml")
    res = plan(placed)
    model = res.model
    ver = verify_plan(model, res.task, res.window, res.q, res.offsets,
                      res.options.force_uncertainty)
    assert ver.feasible
    samples = verify_samples(model, res.task, res.window, res.trajectory, res.options.margin,
                             res.q)
    assert samples.ok, [f.message for f in samples.failures]
    e, inside = sample_errors(model, res.task, res.trajectory, res.window)
    assert inside.sum() > 10
    assert np.all(e[inside] >= res.window.lower - 1e-6)
    assert np.all(e[inside] <= res.window.upper + 1e-6)
    u, _ = tolerated_uncertainty(model, res.task, res.q, res.window)  # waypoints only
    assert res.tolerated_force_uncertainty <= u + 1e-9  # the planner's adds the samples
    assert res.tolerated_force_uncertainty == pytest.approx(chosen["tolerated_uncertainty"],
                                                            rel=1e-3, abs=1e-4)
    json.loads((out / "map.json").read_text(),
               parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
    # Issue 24: on the placed problem the plan tolerates at least its mirror baseline's force
    # uncertainty (less 0.1 percentage point) at +-10 % and +-20 %, and asking for less is
    # never less robust.
    held = {}
    for u_req in (0.1, 0.2):
        opts = replace(placed.planning, force_uncertainty=u_req)
        # plan(placed) planned with placed.planning (options_from_problem): when these options
        # are the same, the plan is the same (deterministic), so it is read, not planned again
        r = res if opts == placed.planning else plan(placed, opts)
        by = r.tolerated_by_strategy
        assert by["nlp"] >= by["mirror"] - DOMINANCE_TOL, (name, u_req, by)
        held[u_req] = by["nlp"]
    assert held[0.1] >= held[0.2] - 1e-6


def test_optimiser_finds_the_known_best_yaw_on_a_robot_with_a_soft_base_joint():
    """ZK-500 with joint 1 made 20x softer and the others 20x stiffer: the lateral compliance
    is c1 (l . (z x r))^2, so the seam must run tangentially around the base (its lateral axis
    radial) to be stiff and robust. The given seam runs radially (worst); the map ranks
    tangential placements first and the full plans choose one."""
    pr = load_problem("zk500_table6_seam")
    k = pr.robot.stiffness * np.array([1, 20, 20, 20, 20, 20])
    # The verdict's claim covers every weld quantity; here only the lateral error is to
    # decide (the depth of the seed's nonlinear joint-2 stiffness would limit every placement
    # at a few per cent), so the depth, tilt and speed tolerances are opened wide.
    wide = replace(pr.window, depth_shallow=5e-3, depth_deep=5e-3, speed_tol=0.5,
                   tilt_tol=float(np.deg2rad(5)))
    # On the force box (no [process.coupling]): the coupled axial law relaxes the given
    # placement's other quantities so that its lateral level (+-17 %) decides it, above the
    # tangential candidates' other limit (+-12.6 %); this test is about the lateral error.
    soft = replace(pr, robot=pr.robot.with_stiffness(k, "test: soft joint 1"), window=wide,
                   coupling=None)
    opts = options_from_problem(soft, {"rotation_starts": 2})
    s = map_problem(soft, MapRequest(shape=(5, 5, 8, 1), max_weld=20), opts)
    m = s.map

    task = s.input.task
    chord = task.frames.p[-1] - task.frames.p[task.n_start]

    def radial_alignment(p: np.ndarray) -> float:
        """|cos| of the angle between the seam and the radial direction at placement p."""
        t = rot_z(p[3]) @ chord
        return abs(float(t[:2] @ p[:2]) / np.linalg.norm(t[:2]) / np.linalg.norm(p[:2]))

    assert radial_alignment(s.input.given.as_array()) > 0.9  # the given seam runs radially
    top = m.ranking(opts.force_uncertainty)[:2]
    assert all(radial_alignment(m.placements[i]) < 0.1 for i in top)
    res = place(soft, m, opts, n_candidates=2)
    assert res.chosen is not None and res.chosen.label != "given"
    given = res.results[res.given]
    # The soft joint moves the lateral error: its level rises five-fold, and the whole claim
    # rises with it.
    assert res.chosen.tolerated_lateral > 5 * given.tolerated_lateral
    assert res.chosen.tolerated_uncertainty > 1.5 * given.tolerated_uncertainty
    assert radial_alignment(res.chosen.placement.as_array()) < 0.1


def _folder(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def test_results_do_not_depend_on_the_executor(tmp_path, capsys):
    """In this process and on two spawned worker processes: the same plans, the same choice.
    Each with its own map, both write the same bytes into the place folder: no wall time in
    it (the map's and each plan's, printed instead), so the same input writes the same bytes,
    in two different folders (``place.json`` and ``map.json`` name their files inside the
    folder)."""
    pr = load_problem("fanuc_butt_1700mm")
    opts = options_from_problem(pr, {"rotation_starts": 2})
    region = MapRequest(shape=(4, 4, 2, 1), max_weld=15)
    s = map_problem(pr, region, opts)
    a = place(pr, s.map, opts, n_candidates=2)
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as ex:
        s_b = map_problem(pr, region, opts)
        b = place(pr, s_b.map, opts, n_candidates=2, executor=ex)
    assert a.best == b.best
    for ra, rb in zip(a.results, b.results, strict=True):
        assert ra.label == rb.label and ra.status == rb.status
        assert ra.tolerated_uncertainty == rb.tolerated_uncertainty
        assert ra.min_lateral_stiffness == rb.min_lateral_stiffness
    files = []
    for i, (session, res) in enumerate(((s, a), (s_b, b))):
        # PlaceRequest.run() with these options; the executor's label is an input, kept equal
        run = PlaceRun(pr, opts, session, res, results_table(res, session.map.anchor), "x")
        out = tmp_path / f"place_{i}"
        out.mkdir()
        run.write(out)
        files.append(_folder(out))
        assert json.loads(files[-1]["place.json"])["files"][-1] == "place.json"
    assert sorted(files[0]) == sorted(["fanuc_butt_1700mm_placed.toml", *PLACE_FILES])
    assert [n for n in files[0] if files[0][n] != files[1][n]] == []
    for n in ("place.json", "map.json", "candidates.csv"):
        assert b"second" not in files[0][n] and b"plan_time_s" not in files[0][n], n
    place_cli._print(pr.name, run.to_dict(out), run.rows, b, s_b)
    out = capsys.readouterr().out
    assert re.search(r"map of \d+ placements in \d+\.\d s; 3 plans in \d+\.\d s", out), out


def test_thread_pools_are_refused():
    """IPOPT/MUMPS in CasADi is not thread-safe: a thread pool is refused, not crashed."""
    pr = load_problem("fanuc_butt_1700mm")
    opts = options_from_problem(pr)
    s = map_problem(pr, MapRequest(shape=(2, 2, 1, 1), max_weld=10), opts)
    with ThreadPoolExecutor(2) as ex, pytest.raises(InputError, match="thread"):
        place(pr, s.map, opts, n_candidates=1, executor=ex)


def test_candidate_evaluation_reports_an_unreachable_placement():
    pr = load_problem("fanuc_butt_1700mm")
    opts = options_from_problem(pr, {"rotation_starts": 1, "branches": False})
    far = Placement(9.0, 0.0, 0.6, 0.0)
    r = evaluate_candidate(move_problem(pr, map_input(pr).anchor, far), opts, "far", far)
    assert r.status == "unreachable" and "unreachable" in r.message and not r.planned


def test_no_compensation_seed_of_the_map_is_the_planner_taught_path():
    pr = load_problem("zk500_table6_seam")
    mi = map_input(pr)
    q = no_compensation(mi.model.robot, mi.task, mi.q_seed, mi.options.tool_rotation).q
    np.testing.assert_allclose(taught_given(mi), q)


# -- bad input -------------------------------------------------------------------------------

@pytest.mark.parametrize("argv, words", [
    (["--region", "5000,6000,0,100"], ["--region", "feasible with its anchor", "mm from"]),
    (["--yaw-range", "30,-30"], ["--yaw-range", "empty range"]),
    (["--robot-base-height", "3000,4000"],
     ["--robot-base-height", "every placement is infeasible"]),
    (["--region", "1,2,3"], ["--region", "4 or 6"]),
    (["--grid", "5,x,2"], ["--grid"]),
])
def test_bad_placement_input_is_one_line_exit_2(argv, words, tmp_path, capsys):
    grid = [] if "--grid" in argv else ["--grid", "5,5,2,2"]
    code = main(["map", "fanuc_butt_1700mm", "-o", str(tmp_path / "o"), "--waypoints", "10",
                 *grid, *argv])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err
    for w in words:
        assert w in err


def test_place_rejects_dask_with_workers(tmp_path, capsys):
    code = main(["place", "fanuc_butt_1700mm", "-o", str(tmp_path / "o"), "--workers", "2",
                 "--dask", "tcp://127.0.0.1:1"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--dask" in err


@pytest.mark.slow
def test_place_on_a_local_dask_cluster_gives_the_same_choice(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    pr = load_problem("fanuc_butt_1700mm")
    opts = options_from_problem(pr, {"rotation_starts": 2})
    s = map_problem(pr, MapRequest(shape=(4, 4, 2, 1), max_weld=15), opts)
    a = place(pr, s.map, opts, n_candidates=2)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cl, \
            distributed.Client(cl) as client:
        b = place(pr, s.map, opts, n_candidates=2, executor=client.get_executor())
    assert a.best == b.best
    for ra, rb in zip(a.results, b.results, strict=True):
        assert (ra.label, ra.status, ra.tolerated_uncertainty) == \
            (rb.label, rb.status, rb.tolerated_uncertainty)


@pytest.mark.slow
def test_place_cli_with_local_processes(tmp_path, capsys):
    out = tmp_path / "w"
    assert main(["place", "fanuc_butt_1700mm", "-o", str(out), "--grid", "5,5,2",
                 "--candidates", "2", "--workers", "2", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["executor"] == "2 local processes" and d["chosen"] is not None
