"""``rfsw-plan predict`` / ``identify`` / ``robots`` in-process: outputs and bad input (§7, §9)."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from rfsw_plan.cli.main import main
from rfsw_plan.elastostatics.effects import JointCompliance
from rfsw_plan.elastostatics.model import ElastostaticModel, load_model
from rfsw_plan.io.measurements import MeasurementSet, write_measurements
from rfsw_plan.robot.description import bundled_robot_names, load_robot_description

Q_DEG = "-82.58,41.65,18.67,0,29.68,15.42"


def inside_pose(name: str) -> str:
    """A pose well inside the robot file's joint limits [deg], as the CLI takes it."""
    d = load_robot_description(name)
    q = (d.lower + d.upper) / 2 + 0.15 * (d.upper - d.lower) * np.array([1, -1, 1, -1, 1, -1])
    return ",".join(f"{v:.3f}" for v in np.degrees(q))


Q_KUKA = inside_pose("kuka_kr600_r2830")
POSE = {"zk500": Q_DEG, "kuka_kr600_r2830": Q_KUKA}
WRENCH = "-845.9,-1272.9,4842.58,10,-20,5"


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code: int, out: str, err: str, *needles: str) -> None:
    assert code == 2, (code, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for n in needles:
        assert n in lines[0], (n, lines[0])


# -- predict ------------------------------------------------------------------------------------
@pytest.mark.parametrize("robot", ["zk500", "kuka_kr600_r2830"])
def test_predict_json_matches_model(capsys: pytest.CaptureFixture[str], robot: str) -> None:
    code, out, _ = run(capsys, "predict", "--robot", robot, "--q-deg", POSE[robot],
                       "--wrench", WRENCH, "--json")
    assert code == 0
    rep = json.loads(out)
    model = load_model(robot)
    q = np.radians([float(v) for v in POSE[robot].split(",")])
    dX = model.deflection(q, np.array([float(v) for v in WRENCH.split(",")]))
    np.testing.assert_allclose(rep["translation_mm"], dX[:3] * 1e3, rtol=1e-12)
    np.testing.assert_allclose(rep["rotation_mrad"], dX[3:] * 1e3, rtol=1e-12)
    assert rep["effects"] == model.labels


def test_predict_applies_robot_file_effects(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "predict", "--robot", "kuka_kr600_r2830", "--q-deg", Q_KUKA,
                       "--wrench", WRENCH, "--json")
    assert code == 0
    with_tilt = np.array(json.loads(out)["translation_mm"])
    base = load_model("kuka_kr600_r2830")
    joint_only = ElastostaticModel(base.robot, [JointCompliance(base.robot)])
    q = np.radians([float(v) for v in Q_KUKA.split(",")])
    d0 = joint_only.deflection(q, np.array([float(v) for v in WRENCH.split(",")]))[:3] * 1e3
    assert np.linalg.norm(with_tilt - d0) > 1e-3  # tilting moves the TCP by > 1 um


def test_predict_text_and_three_force_values(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "predict", "--robot", "zk500", "--q-deg", Q_DEG,
                       "--wrench", "100,200,4800")
    assert code == 0
    assert "translation [mm]" in out and "rotation    [mrad]" in out


def test_predict_accepts_robot_file_path(capsys: pytest.CaptureFixture[str]) -> None:
    path = str(load_robot_description("zk500").path)
    code, out, _ = run(capsys, "predict", "--robot", path, "--q-deg", Q_DEG, "--wrench", WRENCH,
                       "--json")
    assert code == 0 and "translation_mm" in json.loads(out)


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--robot", "zk5000", "--q-deg", Q_DEG, "--wrench", WRENCH],
         ["unknown robot 'zk5000'", *bundled_robot_names()]),
        (["--robot", "zk500", "--q-deg", "1,2,3,4,5", "--wrench", WRENCH],
         ["--q-deg", "got 5 values", "6 joint values"]),
        (["--robot", "zk500", "--q-deg", "1,2,3,4,5,6,7", "--wrench", WRENCH],
         ["--q-deg", "got 7 values"]),
        (["--robot", "zk500", "--q-deg", "1,2,3,4,5,abc", "--wrench", WRENCH],
         ["--q-deg", "'abc' is not a number"]),
        (["--robot", "zk500", "--q-deg", "1,2,3,4,5,nan", "--wrench", WRENCH],
         ["--q-deg", "NaN"]),
        (["--robot", "zk500", "--q-deg", Q_DEG, "--wrench", "1,2,3,4"],
         ["--wrench", "got 4 values"]),
        (["--robot", "zk500", "--q-deg", "0,120,0,0,0,0", "--wrench", WRENCH],
         ["joint 2", "outside its limits"]),
        (["--robot", "zk500", "--q-deg", Q_DEG], ["required", "--wrench"]),
        (["--robot", "zk500", "--q-deg", Q_DEG, "--wrench", WRENCH, "--bogus"],
         ["unrecognized arguments", "--bogus"]),
    ],
)
def test_predict_bad_input(capsys: pytest.CaptureFixture[str], args: list[str],
                           needles: list[str]) -> None:
    assert_one_line_error(*run(capsys, "predict", *args), *needles)


def test_predict_non_positive_stiffness_file(capsys: pytest.CaptureFixture[str],
                                             tmp_path: Path) -> None:
    raw = tomllib.loads(Path(load_robot_description("zk500").path).read_text())  # type: ignore[arg-type]
    raw["stiffness"]["k_Nm_per_rad"][3] = -1.0
    p = tmp_path / "soft.toml"
    p.write_text(tomli_w.dumps(raw))
    assert_one_line_error(
        *run(capsys, "predict", "--robot", str(p), "--q-deg", Q_DEG, "--wrench", WRENCH),
        str(p), "joint 4 is -1",
    )


@pytest.mark.parametrize("cmd", ["predict", "identify", "robots"])
def test_every_subcommand_answers_help(capsys: pytest.CaptureFixture[str], cmd: str) -> None:
    code, out, _ = run(capsys, cmd, "--help")
    assert code == 0 and "usage:" in out


def test_unknown_subcommand_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert_one_line_error(*run(capsys, "predcit"), "invalid choice")


# -- identify -----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def truth() -> tuple[ElastostaticModel, np.ndarray]:
    base = load_model("zk500")
    k_true = base.stiffness * np.array([0.8, 1.5, 0.7, 1.3, 0.6, 2.0])
    params = {f"c{j + 1}": 1.0 / k for j, k in enumerate(k_true)}
    return ElastostaticModel(base.robot, [JointCompliance(base.robot, None, params)]), k_true


@pytest.fixture()
def data_file(tmp_path: Path, truth: tuple[ElastostaticModel, np.ndarray]) -> Path:
    model, _ = truth
    rng = np.random.default_rng(3)
    d = model.robot.description
    mid, half = (d.lower + d.upper) / 2, (d.upper - d.lower) / 2
    Q = rng.uniform(mid - 0.5 * half, mid + 0.5 * half, size=(30, 6))
    F = np.zeros((30, 6))
    F[:, :3] = rng.normal(size=(30, 3)) * 3000.0
    pos = model.predict_position(Q, F)
    return write_measurements(tmp_path / "load.csv", MeasurementSet(Q, F, pos))


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_identify_json_and_output_file(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                       data_file: Path, truth: tuple, method: str) -> None:
    _, k_true = truth
    out_file = tmp_path / "zk500_identified.toml"
    code, out, err = run(capsys, "identify", "--robot", "zk500", "--data", str(data_file),
                         "--method", method, "--json", "-o", str(out_file))
    assert code == 0, err
    rep = json.loads(out)
    k = np.array([j["stiffness_Nm_per_rad"] for j in rep["joints"]])
    # The CSV stores mm with 6 decimals and deg with 8: not bit-exact, but close.
    np.testing.assert_allclose(k[:5], k_true[:5], rtol=2e-3)
    assert [j["identified"] for j in rep["joints"]] == [True] * 5 + [False]
    assert rep["joints"][5]["std_error_Nm_per_rad"] is None
    assert "does not move the measured TCP" in rep["joints"][5]["note"]
    assert rep["condition_number"] > 1.0
    assert rep["rms_after_mm"] < rep["rms_before_mm"]
    new = load_robot_description(out_file)
    np.testing.assert_allclose(new.stiffness, k, rtol=1e-5)
    assert new.stiffness[5] == pytest.approx(load_model("zk500").stiffness[5], rel=1e-5)
    assert "identified by rfsw-plan identify" in new.sources["stiffness"]


def test_identify_text_table(capsys: pytest.CaptureFixture[str], data_file: Path) -> None:
    code, out, _ = run(capsys, "identify", "--robot", "zk500", "--data", str(data_file))
    assert code == 0
    lines = out.splitlines()
    assert any(ln.split()[:1] == ["6"] and "NOT identified" in ln for ln in lines)
    assert sum("identified" in ln and "NOT" not in ln for ln in lines) == 5
    assert "condition number" in out and "RMS position residual: before" in out


def _corrupt(src: Path, dst: Path, old: str, new: str, row: int | None = None) -> Path:
    lines = src.read_text().splitlines()
    if row is None:
        lines[0] = lines[0].replace(old, new)
    else:
        cells = lines[row - 1].split(",")
        header = lines[0].split(",")
        cells[header.index(old)] = new
        lines[row - 1] = ",".join(cells)
    dst.write_text("\n".join(lines) + "\n")
    return dst


def test_identify_bad_files(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                            data_file: Path) -> None:
    cases = [
        (_corrupt(data_file, tmp_path / "a.csv", "fz_N", "Fz"), ["column 'fz_N'", "missing"]),
        (_corrupt(data_file, tmp_path / "b.csv", "fy_N", "nan", row=7),
         ["row 7", "column 'fy_N'"]),
        (_corrupt(data_file, tmp_path / "c.csv", "q6_deg", "q7_deg"),
         ["file has 5 joints but the robot has 6"]),
        (tmp_path / "missing.csv", ["cannot read file"]),
    ]
    for path, needles in cases:
        assert_one_line_error(
            *run(capsys, "identify", "--robot", "zk500", "--data", str(path)), str(path), *needles
        )


def test_identify_too_few_samples_and_bad_method(capsys: pytest.CaptureFixture[str],
                                                 tmp_path: Path, data_file: Path) -> None:
    lines = data_file.read_text().splitlines()
    short = tmp_path / "short.csv"
    short.write_text("\n".join(lines[:2]) + "\n")
    assert_one_line_error(
        *run(capsys, "identify", "--robot", "zk500", "--data", str(short)),
        "cannot identify 6 parameters",
    )
    assert_one_line_error(
        *run(capsys, "identify", "--robot", "zk500", "--data", str(data_file), "--method", "gls"),
        "invalid choice", "gls",
    )
    assert_one_line_error(
        *run(capsys, "identify", "--robot", "nope", "--data", str(data_file)),
        "unknown robot 'nope'", "zk500",
    )


def test_identify_free_option(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    kuka = load_model("kuka_kr600_r2830")
    rng = np.random.default_rng(3)
    d = kuka.robot.description
    mid, half = (d.lower + d.upper) / 2, (d.upper - d.lower) / 2
    Q = rng.uniform(mid - 0.5 * half, mid + 0.5 * half, size=(30, 6))
    F = np.zeros((30, 6))
    F[:, :3] = rng.normal(size=(30, 3)) * 3000.0
    data_file = write_measurements(tmp_path / "kuka.csv",
                                   MeasurementSet(Q, F, kuka.predict_position(Q, F)))
    assert_one_line_error(
        *run(capsys, "identify", "--robot", "kuka_kr600_r2830", "--data", str(data_file),
             "--free", "joint_compliance,tilt"),
        "unknown effect in the model 'tilt'", "tilting_compliance:j1",
    )
    code, out, _ = run(capsys, "identify", "--robot", "kuka_kr600_r2830", "--data",
                       str(data_file), "--json")
    assert code == 0
    rep = json.loads(out)
    assert rep["effects"] == []  # only joint compliance is free by default
    assert all(j["stiffness_Nm_per_rad"] > 0 for j in rep["joints"])
