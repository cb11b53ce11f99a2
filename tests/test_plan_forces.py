"""``plan --forces``: fit the trial weld's force log, derive the force uncertainty, plan."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.io.force_series import read_force_series
from rfsw_plan.process.force_fit import derive_force_uncertainty, fit_process_forces
from rfsw_plan.process.problem import load_problem
from rfsw_plan.realtime.compare import planned_waypoints
from rfsw_plan.realtime.simulator import ProcessVariation, SimConfig
from rfsw_plan.realtime.trial_weld import simulate_trial_weld
from rfsw_plan.robot.kinematics import load_robot

PROBLEM = "zk500_table6_seam"


@pytest.fixture(scope="module")
def trial_log(tmp_path_factory: pytest.TempPathFactory, planned_result: Any) -> Path:
    """The force log of a virtual trial weld of the problem's plan (the session's
    ``planned_result``), written once per module: tests read it, never change it."""
    pb = load_problem(PROBLEM)
    model = ElastostaticModel(load_robot(pb.robot))
    tw = simulate_trial_weld(pb, planned_waypoints(planned_result(PROBLEM)), model)
    return tw.write(str(tmp_path_factory.mktemp("trial")))[0]


def test_uncertainty_is_drift_plus_three_sigma_per_phase(planned_result: Any) -> None:
    """Noise-only log (no drift): the weld bound is ~3 x the sensor noise; with a 10 %
    drift the axial bound grows by about 10 % of the axial force."""
    pb = load_problem(PROBLEM)
    model = ElastostaticModel(load_robot(pb.robot))
    wp = planned_waypoints(planned_result(PROBLEM))  # plan(PROBLEM), the session's
    frames = pb.frames()
    out = {}
    for amp in (0.0, 0.10):
        cfg = SimConfig(variation=ProcessVariation(amplitude=amp))
        series = simulate_trial_weld(pb, wp, model, config=cfg).forces
        fit = fit_process_forces(pb.process, frames, series, pb.planning.tool_rotation)
        out[amp] = derive_force_uncertainty(fit, frames, series, pb.planning.tool_rotation)
    quiet, drift = out[0.0], out[0.10]
    assert quiet.usable and drift.usable
    # Sensor noise 30 N per component: sigma ~ 30 N, bound ~ 3 sigma (+ a small drift part).
    np.testing.assert_allclose(quiet.sigma["weld"], 30.0, rtol=0.1)
    assert np.all(quiet.bound["weld"] < 3 * 30.0 * 1.3)
    axial = pb.process.forces.axial
    assert 0.08 * axial < drift.drift["weld"][2] < 0.11 * axial
    assert set(drift.bound) == {"plunge", "dwell", "weld"}


def test_plan_with_forces_stores_uncertainty_next_to_the_plan(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str],
                                                               trial_log: Path) -> None:
    log = trial_log
    out = tmp_path / "plan"
    assert main(["plan", PROBLEM, "--forces", str(log), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "R^2" in text and "+-" in text and "3 sigma" in text
    data = json.loads((out / "plan.json").read_text())
    fl = data["force_log"]
    assert fl["used"] is True
    unc = fl["measured_force_uncertainty"]
    assert unc["coverage_sigma"] == 3.0
    assert len(unc["bound_N"]["weld"]) == 3
    assert all(r2 > 0.8 for r2 in fl["fit"]["r2"])
    chk = fl["plan_under_measured_uncertainty"]
    # The plan was made for the relative box that covers the measured one.
    assert data["force_uncertainty"] == pytest.approx(chk["planned_relative_uncertainty"])
    assert chk["planned_relative_uncertainty"] >= chk["equivalent_relative_uncertainty"] * 0.999
    assert data["problem_file"] == "zk500_table6_seam"  # the bundled file by its name
    # The verdict comes first and never advises the calibration that was just used.
    assert text.splitlines()[0].split(":")[0] in ("GO", "HOLDS NOMINALLY")
    assert "plan --forces LOG.csv" not in text
    assert all(lv["done"] for lv in data["levers"] if lv["lever"] == "force_model")


def _rewrite(src: Path, dst: Path, fn: object) -> Path:
    with src.open() as fh:
        rows = list(csv.reader(fh))
    head = rows[0]
    body = [fn(head, r) for r in rows[1:]]  # type: ignore[operator]
    with dst.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(head)
        w.writerows(body)
    return dst


@pytest.mark.usefixtures("stored_plans")  # the unused log's plan is the problem's own
def test_log_the_model_cannot_describe_is_not_used(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str],
                                                   trial_log: Path) -> None:
    """Times shifted by 1000 s: no sample falls in the problem's phases -> exit 2 (no load);
    times compressed so the weld phase is not found -> one line, the plan does not use it."""
    log = trial_log
    short = _rewrite(log, tmp_path / "short.csv",
                     lambda h, r: [f"{float(r[0]) * 0.12:.6f}", *r[1:]])
    out = tmp_path / "plan"
    assert main(["plan", PROBLEM, "--forces", str(short), "-o", str(out)]) == 0
    cap = capsys.readouterr()
    assert sum("NOT used" in line for line in cap.err.splitlines()) == 1
    data = json.loads((out / "plan.json").read_text())
    assert data["force_log"]["used"] is False
    assert data["force_uncertainty"] == pytest.approx(0.2)  # the problem's, not the log's
    assert "plan_under_measured_uncertainty" not in data["force_log"]


def test_log_without_axial_force_is_one_line_exit_2(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str],
                                                    trial_log: Path) -> None:
    log = trial_log
    series = read_force_series(log)
    # Zero the component along the (nearly vertical) tool axis: fz in the base frame.
    assert abs(series.force[len(series) // 2, 2]) > 1000.0
    no_fz = _rewrite(log, tmp_path / "nofz.csv",
                     lambda h, r: [v if h[i] != "fz_N" else "0" for i, v in enumerate(r)])
    assert main(["plan", PROBLEM, "--forces", str(no_fz), "-o", str(tmp_path / "p")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no axial force" in err
    assert main(["plan", PROBLEM, "--forces-frame", "base", "-o", str(tmp_path / "p")]) == 2
