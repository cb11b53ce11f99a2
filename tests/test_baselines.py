"""Baselines: taught path, mirror fixed point, branches, metrics."""

from __future__ import annotations

import numpy as np
import pytest
from _helpers import F_SEAM, Q_SEED, zk500_frames

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import UnreachableError
from rfsw_plan.planning.baselines import (
    branch_seeds,
    commanded_poses,
    ik_path,
    metrics,
    mirror_compensation,
    no_compensation,
)
from rfsw_plan.planning.verify import predict
from rfsw_plan.process.frames import SeamFrames
from rfsw_plan.process.task import task_constant_force
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.robot.ik import solve_ik
from rfsw_plan.robot.kinematics import load_robot


@pytest.fixture(scope="module")
def setup(zk500_case):
    return zk500_case(6)[:2]


def test_taught_path_reaches_the_seam(setup):
    model, task = setup
    base = no_compensation(model.robot, task, Q_SEED, rotation=0.3)
    T = commanded_poses(task, base.offsets, 0.3)
    for k in range(len(task)):
        np.testing.assert_allclose(model.robot.fk(base.q[k]), T[k], atol=1e-6)


def test_mirror_fixed_point_cancels_the_predicted_error(setup):
    model, task = setup
    base = no_compensation(model.robot, task, Q_SEED)
    mir = mirror_compensation(model, task, base.q)
    assert mir.converged
    pred = predict(model, task, mir.q, 0.0)
    assert np.max(np.abs(pred.e_lat)) < 1e-6
    assert np.max(np.abs(pred.e_norm)) < 1e-6
    assert np.max(np.abs(pred.e_along)) < 1e-6  # the pin is on its seam point along the track
    # The offset mirrors the deflection: about -4.9 mm lateral (seed 001), and the commanded
    # TCP runs ahead of the pin by the traverse force's along-track lag.
    assert mir.offsets[0, 0] == pytest.approx(-4.9e-3, abs=0.2e-3)
    assert mir.offsets.shape == (len(task), 3)
    np.testing.assert_allclose(mir.offsets[:, 2], -predict(model, task, base.q, 0.0).e_along,
                               rtol=0.05)


def test_metrics_are_consistent(setup):
    model, task = setup
    base = no_compensation(model.robot, task, Q_SEED)
    m = metrics("none", model, task, base.q, WeldWindow(), 0.2)
    pred = predict(model, task, base.q, 0.2)
    assert m.max_abs_lateral == pytest.approx(np.max(np.abs(pred.e_lat)))
    assert m.rms_lateral <= m.max_abs_lateral
    assert m.worst_case == pytest.approx(np.max(np.abs(pred.e_lat) + pred.worst))
    assert m.min_lateral_stiffness == pytest.approx(np.min(pred.lateral_stiffness))
    assert m.inside_fraction == 0.0
    d = m.to_dict()
    assert d["max_abs_lateral_mm"] == pytest.approx(m.max_abs_lateral * 1e3)


def test_wrist_flip_seed_reaches_the_same_pose_on_another_branch(setup):
    model, task = setup
    seeds = dict(branch_seeds(model.robot, Q_SEED))
    assert {"seed", "wrist_flip", "elbow_flip", "shoulder_flip"} <= set(seeds)
    a = no_compensation(model.robot, task, seeds["seed"])
    b = no_compensation(model.robot, task, seeds["wrist_flip"])
    assert not np.allclose(a.q, b.q, atol=1e-3)
    np.testing.assert_allclose(model.robot.fk(a.q[0]), model.robot.fk(b.q[0]), atol=1e-6)


# A pose per bundled 6R arm (controller values, deg) that both shoulder branches reach: the
# wrist centre close to axis 1, so the arm can also reach it over its head.
BOTH_SHOULDERS_DEG = {
    "kuka_kr600_r2830": [20, -120, -90, 10, 60, 20],
    "fanuc_s900ib_400": [20, -60, -120, 10, 30, 20],
    "zk500": [20, -80, -120, 10, 30, 20],
}


@pytest.mark.parametrize("robot_name", sorted(BOTH_SHOULDERS_DEG))
def test_shoulder_flip_seed_finds_both_shoulder_branches(robot_name):
    """IK from the branch seeds reaches the pose with q1 and with q1 + pi, both inside the
    joint limits and at the same TCP (the chain's FK is checked against the vendors'
    descriptions in test_vendor_descriptions). On the KUKA the upper arm is mirrored about
    A2 = -90 deg (vertical), not A2 = 0: the former seed q + (pi, -2 q2, 0, 0, 0, 0) put A2 at
    +120 deg, outside -130..+20 deg."""
    robot = load_robot(robot_name)
    lo, hi = robot.description.lower, robot.description.upper
    q = np.radians(BOTH_SHOULDERS_DEG[robot_name])
    target = robot.fk(q)
    shoulder = {}
    for name, seed in branch_seeds(robot, q):
        assert np.all(seed >= lo) and np.all(seed <= hi), name
        res = solve_ik(robot, target, seed, max_iter=400)
        if not res.converged:
            continue
        assert np.all(res.q >= lo) and np.all(res.q <= hi), name
        np.testing.assert_allclose(robot.fk(res.q), target, atol=1e-9)
        flipped = abs(np.angle(np.exp(1j * (res.q[0] - q[0])))) > np.pi - 0.1
        shoulder.setdefault(flipped, name)
    assert shoulder.get(False) == "seed"
    assert shoulder.get(True, "").startswith("shoulder_"), shoulder


def test_unreachable_seam_names_waypoint_and_distance():
    model = ElastostaticModel(load_robot("zk500"))
    fr = zk500_frames(5)
    far = SeamFrames(fr.s, fr.p + np.array([0, -2.0, 0]) * (fr.s[:, None] > 0.05), fr.t, fr.l,
                     fr.n)
    task = task_constant_force(far, F_SEAM, 3e-3)
    pattern = r"seam waypoint 2 \(s = 56.8 mm\) .*misses it by \d"
    with pytest.raises(UnreachableError, match=pattern):
        no_compensation(model.robot, task, Q_SEED)


def test_batched_newton_refinement_matches_the_ik_path(setup):
    from rfsw_plan.planning.baselines import refine_path

    model, task = setup
    base = no_compensation(model.robot, task, Q_SEED)
    rng = np.random.default_rng(3)
    off = np.column_stack([rng.normal(0, 3e-3, (len(task), 3))])
    poses = commanded_poses(task, off, 0.0)
    q_new = refine_path(model.robot, poses, base.q)
    q_ref = ik_path(model.robot, poses, base.q[0], q_warm=base.q)
    np.testing.assert_allclose(q_new, q_ref, atol=1e-6)
    for k in range(len(task)):
        np.testing.assert_allclose(model.robot.fk(q_new[k]), poses[k], atol=1e-7)


def test_a_branch_that_cannot_reach_the_seam_stops_where_it_is_stuck(setup, monkeypatch):
    """The batched IK stops a start whose errors no longer change (IK_STALL) instead of
    running all its steps: same convergence, same reported miss as without the stop."""
    import rfsw_plan.planning.baselines as baselines

    model, task = setup
    seeds = np.stack([q for _, q in branch_seeds(model.robot, Q_SEED)])
    pose = commanded_poses(task, np.zeros((len(task), 3)), 0.0)[0]
    poses = np.repeat(pose[None], len(seeds), axis=0)
    q, ok, ep, er = baselines._batch_ik(model.robot, poses, seeds, 1e-7, 400)
    assert ok.any() and not ok.all()  # the shoulder flips cannot reach it
    monkeypatch.setattr(baselines, "IK_STALL", -1.0)
    q_all, ok_all, ep_all, er_all = baselines._batch_ik(model.robot, poses, seeds, 1e-7, 400)
    np.testing.assert_array_equal(ok, ok_all)
    np.testing.assert_array_equal(q[ok], q_all[ok])
    np.testing.assert_allclose(ep, ep_all, rtol=0, atol=1e-9)
    np.testing.assert_allclose(er, er_all, rtol=0, atol=1e-9)
