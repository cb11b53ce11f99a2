"""What the planner writes is what it verified, sample by sample (issue 9 §1-3)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.exceptions import InfeasibleError
from rfsw_plan.planfiles.folder import PlanFolder
from rfsw_plan.planfiles.waypoints import Q_RESOLUTION
from rfsw_plan.planning.verify import CONTACT_PHASES, verify_samples
from rfsw_plan.timing.trajectory import monotone_interp

BUNDLED = ("zk500_table6_seam", "fanuc_butt_1700mm", "kr600_curved_seam")


def _reject(c: str) -> float:
    raise ValueError(f"non-strict JSON constant {c}")


@pytest.fixture(scope="module")
def planned(tmp_path_factory, plan_folder):
    """Every bundled plan folder as ``rfsw-plan -q plan NAME -o DIR`` writes it, the session's
    (``plan_folder``: written once per session from the session's plan, for every test that
    reads it; ``rfsw_plan.write_plan`` writes the same files: tests/test_examples.py)."""
    return {name: plan_folder(name, tmp_path_factory.mktemp(name) / "plan") for name in BUNDLED}


@pytest.mark.parametrize("name", BUNDLED)
def test_every_written_in_material_sample_is_inside_the_window(planned, planned_result,
                                                               name) -> None:
    d = planned[name]
    rec = PlanFolder.open(d).record  # the commit record vouches for the files beside it
    assert set(rec["sha256"]) == {"waypoints.csv", "plan.html", "lateral_error.png",
                                  "lateral_error_time.png", "tradeoff.png"}
    res = planned_result(name)
    written = PlanFolder.open(d).samples
    assert len(written.t) == len(res.trajectory)
    sv = verify_samples(res.model, res.task, res.window, written, res.options.margin, res.q,
                        Q_RESOLUTION)
    assert sv.ok, sv.failures[0].message
    # In the material: the contact phases less the plunge's start in the air above the plate.
    c = np.isin(written.phase, CONTACT_PHASES)
    assert sv.contact.sum() > 1000 and not np.any(sv.contact & ~c)
    air = c & ~sv.contact
    assert air.any() and set(written.phase[air]) == {"plunge"}
    assert sv.min_margin >= res.options.margin - 1e-6
    # The file's own columns say the same.
    rows = np.genfromtxt(d / "waypoints.csv", delimiter=",", names=True, dtype=None,
                         encoding="utf-8")
    np.testing.assert_array_equal(np.isfinite(rows["margin_mm"]), sv.contact)
    c = sv.contact
    assert np.nanmin(rows["margin_mm"][c]) >= res.options.margin * 1e3 - 1e-3
    assert rec["samples"]["verified"] is True
    assert rec["tolerated_force_uncertainty"] == pytest.approx(res.tolerated_force_uncertainty)


@pytest.mark.parametrize("name", BUNDLED)
def test_plunge_and_dwell_samples_stay_between_their_neighbouring_waypoints(planned_result,
                                                                          name) -> None:
    res = planned_result(name)
    tr = res.trajectory
    m = res.task.n_start
    qw = res.q[:m + 1]
    # The plunge starts in the air at the spindle clearance, above the first plunge
    # waypoint on its tool axis: from there on it stays between the waypoints.
    x = res.model.robot.batch_fk_jacobian(tr.q)[0][:, :3, 3]
    x0 = res.model.robot.batch_fk_jacobian(res.q[:1])[0][0, :3, 3]
    in_air = (x - x0) @ res.task.frames.n[0] > 1e-9
    assert in_air[tr.phase == "plunge"].any()
    for ph in ("plunge", "dwell"):
        rows = (tr.phase == ph) & ~in_air
        if rows.any():
            assert np.all(tr.q[rows] >= qw.min(axis=0) - 1e-12)
            assert np.all(tr.q[rows] <= qw.max(axis=0) + 1e-12)


def test_monotone_interp_never_overshoots() -> None:
    rng = np.random.default_rng(0)
    for _ in range(50):
        xk = np.cumsum(rng.uniform(0.01, 3.0, 6))
        yk = rng.normal(size=(6, 3))
        x = np.linspace(xk[0], xk[-1], 997)
        y = monotone_interp(xk, yk, x, rest_ends=True)
        i = np.clip(np.searchsorted(xk, x, side="right") - 1, 0, 4)
        assert np.all(y >= np.minimum(yk[i], yk[i + 1]) - 1e-15)
        assert np.all(y <= np.maximum(yk[i], yk[i + 1]) + 1e-15)
        assert np.allclose(monotone_interp(xk, yk, xk), yk)


def test_a_swinging_dwell_is_refused_naming_the_first_sample(planned_result) -> None:
    """The old clamped spline swung the fanuc dwell by 15 mm; a swing of that kind is caught
    at its first sample, with time, phase, value and bound."""
    res = planned_result("fanuc_butt_1700mm")
    tr = res.trajectory
    dw = np.flatnonzero(tr.phase == "dwell")
    q = tr.q.copy()
    bump = np.sin(np.linspace(0, np.pi, len(dw)))
    q[dw, 0] += np.deg2rad(0.8) * bump  # ~ the swing seen before the fix
    bad = replace(tr, q=q)
    sv = verify_samples(res.model, res.task, res.window, bad, res.options.margin, res.q)
    assert not sv.ok
    f = sv.first_failure
    assert f is not None and f.phase == "dwell" and dw[0] <= f.index <= dw[-1]
    assert f"sample {f.index + 1} (t = {tr.t[f.index]:.3f} s, dwell" in f.message
    assert "bound" in f.message
    with pytest.raises(InfeasibleError, match=r"fails first: sample \d+ \(t = "):
        sv.raise_if_failed()


@pytest.mark.usefixtures("stored_plans")  # the session's plans (conftest)
def test_robust_status_warning_and_robust_hard(tmp_path, capsys) -> None:
    out = tmp_path / "f"
    assert main(["-q", "plan", "fanuc_butt_1700mm", "-o", str(out)]) == 0
    cap = capsys.readouterr()
    rec = json.loads((out / "plan.json").read_text(), parse_constant=_reject)
    assert rec["status"] == "optimal_nominal"
    tol = rec["tolerated_force_uncertainty"]
    assert 0.0 < tol < 0.2
    # The verdict comes first, then its levers (issue 24).
    lines = cap.out.splitlines()
    assert lines[0].startswith("HOLDS NOMINALLY: ") and rec["verdict"] == "HOLDS NOMINALLY"
    refuse = lines.index("  to refuse such plans instead: --set robust_hard=true")
    head = "\n".join(lines[:refuse + 1])
    for part in (f"+-{100 * tol:.3g} %", "not the requested +-20 %", "robust_hard=true",
                 "placement", "trial weld", "hybrid"):
        assert part in head
    assert f"holds up to +-{100 * tol:.3g} %" in cap.out
    # robust_hard refuses it: exit 3, nothing claiming success.
    assert main(["-q", "plan", "fanuc_butt_1700mm", "-o", str(out), "--set",
                 "robust_hard=true"]) == 3
    rec = json.loads((out / "plan.json").read_text(), parse_constant=_reject)
    assert rec["status"] == "infeasible" and rec["message"]
    assert not (out / "waypoints.csv").exists()
    # A requested uncertainty below the tolerated one is held: plain optimal.
    assert main(["-q", "plan", "fanuc_butt_1700mm", "-o", str(out), "--force-uncertainty",
                 f"{0.5 * tol:.6f}"]) == 0
    rec = json.loads((out / "plan.json").read_text(), parse_constant=_reject)
    assert rec["status"] == "optimal" and rec["robust_window_held"] is True


@pytest.mark.parametrize("sets", [["margin_mm=1"], ["margin_mm=0.975"]])
def test_ill_posed_options_are_refused_before_the_solver(tmp_path, capsys, sets) -> None:
    args = ["-q", "plan", "zk500_table6_seam", "-o", str(tmp_path / "o")]
    for s in sets:
        args += ["--set", s]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "margin_mm" in err and "0.975" in err
    assert not (tmp_path / "o").exists()  # refused before anything was done
