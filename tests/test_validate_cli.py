"""``rfsw-plan validate``: JSON contract, self-contained report, --add/--save-robot, bad input."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.elastostatics.effects import EFFECTS
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.io.measurements import write_measurements
from rfsw_plan.robot.kinematics import load_robot
from rfsw_plan.validation.campaign.simulation import run_campaign

FOLDS = "3"


@pytest.fixture(scope="module")
def campaign_csv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    data = run_campaign("zk500", ["payload_gravity"], poses=30, loads_per_pose=4,
                        noise_mm=0.01, seed=4).data
    return write_measurements(tmp_path_factory.mktemp("camp") / "campaign.csv", data)


def _run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_json_contract_and_report_files(
    campaign_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out_dir = tmp_path / "rep"
    code, out, err = _run(["validate", "--robot", "zk500", "--data", str(campaign_csv),
                           "--folds", FOLDS, "-o", str(out_dir), "--json"], capsys)
    assert code == 0, err
    js = json.loads(out)  # exactly one JSON object on stdout
    assert js["verdict"] == "missing"
    assert js["missing"] == {**js["missing"], "effect": "payload_gravity", "joint": None}
    assert js["rms_mm"] > 0.05 and 0.005 < js["noise_floor_mm"] < 0.02
    cands = js["candidates"]
    assert cands[0]["effect"] == "payload_gravity" and cands[0]["joint"] is None
    assert [c["rms_after_mm"] for c in cands] == sorted(c["rms_after_mm"] for c in cands)
    for c in cands:
        assert c["effect"] in EFFECTS
        assert c["joint"] is None or isinstance(c["joint"], int)
        assert isinstance(c["explained_fraction"], float)
    assert {s["label"] for s in js["not_identifiable"]} >= {"torque_dependent_stiffness:j6"}

    saved = json.loads((out_dir / "validate.json").read_text())
    assert saved["verdict"] == js["verdict"] and saved["candidates"] == js["candidates"]
    html = (out_dir / "report.html").read_text()
    assert "data:image/png;base64," in html
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//)""", html)  # offline
    # the 3-D residual view (issue 35) is inline script: nothing loaded from a file or a server
    assert not re.search(r"""<script[^>]*\bsrc\s*=\s*["'](?!data:)""", html)
    assert "payload_gravity" in html and "MISSING" in html
    for name in ("residual_histogram", "residual_vs_time", "residual_vs_torque",
                 "residual_vs_force", "workspace_map", "candidates", "correlations"):
        png = out_dir / f"{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert html.count("data:image/png;base64,") >= 7


def test_add_and_save_robot_feed_predict(
    campaign_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    new = tmp_path / "zk500_payload.toml"
    code, out, err = _run(["validate", "--robot", "zk500", "--data", str(campaign_csv),
                           "--folds", FOLDS, "--add", "payload_gravity", "--save-robot",
                           str(new), "-o", str(tmp_path / "rep")], capsys)
    assert code == 0, err
    assert "verdict: adequate" in out
    assert "joint_compliance, payload_gravity" in out  # before/after table
    assert (tmp_path / "rep" / "before_after.png").exists()
    js = json.loads((tmp_path / "rep" / "validate.json").read_text())
    add = js["add"]
    assert add["added"] == ["payload_gravity"]
    assert add["heldout_rms_after_mm"] < 0.1 * add["heldout_rms_before_mm"]
    assert add["heldout_rms_after_mm"] <= 1.5 * js["noise_floor_mm"]

    # The saved description carries the effect; predict uses it.
    extended = ElastostaticModel(load_robot(new))
    assert extended.labels == ["joint_compliance", "payload_gravity"]
    mass = extended.effects[1].params[0]
    assert 50.0 < mass < 300.0
    q = "0,20,-10,0,80,0"
    code, out_new, _ = _run(["predict", "--robot", str(new), "--q-deg", q, "--wrench",
                             "0,0,3000", "--json"], capsys)
    assert code == 0
    code, out_old, _ = _run(["predict", "--robot", "zk500", "--q-deg", q, "--wrench",
                             "0,0,3000", "--json"], capsys)
    p_new, p_old = json.loads(out_new), json.loads(out_old)
    assert p_new["effects"] == ["joint_compliance", "payload_gravity"]
    expected = extended.deflection(np.radians([0.0, 20, -10, 0, 80, 0]),
                                   np.array([0.0, 0, 3000, 0, 0, 0]))
    np.testing.assert_allclose(p_new["translation_mm"], expected[:3] * 1e3, rtol=1e-9)
    assert not np.allclose(p_new["translation_mm"], p_old["translation_mm"])

    # The extended robot never gets payload_gravity suggested again.
    code, out, _ = _run(["validate", "--robot", str(new), "--data", str(campaign_csv),
                         "--folds", FOLDS, "--json", "--no-report"], capsys)
    js2 = json.loads(out)
    assert js2["verdict"] == "adequate"
    assert "payload_gravity" not in [c["effect"] for c in js2["candidates"]]


def test_text_summary_without_json(campaign_csv: Path, tmp_path: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(["validate", "--robot", "zk500", "--data", str(campaign_csv),
                         "--folds", FOLDS, "--no-report", "--noise-mm", "0.01"], capsys)
    assert code == 0
    assert "noise floor 0.01 mm (given)" in out
    assert "verdict: missing: payload_gravity" in out


def _write(path: Path, header: list[str], rows: list[list[object]]) -> Path:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    return path


def _one_line_error(code: int, err: str, *needles: str) -> None:
    assert code != 0
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for n in needles:
        assert n in lines[0], lines[0]


def test_bad_input_gives_one_line_errors(
    campaign_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["validate", "--robot", "zk500", "--folds", FOLDS, "--no-report"]
    q = [f"q{j}_deg" for j in range(1, 7)]
    forces = ["fx_N", "fy_N", "fz_N"]
    row: list[object] = [0, 10, -10, 0, 80, 0, 0, 0, 1000]

    no_axis = _write(tmp_path / "no_axis.csv", q + forces, [row] * 10)
    code, _, err = _run([*base, "--data", str(no_axis)], capsys)
    _one_line_error(code, err, "no_axis.csv", "no measured TCP axis")

    blank = _write(tmp_path / "blank.csv", [*q, *forces, "x_mm"], [[*row, ""]] * 10)
    code, _, err = _run([*base, "--data", str(blank)], capsys)
    _one_line_error(code, err, "blank.csv", "blank")

    tcp = load_robot("zk500").fk(np.radians(np.array(row[:6], dtype=float)))[:3, 3] * 1e3
    few = _write(tmp_path / "few.csv", ["pose_id", *q, *forces, "x_mm", "y_mm", "z_mm"],
                 [[f"P{i}", *row, tcp[0] + i, tcp[1], tcp[2]] for i in range(3)])
    code, _, err = _run([*base, "--data", str(few)], capsys)
    _one_line_error(code, err, "few.csv", "need at least")

    five = _write(tmp_path / "five.csv", [*q[:5], *forces, "x_mm"], [[*row[:5], 0, 0, 1, 1]])
    code, _, err = _run([*base, "--data", str(five)], capsys)
    _one_line_error(code, err, "five.csv", "5 joints", "6")

    data = ["--data", str(campaign_csv)]
    code, _, err = _run([*base, *data, "--add", "thermal_expansion"], capsys)
    _one_line_error(code, err, "unknown effect 'thermal_expansion'", "payload_gravity",
                    "joint_backlash")

    code, _, err = _run([*base, *data, "--add", "tilting_compliance:j9"], capsys)
    _one_line_error(code, err, "tilting_compliance:j9", "out of range", "1..6")

    code, _, err = _run([*base, *data, "--add", "tilting_compliance"], capsys)
    _one_line_error(code, err, "needs a joint")

    code, _, err = _run([*base, *data, "--add", "joint_compliance"], capsys)
    _one_line_error(code, err, "already in the model")

    code, _, err = _run([*base, *data, "--noise-mm", "-1"], capsys)
    _one_line_error(code, err, "--noise-mm")

    code, _, err = _run([*base, *data, "--folds", "50"], capsys)
    _one_line_error(code, err, "30 distinct poses", "50 folds")


def test_unidentifiable_added_effect_is_reported_not_fitted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Joint 6's axis passes through the TCP: its torque-dependent stiffness cannot move the
    # measured position, so it is reported and left out of the model.
    data = run_campaign("zk500", [], poses=20, loads_per_pose=2, noise_mm=0.01, seed=2).data
    csv_path = write_measurements(tmp_path / "c.csv", data)
    code, out, err = _run(["validate", "--robot", "zk500", "--data", str(csv_path), "--folds",
                           FOLDS, "--no-report", "--json", "--add",
                           "torque_dependent_stiffness:j6"], capsys)
    assert code == 0, err
    js = json.loads(out)
    assert js["add"]["not_added"][0]["label"] == "torque_dependent_stiffness:j6"
    assert "does not move the measured TCP" in js["add"]["not_added"][0]["reason"]
    assert js["add"]["added"] == []
    assert js["model_effects"] == ["joint_compliance"]

    # An effect whose own check fails is not fitted either (backlash needs both torque signs).
    one_sign = data.subset(np.einsum("ma,ma->m", load_robot("zk500").batch_fk_jacobian(
        data.q)[1][:, :, 0], data.wrench) >= 0)
    csv2 = write_measurements(tmp_path / "one_sign.csv", one_sign)
    code, out, err = _run(["validate", "--robot", "zk500", "--data", str(csv2), "--folds",
                           FOLDS, "--no-report", "--json", "--add", "joint_backlash:j1"], capsys)
    assert code == 0, err
    reason = json.loads(out)["add"]["not_added"][0]["reason"]
    assert "does not change sign" in reason


def test_json_writes_no_report_and_a_default_report_never_overwrites(
    campaign_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Issue 24: --json prints JSON and writes a report folder only with -o; the default
    folder is never overwritten silently: a second run writes beside it and says where."""
    monkeypatch.chdir(tmp_path)
    base = ["validate", "--robot", "zk500", "--data", str(campaign_csv), "--folds", FOLDS]
    code, out, err = _run([*base, "--json"], capsys)
    assert code == 0, err
    assert json.loads(out)["verdict"] == "missing"
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    code, out, _ = _run(base, capsys)
    assert code == 0 and "report: out/validate/campaign/report.html" in out
    first = (tmp_path / "out/validate/campaign" / "validate.json").read_bytes()
    code, out, _ = _run(base, capsys)
    assert code == 0 and "report: out/validate/campaign_2/report.html" in out
    assert (tmp_path / "out/validate/campaign" / "validate.json").read_bytes() == first
    assert sorted(p.name for p in (tmp_path / "out/validate").iterdir()) == ["campaign",
                                                                          "campaign_2"]
