"""Real motion-capture data of a PAL TIAGo arm (FIGAROH, Apache-2.0): issues 12 §5 and 27.

Fit on the 2021-11-30 recording, predict the 2021-11-26 recording with everything held as
fitted. The reference figures (FIGAROH, the data set's README): registration only 3.37 mm on
training and 4.87 mm held out; with the joint offsets of arm_2..arm_6 2.88 / 4.23 mm, arm_5
about -50 +- 10 mrad; full_params (31 parameters) 1.64 / 3.07 mm. RMS of the 3-D error of
point 1. The model is chosen on 11-30 and physics (examples/figaroh_tiago/fit.sh), never on
11-26.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.elastostatics.identification import identify
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel, load_model
from rfsw_plan.elastostatics.registration import prepare_device_setup
from rfsw_plan.io.measurements import read_measurements
from rfsw_plan.robot.description import load_robot_description

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "figaroh_tiago"
TRAIN = DATA / "qualisys_2021-11-30_static_postures.csv"
TEST = DATA / "qualisys_2021-11-26_static_postures.csv"
COLUMNS = ROOT / "examples" / "figaroh_tiago" / "columns.toml"

pytestmark = pytest.mark.skipif(not TRAIN.is_file(), reason="shared/data/figaroh_tiago absent")


def _read(path: Path, model: ElastostaticModel) -> MeasurementSet:
    r = model.robot
    return read_measurements(path, r.nq, prismatic=list(r.prismatic), columns=COLUMNS)


def _rms3(res: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(res**2, axis=1))) * 1e3)


def _fit_and_hold_out(free: list[str], add: list[str]) -> tuple[float, float, list]:
    """(training RMS 3-D, held-out RMS 3-D [mm], estimates) of one model form."""
    model = load_model("tiago_arm")
    train, test = _read(TRAIN, model), _read(TEST, model)
    setup = prepare_device_setup(model, train)
    form = setup.model(model)
    for label in add:
        form = form.with_effect(label)
    fit = identify(form, setup.data(train), free=[*free, *setup.effect_labels, *add])
    db = setup.data(train)
    res_train = db.position - fit.model.predict_position(db.q, db.wrench)
    fitted, frame = setup.fold(fit.model, fit.estimates)
    held = prepare_device_setup(fitted, test, held=frame)
    dt = held.data(test)
    res_test = dt.position - held.model(fitted).predict_position(dt.q, dt.wrench)
    return _rms3(res_train), _rms3(res_test), list(fit.estimates)


def test_chain_matches_the_table_and_carries_the_link_masses() -> None:
    """FK of the generated URDF equals the table's joint transforms composed by hand."""
    table = json.loads((DATA / "tiago_arm_chain.json").read_text())
    model = load_model("tiago_arm")
    robot = model.robot
    assert robot.nq == 8 and list(robot.prismatic) == [True] + [False] * 7
    assert robot.joint_names[0] == "torso_lift_joint" and robot.joint_names[-1] == "arm_7_joint"

    def rpy(r: float, p: float, y: float) -> np.ndarray:
        cx, sx, cy, sy, cz, sz = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
        Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        return Rz @ Ry @ Rx

    rng = np.random.default_rng(0)
    for _ in range(5):
        q = rng.uniform(robot.description.lower, robot.description.upper)
        T = np.eye(4)
        k = 0
        for j in table["joints"]:
            M = np.eye(4)
            M[:3, :3] = rpy(*j["origin_rpy_rad"])
            M[:3, 3] = j["origin_xyz_m"]
            T = T @ M
            if j["type"] == "revolute":
                M = np.eye(4)
                M[:3, :3] = rpy(0.0, 0.0, q[k]) if j["axis"] == [0, 0, 1] else np.eye(3)
                T, k = T @ M, k + 1
            elif j["type"] == "prismatic":
                M = np.eye(4)
                M[:3, 3] = np.asarray(j["axis"]) * q[k]
                T, k = T @ M, k + 1
        np.testing.assert_allclose(robot.fk(q), T, atol=1e-12)
    # The arm's own weight loads the joints: ~ the total mass after the torso lift, along z.
    tau = robot.gravity_torque(np.zeros((1, 8)))[0]
    mass = sum(j["child_inertial"]["mass_kg"] for j in table["joints"][1:])  # lift and after
    assert tau[0] == pytest.approx(-mass * 9.81, rel=1e-3)
    desc = load_robot_description("tiago_arm")
    assert "ASSUMED" in desc.sources["stiffness"]


def test_registration_only_reproduces_the_reference_and_offsets_beat_it() -> None:
    reg_train, reg_test, _ = _fit_and_hold_out([], [])
    # Registration only (9 parameters), as the reference: 3.37 / 4.87 mm.
    assert reg_train == pytest.approx(3.37, abs=0.05)
    assert reg_test == pytest.approx(4.87, abs=0.05)
    _off_train, off_test, est = _fit_and_hold_out([], ["kinematic_offsets"])
    assert off_test < reg_test
    assert off_test == pytest.approx(4.23, abs=0.1)  # reference with arm_2..arm_6 offsets
    dq = {e.name: e for e in est if e.effect == "kinematic_offsets"}
    # A free registration absorbs torso_lift (vertical slide), arm_1 (vertical axis) and
    # arm_7 (turns the marker like the marker offset): named, not fitted.
    for name in ("dq1", "dq2", "dq8"):
        assert not dq[name].identified and "registration absorbs" in dq[name].note
    assert all(dq[f"dq{j}"].identified for j in range(3, 8))
    arm5 = dq["dq6"]
    assert -0.08 < arm5.value < -0.03 and arm5.std_error < 0.02  # reference: -50 +- 10 mrad
    # Beyond the reference: the links' own weight through the joint compliance.
    _, grav_test, _ = _fit_and_hold_out(["joint_compliance"], ["kinematic_offsets"])
    assert grav_test < off_test


def test_cli_fit_save_and_hold_out(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The scripted workflow of the README, through the CLI."""
    common = ["--columns", str(COLUMNS), "--frame", "device", "--no-report"]
    reg, fitted = tmp_path / "REG.toml", tmp_path / "FITTED.toml"
    assert main(["validate", "--robot", "tiago_arm", "--data", str(TRAIN), *common,
                 "--save-robot", str(reg)]) == 0
    text = capsys.readouterr().out
    # The diagnosis names arm_6's lost motion first (by approach direction: the recording
    # has no force sensor) with its play, the joint offsets next, and says the floor is
    # unknown.
    lines = text.splitlines()
    first = lines.index("best candidates (held-out RMS after adding):") + 1
    assert lines[first].split()[0] == "lost_motion:j7", text
    assert "kinematic_offsets" in "\n".join(lines[first:first + 5])
    assert "lost_motion:j7 parameters beyond 2 standard errors: b 0.0" in text
    assert "floor is unknown" in text
    assert main(["validate", "--robot", "tiago_arm", "--data", str(TRAIN), *common,
                 "--add", "kinematic_offsets", "--save-robot", str(fitted)]) == 0
    capsys.readouterr()
    desc = load_robot_description(fitted)
    assert desc.device_frame is not None and desc.device_frame.std
    assert [e.name for e in desc.effects] == ["kinematic_offsets"]
    results = {}
    for name, robot in (("registration", reg), ("kinematic_offsets", fitted)):
        assert main(["validate", "--robot", str(robot), "--data", str(TEST), *common,
                     "--json"]) == 0
        js = json.loads(capsys.readouterr().out)
        assert js["device_frame"]["registration"] == "held"
        assert js["rms_3d_mm"] == pytest.approx(np.sqrt(3) * js["rms_mm"], rel=0.2)
        results[name] = js["rms_3d_mm"]
    # Held out, nothing refitted: joint compliance under gravity is in both.
    assert results["kinematic_offsets"] < results["registration"] < 4.87
    assert results["kinematic_offsets"] < 4.3


#: FIGAROH's best on the same split: full_params (31 parameters), norm RMSE of point BL on
#: 11-26 after fitting on 11-30 [mm].
FIGAROH_FULL_PARAMS_HELDOUT_MM = 3.07
#: The model fit.sh chooses on 11-30 (its forward selection adds more lost motion; this is
#: its core, which the default test run checks): geometry and arm_6's lost motion.
CORE = ("kinematic_offsets", "link_errors", "lost_motion:j7")


def test_geometry_and_arm6_lost_motion_beat_figaroh_held_out(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 27: fit on 11-30, hold out 11-26 with nothing refitted: norm RMSE of point BL at
    or below FIGAROH's full_params, with every identified parameter plausible."""
    common = ["--columns", str(COLUMNS), "--frame", "device", "--no-report"]
    fitted = tmp_path / "FITTED.toml"
    adds = [x for label in CORE for x in ("--add", label)]
    assert main(["validate", "--robot", "tiago_arm", "--data", str(TRAIN), *common, *adds,
                 "--save-robot", str(fitted), "--json"]) == 0
    fit = json.loads(capsys.readouterr().out)
    assert main(["validate", "--robot", str(fitted), "--data", str(TEST), *common,
                 "--json"]) == 0
    held = json.loads(capsys.readouterr().out)
    assert held["device_frame"]["registration"] == "held"
    assert held["rms_3d_mm"] <= FIGAROH_FULL_PARAMS_HELDOUT_MM
    # Training cross-validation: arm_6's lost motion carries the gain over the geometry.
    assert fit["diagnosis"]["heldout_rms_mm"] < 2.0
    model = load_model(str(fitted))
    by_label = {e.label: e for e in model.effects}
    # arm_6 play: tens of mrad (the FIGAROH authors: about 40 mrad of free play).
    assert 0.015 < by_label["lost_motion:j7"].params[0] < 0.06
    # Every link error within its plausible size (5 mm, 3 deg): a calibration, not a stand-in.
    links = by_label["link_errors"]
    for name, value in links.param_dict().items():
        limit = links.plausible_limit(name)
        assert limit is not None and abs(value) <= limit, name
    # No joint softer than 100 N m/rad: arm_6 keeps its prior instead of standing in.
    assert np.all(model.stiffness[1:] >= 100.0)
    assert model.stiffness[6] == pytest.approx(3000.0)


#: The held-out figure of fit.sh on 11-26 before it became one `rfsw-plan calibrate` [mm].
FIT_SH_HELDOUT_MM = 2.78


@pytest.mark.slow
def test_fit_sh_chooses_on_training_and_beats_figaroh(tmp_path: Path) -> None:
    """The recommended fit as a user runs it: examples/figaroh_tiago/fit.sh, which is one
    `rfsw-plan calibrate` (model chosen on 11-30 only) and a `validate` of 11-26."""
    fitted = tmp_path / "FITTED.toml"
    env = {**os.environ, "PYTHON": sys.executable}
    out = subprocess.run([str(ROOT / "examples" / "figaroh_tiago" / "fit.sh"), str(TRAIN),
                          str(fitted), str(TEST)], capture_output=True, text=True, env=env,
                         check=True).stdout
    assert any(line.split()[:1] == ["lost_motion:j7"] for line in out.splitlines())
    assert "held out (leave-one-pose-group-out, 37 pose groups)" in out
    row = next(line for line in out.splitlines() if "held out, nothing refitted" in line)
    heldout = float(row.split("refitted: ")[1].split()[0])
    assert heldout <= FIT_SH_HELDOUT_MM <= FIGAROH_FULL_PARAMS_HELDOUT_MM
    assert load_model(str(fitted)).robot.description.device_frame is not None


def test_too_few_poses_to_register(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    lines = TRAIN.read_text().splitlines()
    few = tmp_path / "few.csv"
    few.write_text("\n".join(lines[:4]) + "\n")
    out = tmp_path / "x.toml"
    code = main(["identify", "--robot", "tiago_arm", "--data", str(few), "--columns",
                 str(COLUMNS), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "need at least 4 distinct poses" in err
    assert not out.exists()
