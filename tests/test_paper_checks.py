"""Checks against the papers (issue 2 §8) and the workspace index maps behind them."""

from __future__ import annotations

import functools
import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from rfsw_plan.elastostatics.compliance import (
    complementary_stiffness,
    dexterity,
    kc_influence_index,
)
from rfsw_plan.elastostatics.workspace import index_map, sample_joint_grid
from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.kinematics import load_robot

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "paper_checks.py"


#: The example's computations that several tests (and ``checks()``, which calls them all) read:
#: each is deterministic and returns what its callers only read, so it runs once per module.
SHARED = ("zk500_seam_check", "zk500_plunge_cases", "table3_eight_mm", "seed001_cases",
          "fanuc_direction_cases", "eq10_readings", "eq10_scale_for_limit",
          "kr600_forming_check")


@pytest.fixture(scope="module")
def paper() -> ModuleType:
    """``examples/paper_checks.py`` loaded as a module, its :data:`SHARED` functions cached
    (the module's own calls go through its globals, so ``checks()`` reuses them too)."""
    spec = importlib.util.spec_from_file_location("paper_checks", EXAMPLE)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["paper_checks"] = mod
    spec.loader.exec_module(mod)
    for name in SHARED:
        setattr(mod, name, functools.cache(getattr(mod, name)))
    return mod


def test_zk500_lateral_deflection_within_10_percent_of_measured(paper: ModuleType) -> None:
    s = paper.zk500_seam_check()
    # Tool straight down at the seam start (seed 001 Table 6).
    robot = load_robot(paper.ZK500)
    T = robot.fk(np.radians(s.q_deg))
    np.testing.assert_allclose(T[:3, 3], paper.SEAM_START, atol=1e-6)
    np.testing.assert_allclose(T[:3, 2], [0.0, 0.0, -1.0], atol=1e-6)
    assert s.q_deg[2] > 0 and s.q_deg[1] > 0  # elbow-up branch of Table 2 pose 1
    assert abs(s.lateral_mm - paper.MEASURED_MM) <= 0.1 * paper.MEASURED_MM, s.lateral_mm
    t = (paper.SEAM_END - paper.SEAM_START) / np.linalg.norm(paper.SEAM_END - paper.SEAM_START)
    lat = np.cross([0.0, 0.0, 1.0], t)
    lat /= np.linalg.norm(lat)
    assert s.wrench[:3] @ lat == pytest.approx(paper.FL_N, rel=1e-12)  # lateral force along l
    assert s.wrench[2] > 4800.0  # down force pushes the tool up


def test_fanuc_nu_p_map_is_sane(paper: ModuleType) -> None:
    maps = paper.fanuc_nu_p_maps(n_points=15)
    eq10 = maps["eq. 10 Kq (k6 = 1e4 assumed)"]
    table2 = maps["Table 2 (identified)"]
    for mp in (eq10, table2):
        nu = mp.nu_p[np.isfinite(mp.nu_p)]
        assert nu.size == 15 * 15
        assert np.all((nu >= 0) & (nu < 1))
        assert nu.max() > 0
        assert np.all(mp.kappa_f >= 1.0 - 1e-12)
    # nu_p is first order in F/K: the stiffer identified robot has the smaller index.
    assert np.nanmax(table2.nu_p) < np.nanmax(eq10.nu_p)
    assert np.nanmedian(table2.nu_p) < 0.05


def test_index_map_matches_pointwise_functions() -> None:
    robot = load_robot("fanuc_s900ib_400")
    grid = sample_joint_grid(robot, np.radians([0, 0, 0, 45, 45, 45]), n_points=(4, 5))
    assert grid.q.shape == (20, 6) and grid.shape == (4, 5)
    np.testing.assert_allclose(grid.q[:, [0, 3, 4, 5]], np.radians([[0, 45, 45, 45]] * 20))
    assert grid.q[0, 1] == pytest.approx(robot.description.lower[1])
    assert grid.q[-1, 2] == pytest.approx(robot.description.upper[2])
    for i in (0, 7, 19):
        np.testing.assert_allclose(grid.position[i], robot.fk(grid.q[i])[:3, 3], atol=1e-12)
    F = np.array([1000.0, -3000.0, -4000.0, -200.0, 200.0, -200.0])
    Kq = np.array([1e6, 4e5, 4e5, 1e4, 1e4, 1e4])
    mp = index_map(robot, grid, F, Kq)
    for i in (0, 7, 19):
        J = robot.jacobian(grid.q[i])
        Kc = complementary_stiffness(robot.jacobian_derivatives(grid.q[i]), F)
        assert mp.nu_p[i] == pytest.approx(kc_influence_index(J, np.diag(Kq), Kc, F), rel=1e-9)
        assert mp.kappa_f[i] == pytest.approx(dexterity(J), rel=1e-12)
    pc = mp.percentiles((50.0,))
    assert pc["max"] == pytest.approx(np.nanmax(mp.nu_p))


def test_workspace_bad_input() -> None:
    robot = load_robot("zk500")
    with pytest.raises(InputError, match="joint values"):
        sample_joint_grid(robot, np.zeros(5))
    with pytest.raises(InputError, match="two different joints"):
        sample_joint_grid(robot, np.zeros(6), swept=(1, 1))
    with pytest.raises(InputError, match="at least 2"):
        sample_joint_grid(robot, np.zeros(6), n_points=(1, 5))
    grid = sample_joint_grid(robot, np.zeros(6), n_points=(2, 2))
    with pytest.raises(InputError, match="6 values"):
        index_map(robot, grid, np.zeros(5))
    with pytest.raises(InputError, match="Kq"):
        index_map(robot, grid, np.ones(6), np.ones(5))


def test_one_table_keeps_the_reproduced_numbers_reproduced(paper: ModuleType) -> None:
    rows = paper.checks(n_points=15)
    reproduced = {r.paper for r in rows if r.reproduced}
    assert "001 §4: lateral deflection 4.9 mm (measured)" in reproduced
    assert "001 Fig. 10a-c: penetration ~4.2 / ~4.8 / >5 mm for 7 / 8 / 9 mm plunge" in reproduced
    assert "000 Table 2 stiffness: nu_p <= 0.03" in reproduced
    assert "000 Figs. 16-17: 1400 mm, lateral deviation lower along y+ than y-" in reproduced
    assert "001 Table 3: k1-k5 identified from the 5 Table 2 poses (cable at the TCP)" in reproduced
    # Every row that is not reproduced says why.
    assert all(r.why for r in rows if not r.reproduced)


def test_seed001_numbers_hold_together_in_one_run(paper: ModuleType) -> None:
    """Issue 28's joint check on the problems' robot (zk500_seed001): each plunge is one
    co-simulation; the 8 mm run gives penetration, measured axial force and lateral deviation
    at once; Table 3 alone (zk500) pushes 1.8x the measured force for the same penetration."""
    cases = paper.zk500_plunge_cases()
    assert [c.commanded_mm for c in cases] == [7.0, 8.0, 9.0]
    assert all(c.result.cosim is not None and c.result.cosim.all_converged for c in cases)
    seven, eight, nine = cases
    assert abs(seven.max_penetration_mm - 4.2) <= 0.3
    assert abs(eight.max_penetration_mm - 4.8) <= 0.3
    assert nine.max_penetration_mm > 5.0
    assert abs(eight.steady_force_N / paper.FD_N - 1.0) <= 0.15
    assert abs(eight.max_lateral_mm / paper.COSIM_MM - 1.0) <= 0.10
    # The three numbers come from the same run's series (what deviation --cosim --json gives).
    js = eight.result.to_dict()["cosim"]
    assert js["max_penetration_mm"] == pytest.approx(eight.max_penetration_mm)
    assert js["steady_axial_force_N"] == pytest.approx(eight.steady_force_N)
    assert js["max_abs_lateral_weld_mm"] == pytest.approx(eight.max_lateral_mm)
    holds, text = paper.joint_check(cases)
    assert holds and "8 mm run" in text
    t3 = paper.table3_eight_mm()
    assert t3.result.cosim is not None and t3.steady_force_N > 1.5 * paper.FD_N
    rows = {r.paper: r for r in paper._seed001_rows()}
    joint = rows["001 §2.1/§3/§4 together: 4.2 / 4.8 / >5 mm, Fd0 4842.58 N, lateral 5.24 mm"]
    assert joint.reproduced
    assert rows["001 §3: axial force 4842.58 N (measured, 8 mm plunge)"].reproduced
    # The paper's own model's mean of the final ten iterations stays above ours, honestly.
    assert not rows["001 §4: co-simulated lateral 5.24 mm (8 mm, mean of the final 10 "
                    "iterations)"].reproduced


def test_seed000_direction_cases_keep_their_finding(paper: ModuleType) -> None:
    """Seed 000 Figs. 16-17: at 1400 mm the deviation is lower along y+ than along y-; the
    axial force's part reverses with the travel direction, the lateral force's part does not;
    the splits by force and by joint add up to the deviation (the model is linear)."""
    cases = {c.case: c for c in paper.fanuc_direction_cases()}
    assert list(cases) == ["1400 mm y+", "1400 mm y-", "1700 mm y+", "1700 mm y-"]
    for c in cases.values():
        assert sum(c.by_force_mm.values()) == pytest.approx(c.lateral_mm[0], abs=1e-6)
        assert sum(c.by_joint_mm) == pytest.approx(c.lateral_mm[0], abs=1e-6)
        assert c.by_joint_mm[5] == pytest.approx(0.0, abs=1e-9)  # J6 is the tool axis
        assert c.by_force_mm["lateral"] > 0  # toward the advancing side
    for d in ("1400", "1700"):
        yp, ym = cases[f"{d} mm y+"], cases[f"{d} mm y-"]
        assert max(map(abs, yp.lateral_mm)) < min(map(abs, ym.lateral_mm))
        assert yp.by_force_mm["axial"] == pytest.approx(-ym.by_force_mm["axial"], rel=1e-6)
        assert yp.by_force_mm["lateral"] == pytest.approx(ym.by_force_mm["lateral"], rel=1e-6)
        assert yp.by_force_mm["axial"] < -2.0
        # Joint 5 (the wrist bending under the lateral force) carries the largest part.
        assert int(np.argmax(np.abs(yp.by_joint_mm))) == 4
    # Magnitudes measured on the bundled problems (1400 mm y+ 4.60-5.10, y- 11.89-11.39 mm).
    assert 4.0 < cases["1400 mm y+"].lateral_mm[0] < 5.5 < 10.5 < cases["1400 mm y-"].lateral_mm[0]
    p17 = cases["1700 mm y+"]
    assert p17.lateral_force_for(p17.lateral_mm[0]) == pytest.approx(p17.lateral_force_N)
    assert 1000.0 < p17.lateral_force_for(paper.PAPER_1700_MM) < 1500.0
    rows = {r.paper: r for r in paper._fanuc_direction_rows()}
    assert rows["000 Figs. 16-17: 1400 mm, lateral deviation lower along y+ than y-"].reproduced
    assert not rows["000 §3.2.6: ~7 mm lateral deviation at 1700 mm (pin entering)"].reproduced


def test_seed000_1700mm_sensitivity(paper: ModuleType) -> None:
    """The spindle sense swaps the two travel directions; the lateral force and the wrist
    stiffness move the 1700 mm deviation most, the coupling and seam height least."""
    rows = paper.fanuc_1700_sensitivity()
    by = {r.variant: r for r in rows}
    base = rows[0]
    assert base.assumption == "baseline"
    ccw = by["spindle ccw (advancing side on the other side)"]
    np.testing.assert_allclose(ccw.y_plus_mm, base.y_minus_mm, atol=1e-6)
    np.testing.assert_allclose(ccw.y_minus_mm, base.y_plus_mm, atol=1e-6)
    spread = paper.sensitivity_spread(rows)
    assert set(spread) == {"force direction", "force magnitude", "stiffness", "coupling",
                           "geometry", "seam placement"}
    assert spread["force magnitude"] > 3.0 and spread["stiffness"] > 3.0
    assert spread["coupling"] < 1.0 and spread["seam placement"] < 1.5
def test_seed001_table3_rows_keep_their_finding(paper: ModuleType) -> None:
    """Five Table 2 poses with the cable at the TCP identify k1-k5 within their standard
    errors; k6 is not identifiable, 3-D or 6-D; off the tool axis with 6-D data it is."""
    rows = paper._seed001_table3_rows(paper.seed001_cases())
    assert [r.reproduced for r in rows] == [True, False, False]
    assert "not identifiable with the cable at the TCP" in rows[1].project
    assert "k6 not identified" in rows[1].why and "3-D: k6 not identified" in rows[1].why


def test_seed000_eq10_readings(paper: ModuleType) -> None:
    """Seed 000 eq. 10 lists five stiffnesses: no plausible reading gives nu_p <= 0.03 over
    the Fig. 13 plane; only kN m/rad (1000x Table 2) does. Table 2 is the reproduced one."""
    rows = {r.reading: r for r in paper.eq10_readings(n_points=15)}
    assert len(rows) == 8
    for r in rows.values():
        assert len(r.Kq) == 6 and 0.0 <= r.median <= r.max < 1.0
    eq10 = [r for r in rows.values() if not r.reading.startswith("Table 2")]
    assert [r.reading for r in eq10 if r.holds] == ["values in kN m/rad (x 1e3)"]
    assert rows["k6 = k5 lost (wrist 1e4)"].median > 0.1
    assert rows["wrist exponent misread (1e5)"].max > 0.03  # close, but not within
    t2 = rows["Table 2 (identified)"]
    assert t2.median <= 0.03 and t2.max <= 0.035
    assert rows["Table 2, wrench in the tool frame"].holds
    scale = paper.eq10_scale_for_limit(0.03, n_points=15)
    assert 3.0 < scale < 30.0
    robot = load_robot("fanuc_s900ib_400")
    grid = sample_joint_grid(robot, np.radians(paper.FIG13_Q_DEG), n_points=(15, 15))
    k = np.array([*paper.EQ10_FIVE, paper.EQ10_FIVE[-1]])
    assert np.nanmax(index_map(robot, grid, paper.EQ10_WRENCH, scale * k).nu_p) <= 0.03
    assert np.nanmax(index_map(robot, grid, paper.EQ10_WRENCH, 0.95 * scale * k).nu_p) > 0.03


def test_kr600_torque_variant_is_seed002s_robot() -> None:
    """Seed 002: torque-dependent rotational stiffness (stiffening, Fig. 7's shape) on joints
    1-5, tilting in both directions on every joint, joint 6 rigid in rotation."""
    from rfsw_plan.elastostatics.model import load_model

    robot = load_robot("kuka_kr600_r2830_torque")
    d = robot.description
    labels = [e.name for e in d.effects]
    assert labels[:5] == [f"torque_dependent_stiffness:j{i}" for i in range(1, 6)]
    assert [x for x in labels if x.startswith("tilting")] == [
        f"tilting_compliance:j{i}" for i in range(1, 7)]
    assert "torque_dependent_stiffness:j6" not in labels
    assert d.stiffness[5] >= 1e12 and np.all(d.stiffness[:5] < 1e7)
    base = load_robot("kuka_kr600_r2830")
    np.testing.assert_allclose(d.stiffness[:5], base.description.stiffness[:5])
    model = load_model(robot)
    q = np.radians([0.0, -80.0, 110.0, 0.0, 60.0, 0.0])
    F = np.array([0.0, 0.0, 5000.0, 0.0, 0.0, 0.0])
    d1 = model.deflection(q, 0.2 * F)[:3]
    d5 = model.deflection(q, F)[:3]
    # Stiffening: five times the force gives less than five times the deflection, not much less.
    assert 0.9 * 5 < (d5 @ F[:3]) / (d1 @ F[:3]) < 5.0
    # Odd in the force: the reversed force gives the mirrored deflection.
    np.testing.assert_allclose(model.deflection(q, -F)[:3], -d5, rtol=1e-9)


def test_seed002_forming_rows(paper: ModuleType) -> None:
    """Seed 002 Table 3 on the forming-like path: the compensation's reduction is reproduced,
    the absolute levels are not (and say why)."""
    f = paper.kr600_forming_check()
    none, comp = f.mae_mm["main", "none"], f.mae_mm["main", "realtime_seed002"]
    assert 0.4 < none < 0.8  # measured 0.599 mm against the paper's 0.4277 mm
    assert comp < 0.05 < f.mae_mm["stiffness_-20%", "realtime_seed002"] < 0.5 * none
    rows = {r.paper: r for r in paper._seed002_rows()}
    assert rows["002 Table 3: compensation halves the MAE (0.43 -> ~0.2 mm, E19-E24)"].reproduced
    assert not rows["002 Table 3: MAE along the normal 0.43 mm uncompensated (E13-E18)"].reproduced
