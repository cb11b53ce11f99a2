"""Issue 32, planning half: the weld envelope and physical phases of EVERY bundled problem,
computed from the written ``waypoints.csv`` and the problem file with plain numpy, independently
of the planner's own verification (no call into rfsw_plan.planning or rfsw_plan.timing: the
problem file is read by the problem reader, the plan folder's CSV by ``csv``).

For every bundled problem (each planned once per session, ``planned_result``):

* no pin tip below the plate surface before the plunge (approach samples); plate surface =
  seam point + plunge depth along the plate normal (the problem's ``surface_normal`` made
  orthogonal to the seam tangent);
* under position control, the pin depth along the plate normal within the depth window at
  every full-depth sample (dwell, accelerate, weld, decelerate);
* work and travel angle of the tool axis (from the written quaternion) within the tilt
  tolerance of the problem's ``tilt_deg`` at every in-material sample;
* the pin's travel along the seam (arc length of its seam point plus its along-track offset)
  within the speed tolerance of the weld speed at every constant-speed weld sample;
* while the pin is in the plate during the retract, it rises at most at the process retract
  speed; the first and last samples are at the safe height, the approach a line along the
  tool axis.
"""

from __future__ import annotations

import csv
import tomllib
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.process.problem import BUNDLED_PROBLEMS_DIR, load_problem

PROBLEMS = sorted(p.stem for p in BUNDLED_PROBLEMS_DIR.glob("*.toml"))
#: The CSV writes 6 decimals of mm; heights are compared to 1 um.
TOL_MM = 1e-3


def _read_csv(path: Path) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    phase = np.array([r["phase"] for r in rows])
    cols = {k: np.array([float(r[k]) if r[k] != "" else np.nan for r in rows])
            for k in rows[0] if k != "phase"}
    return phase, cols


@pytest.fixture(scope="module")
def written(planned_result, tmp_path_factory):
    """``written(problem)`` -> (phase, columns, problem TOML, problem) of the plan's
    ``waypoints.csv`` (written by the plan-folder writer from the session's plan)."""
    from rfsw_plan.planfiles.waypoints import write_waypoints_csv

    cache: dict[str, tuple] = {}

    def get(name: str) -> tuple:
        if name not in cache:
            folder = tmp_path_factory.mktemp(name)
            write_waypoints_csv(folder / "waypoints.csv", planned_result(name))
            phase, cols = _read_csv(folder / "waypoints.csv")
            with open(BUNDLED_PROBLEMS_DIR / f"{name}.toml", "rb") as fh:
                toml = tomllib.load(fh)
            cache[name] = (phase, cols, toml, load_problem(name))
        return cache[name]

    return get


def _geometry(cols: dict[str, np.ndarray], phase: np.ndarray, toml: dict
              ) -> dict[str, np.ndarray]:
    """Seam point, tangent, plate normal, pin and tool axis of every sample (mm, base frame)."""
    seam = np.stack([cols[f"seam_{c}_mm"] for c in "xyz"], axis=1)
    pin = np.stack([cols[f"{c}_mm"] + cols[f"d{c}_mm"] for c in "xyz"], axis=1)
    s = cols["s_mm"]
    # Seam tangent at each sample's s: the chord of the written seam points (of the weld
    # samples) from s - 1 mm to s + 1 mm (the points are piecewise linear between the seam's
    # waypoints; the chord does not jump at their corners).
    w = np.isin(phase, ("accelerate", "weld", "decelerate"))
    sw, order = np.unique(s[w], return_index=True)
    pw = seam[w][order]

    def at(x: np.ndarray) -> np.ndarray:
        x = np.clip(x, sw[0], sw[-1])
        return np.stack([np.interp(x, sw, pw[:, i]) for i in range(3)], axis=1)

    tan = at(s + 1.0) - at(s - 1.0)
    tan /= np.linalg.norm(tan, axis=1, keepdims=True)
    nrm = np.asarray(toml["seam"].get("surface_normal", [0.0, 0.0, 1.0]), dtype=float)
    if nrm.ndim == 2:  # one normal per seam point: the nearest point's
        pts = np.asarray(toml["seam"]["points_mm"], dtype=float)
        nrm = nrm[np.argmin(np.linalg.norm(seam[:, None] - pts[None], axis=2), axis=1)]
    nrm = np.broadcast_to(nrm, seam.shape).copy()
    nrm -= np.einsum("ki,ki->k", nrm, tan)[:, None] * tan
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    qw, qx, qy, qz = (cols[k] for k in ("qw", "qx", "qy", "qz"))
    # Third column of the rotation matrix of the unit quaternion: the TCP z axis.
    z = np.stack([2 * (qx * qz + qw * qy), 2 * (qy * qz - qw * qx),
                  1 - 2 * (qx * qx + qy * qy)], axis=1)
    return {"seam": seam, "pin": pin, "t": tan, "n": nrm, "z": z}


def _height(g: dict[str, np.ndarray], depth_mm: float) -> np.ndarray:
    """Pin tip height above the plate surface along the plate normal [mm]."""
    return np.einsum("ki,ki->k", g["n"], g["pin"] - g["seam"]) - depth_mm


@pytest.mark.parametrize("name", PROBLEMS)
def test_no_pin_below_the_plate_before_the_plunge(written, name):
    phase, cols, toml, problem = written(name)
    g = _geometry(cols, phase, toml)
    h = _height(g, problem.process.plunge_depth * 1e3)
    before = phase == "approach"
    assert before.any()
    assert np.min(h[before]) >= -TOL_MM, (
        f"{name}: pin {-np.min(h[before]):.3f} mm below the plate before the plunge")
    # The spindle-start hook sits at the end of the approach: the pin above the surface by the
    # spindle clearance (option, default 2 mm).
    clearance = toml.get("planning", {}).get("spindle_clearance_mm", 2.0)
    last = np.flatnonzero(before)[-1]
    assert h[last] == pytest.approx(clearance, abs=0.01)


@pytest.mark.parametrize("name", PROBLEMS)
def test_depth_and_tilt_in_their_windows_at_every_weld_sample(written, name):
    phase, cols, toml, problem = written(name)
    g = _geometry(cols, phase, toml)
    depth = problem.process.plunge_depth * 1e3
    win = toml.get("window", {})
    full = np.isin(phase, ("dwell", "accelerate", "weld", "decelerate"))
    axial = toml["process"].get("axial_control", problem.process.axial_control)
    if axial == "position":
        err = _height(g, depth)[full] + depth  # + shallow, - deep
        assert np.max(err) <= win.get("depth_shallow_mm", 0.5) + TOL_MM, name
        assert np.min(err) >= -win.get("depth_deep_mm", 0.2) - TOL_MM, name
    inside = np.isin(phase, ("plunge", "dwell", "accelerate", "weld", "decelerate"))
    up = -g["z"][inside]  # tool axis, up into the spindle
    t, n = g["t"][inside], g["n"][inside]
    lat = np.cross(n, t)
    work = np.rad2deg(np.arcsin(np.clip(np.einsum("ki,ki->k", up, lat), -1, 1)))
    travel = np.rad2deg(np.arctan2(-np.einsum("ki,ki->k", up, t), np.einsum("ki,ki->k", up, n)))
    tilt = toml["seam"].get("tilt_deg", 0.0)
    tol = win.get("tilt_tol_deg", 0.5)
    assert np.max(np.abs(work)) <= tol, name
    assert np.max(np.abs(travel - tilt)) <= tol, name


@pytest.mark.parametrize("name", PROBLEMS)
def test_pin_speed_within_its_tolerance_of_the_weld_speed(written, name):
    phase, cols, toml, problem = written(name)
    g = _geometry(cols, phase, toml)
    w = phase == "weld"
    # The pin's travel along the seam: the arc length of its seam point plus its along-track
    # offset from it, sigma = s + t . (pin - seam), in time (its lateral and normal motion
    # while the forces ramp up at the weld start is not travel). On the 12 mm corners of
    # kr600_forming_contour this measure (the untilted chord tangent) departs by up to 4.4 %,
    # the planner's own (the tilted tangent interpolated between waypoints) by 1.8 %.
    sigma = cols["s_mm"] + np.einsum("ki,ki->k", g["t"], g["pin"] - g["seam"])
    v = np.gradient(sigma[w], cols["t_s"][w])
    v_weld = problem.process.travel_speed * 1e3
    tol = toml.get("window", {}).get("speed_tol_pct", 5.0) / 100
    assert np.max(np.abs(v / v_weld - 1)) <= tol, name


@pytest.mark.parametrize("name", PROBLEMS)
def test_retract_at_the_process_speed_and_safe_heights(written, name):
    phase, cols, toml, problem = written(name)
    g = _geometry(cols, phase, toml)
    h = _height(g, problem.process.plunge_depth * 1e3)
    t = cols["t_s"]
    r = np.flatnonzero(phase == "retract")
    in_plate = r[h[r] < -TOL_MM]
    assert len(in_plate) > 10, name
    rise = np.gradient(h, t)[in_plate]
    v_ret = problem.process.retract_speed * 1e3
    assert np.max(rise) <= v_ret * 1.01, (name, np.max(rise), v_ret)
    # It does leave: the last in-plate sample is within a sample of the surface.
    assert np.max(h[in_plate]) > -v_ret * 0.02
    # The force does not vanish while the pin is still in the plate: it falls with the depth.
    fz = np.linalg.norm(np.stack([cols["fx_N"], cols["fy_N"], cols["fz_N"]], axis=1), axis=1)
    deep = in_plate[h[in_plate] < -0.5 * problem.process.plunge_depth * 1e3]
    assert np.all(fz[deep] > 0.4 * np.max(fz[phase == "weld"])), name
    # First and last samples at the safe height above the plate; the approach runs along
    # the tool axis.
    safe = (toml["process"].get("approach_height_mm")
            or toml.get("planning", {}).get("clearance_mm", 50.0))
    assert h[0] == pytest.approx(safe, abs=0.01), name
    assert h[-1] == pytest.approx(safe, abs=0.01), name
    a = np.flatnonzero(phase == "approach")
    axis = -g["z"][a[0]]
    rel = g["pin"][a] - g["pin"][a[0]]
    off = np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1)
    assert np.max(off) < 1e-3, name


def test_no_two_bundled_problems_give_identical_waypoints_without_a_reason(written):
    """The only bundled problems with identical plans are the seed 001 Fig. 10 co-simulation
    cases (the commanded plunge drives ``rfsw-plan deviation --cosim``, not the plan: the
    planner compensates the deflection to the planned depth; docs/formats/problem-files.md)."""
    explained = {frozenset({"zk500_plunge7mm", "zk500_table6_seam", "zk500_plunge9mm"})}
    seen: dict[bytes, list[str]] = {}
    for name in PROBLEMS:
        _, cols, _, _ = written(name)
        key = np.round(np.stack([cols["x_mm"], cols["y_mm"], cols["z_mm"]]), 6).tobytes()
        seen.setdefault(key, []).append(name)
    groups = [frozenset(v) for v in seen.values() if len(v) > 1]
    for grp in groups:
        assert any(grp <= e for e in explained), sorted(grp)


def test_kr600_curved_seam_holds_its_depth_and_names_it_limiting(written, planned_result):
    """Issue 32: GO on kr600_curved_seam lost 2.82 mm of penetration over s = 379-468 mm; now
    the depth is in its window at every weld sample (from the CSV). Issue 38: in position
    control its depth alone holds less than the requested +-10 %, so the verdict is HOLDS
    NOMINALLY, and the verdict names first the quantity with the smallest level (the pin
    speed, at the weld start where the traverse force builds, or the depth)."""
    phase, cols, toml, problem = written("kr600_curved_seam")
    res = planned_result("kr600_curved_seam")
    v = res.verdict()
    assert v.word == "HOLDS NOMINALLY" and v.claim is not None
    levels = v.claim.levels
    assert levels["depth"] < res.options.force_uncertainty
    first = min(levels, key=lambda q: levels[q])
    assert v.claim.limiting.quantity == first and v.line.split(": ")[2].startswith(first)
    g = _geometry(cols, phase, toml)
    depth = problem.process.plunge_depth * 1e3
    w = phase == "weld"
    err = _height(g, depth)[w] + depth
    assert np.min(err) >= -0.2 and np.max(err) <= 0.5, (np.min(err), np.max(err))


def test_a_failing_depth_is_named_first_with_where_how_much_and_its_levers(planned_result):
    """The written kr600 plan checked against a depth window narrower than its samples: the
    sample check's first envelope failure is the depth, with sample, time, phase, arc length,
    value, bound, and the depth's levers; the planner's error (the NO verdict) starts with it."""
    from dataclasses import replace as dc_replace

    from rfsw_plan.exceptions import InfeasibleError
    from rfsw_plan.planning.verify import verify_samples

    res = planned_result("kr600_curved_seam")
    narrow = dc_replace(res.window, depth_shallow=0.05e-3)
    sv = verify_samples(res.model, res.task, narrow, res.trajectory, res.options.margin, res.q)
    f = sv.envelope_failure
    assert f is not None and f.check == "depth" and f.quantity == "depth"
    assert f.value > 0.05 and f.bound == pytest.approx(0.05)
    assert f"sample {f.index + 1} (t = {res.trajectory.t[f.index]:.3f} s" in f.message
    with pytest.raises(InfeasibleError, match=r"^depth fails first: sample \d+ .*levers: axial "
                                              r"force control"):
        sv.raise_if_failed()
    # The same plan against its own window holds every envelope check.
    assert verify_samples(res.model, res.task, res.window, res.trajectory, res.options.margin,
                          res.q).ok


def test_force_control_holds_the_axial_force_so_only_traverse_and_lateral_spread(
        planned_result):
    """seed 000 welds in axial force control: the fanuc plan's task says so, its worst case has
    no axial share, and plan.json names the set force for the force_on hook."""
    from rfsw_plan.planning.verify import predict

    res = planned_result("fanuc_butt_1700mm")
    assert res.task.axial_control == "force"
    env = res.summary()["envelope"]
    assert env["axial_control"] == "force" and env["set_force_N"] == pytest.approx(3100.0)
    pos = predict(res.model, dc_position(res.task), res.q, 0.2)
    frc = predict(res.model, res.task, res.q, 0.2)
    w = res.task.weld
    assert np.all(frc.worst[w] < pos.worst[w])  # the axial spread is gone


def dc_position(task):
    from dataclasses import replace as dc_replace

    return dc_replace(task, axial_control="position")
