"""Issue 34, data half: readers as the data come (MATLAB files, ';' with decimal commas, several
markers per pose, a 6-D probe's Euler angles, temperature) and ``rfsw-plan calibrate`` on
campaigns whose truth is known (computed here with the robot's forward kinematics, not with
the identification code), plus the real FANUC set when ../shared/data is present."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from scipy.spatial.transform import Rotation

from rfsw_plan.cli.main import main
from rfsw_plan.exceptions import InputError
from rfsw_plan.io.measurements import read_measurements
from rfsw_plan.robot.kinematics import load_robot

ROOT = Path(__file__).resolve().parents[1]
FANUC = ROOT.parent / "shared" / "data" / "fanuc_r2000ic_165f" / "calibration_dataset.mat"
FANUC_COLUMNS = ROOT / "examples" / "fanuc_r2000ic_165f" / "columns.toml"

#: Three reflectors on the tool, tool frame [m] (about 60 mm apart, 200 mm out).
REFLECTORS = np.array([[0.06, 0.017, 0.202], [-0.016, -0.057, 0.206], [-0.042, 0.044, 0.205]])

MAT_MAP = """frame = "device"
[columns]
q1 = { name = "q", column = 1, unit = "rad" }
q2 = { name = "q", column = 2, unit = "rad" }
q3 = { name = "q", column = 3, unit = "rad" }
q4 = { name = "q", column = 4, unit = "rad" }
q5 = { name = "q", column = 5, unit = "rad" }
q6 = { name = "q", column = 6, unit = "rad" }
x = { name = "mA", column = 1, unit = "m" }
y = { name = "mA", column = 2, unit = "m" }
z = { name = "mA", column = 3, unit = "m" }
x2 = { name = "mB", column = 1, unit = "m" }
y2 = { name = "mB", column = 2, unit = "m" }
z2 = { name = "mB", column = 3, unit = "m" }
x3 = { name = "mC", column = 1, unit = "m" }
y3 = { name = "mC", column = 2, unit = "m" }
z3 = { name = "mC", column = 3, unit = "m" }
"""


def _rot(rv: list[float]) -> np.ndarray:
    return Rotation.from_rotvec(rv).as_matrix()


def campaign(seed: int, n_poses: int, repeats: int, R_dev: np.ndarray, t_dev: np.ndarray,
             dq: np.ndarray, noise_m: float) -> dict[str, np.ndarray]:
    """A laser-tracker campaign of the FANUC R-2000iC/165F whose joints read ``dq`` less than
    they are (zero offsets), three reflectors, the tracker at (R_dev, t_dev): arrays as the
    data set's MATLAB file has them (q rad, markers m, device frame)."""
    robot = load_robot("fanuc_r2000ic_165f")
    rng = np.random.default_rng(seed)
    lo, hi = np.radians([-60, -30, -40, -90, -60, -90]), np.radians([60, 40, 30, 90, 60, 90])
    q_true = np.repeat(rng.uniform(lo, hi, (n_poses, 6)), repeats, axis=0)
    T = robot.batch_fk_jacobian(q_true)[0]
    markers = T[:, None, :3, 3] + np.einsum("mab,kb->mka", T[:, :3, :3], REFLECTORS)
    markers = markers @ R_dev.T + t_dev + rng.normal(0.0, noise_m, markers.shape)
    return {"q": q_true - dq, "mA": markers[:, 0], "mB": markers[:, 1], "mC": markers[:, 2]}


def _mat(tmp_path: Path, name: str, arrays: dict[str, np.ndarray]) -> Path:
    path = tmp_path / name
    scipy.io.savemat(path, arrays)
    return path


def _map(tmp_path: Path, text: str = MAT_MAP) -> Path:
    path = tmp_path / "columns.toml"
    path.write_text(text)
    return path


# -- readers --------------------------------------------------------------------------------------
def test_mat_file_through_the_column_map_with_three_markers(tmp_path: Path) -> None:
    arrays = campaign(0, 4, 2, np.eye(3), np.zeros(3), np.zeros(6), 0.0)
    data = read_measurements(_mat(tmp_path, "c.mat", arrays), 6, columns=_map(tmp_path))
    assert data.dialect == "MATLAB file" and data.frame == "device"
    assert data.markers is not None and data.markers.shape == (8, 3, 3)
    np.testing.assert_array_equal(data.q, arrays["q"])
    np.testing.assert_array_equal(data.markers[:, 1], arrays["mB"])
    # The tracked point is the reflectors' centroid.
    centroid = (arrays["mA"] + arrays["mB"] + arrays["mC"]) / 3.0
    np.testing.assert_allclose(data.position, centroid, atol=1e-15)


@pytest.mark.parametrize(("change", "message"), [
    (("mC", None), "array 'mC' (columns.x3 of"),
    (("mB", np.zeros((8, 2))), "columns.z2.column: 3 but array 'mB' has 2 columns"),
    (("mA", np.zeros((7, 3))), "rows but array"),
    (("q", np.array([["a"] * 6] * 8)), "not a 2-D numeric array"),
])
def test_mat_file_refusals_name_the_array(tmp_path: Path, change: tuple[str, object],
                                          message: str) -> None:
    arrays: dict[str, object] = dict(campaign(0, 4, 2, np.eye(3), np.zeros(3), np.zeros(6), 0.0))
    key, value = change
    if value is None:
        del arrays[key]
    else:
        arrays[key] = value
    path = tmp_path / "bad.mat"
    scipy.io.savemat(path, arrays)
    with pytest.raises(InputError) as err:
        read_measurements(path, 6, columns=_map(tmp_path))
    assert message in str(err.value) and "\n" not in str(err.value)


def test_mat_file_needs_a_column_map(tmp_path: Path) -> None:
    path = _mat(tmp_path, "c.mat", campaign(0, 4, 2, np.eye(3), np.zeros(3), np.zeros(6), 0.0))
    with pytest.raises(InputError, match="a MATLAB file has no column names"):
        read_measurements(path, 6)
    bad = _map(tmp_path, MAT_MAP.replace('column = 1, unit = "rad" }', 'column = 0, unit = "rad" }',
                                         1))
    with pytest.raises(InputError, match=r"columns.q1.column: got 0"):
        read_measurements(path, 6, columns=bad)


UR_MAP = """frame = "device"
orientation = "euler_xyz"
[columns]
q1 = { name = "j1", unit = "rad" }
q2 = { name = "j2", unit = "rad" }
q3 = { name = "j3", unit = "rad" }
q4 = { name = "j4", unit = "rad" }
q5 = { name = "j5", unit = "rad" }
q6 = { name = "j6", unit = "rad" }
x = { name = "mx", unit = "mm" }
y = { name = "my", unit = "mm" }
z = { name = "mz", unit = "mm" }
rx = { name = "a", unit = "deg" }
ry = { name = "b", unit = "deg" }
rz = { name = "c", unit = "deg" }
temperature = { name = "T", unit = "C" }
"""


def _semicolon_csv(path: Path, rows: list[list[float]]) -> None:
    head = "stamp;j1;j2;j3;j4;j5;j6;T;mx;my;mz;a;b;c"
    lines = [head] + [";".join(f"{v:.6f}".replace(".", ",") for v in r) for r in rows]
    path.write_text("\n".join(lines) + "\n")


def test_semicolon_decimal_comma_euler_probe_and_temperature(tmp_path: Path) -> None:
    rows = [[20200714163904, 0.1, -1.5, 0.3, -1.2, 0.4, 0.5, 23.68, 2361.98, -1368.55, 119.4,
             -90.4, -59.9, -90.9],
            [20200714163924, -2.1, -2.0, -0.8, -0.2, 0.39, 0.0, 23.7, 1685.28, -1665.35, -415.8,
             30.0, 20.0, 10.0]]
    path = tmp_path / "series.csv"
    _semicolon_csv(path, rows)
    cols = tmp_path / "ur.toml"
    cols.write_text(UR_MAP)
    data = read_measurements(path, 6, columns=cols)
    assert data.dialect == "semicolon-separated, decimal comma"
    np.testing.assert_allclose(data.position[1], [1.68528, -1.66535, -0.4158])
    np.testing.assert_allclose(data.extra["temperature_C"], [23.68, 23.7])
    # Extrinsic x-y-z Euler angles: R = Rz(c) Ry(b) Rx(a), built here by hand.
    a, b, c = np.radians(rows[1][11:14])
    Rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    Ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    Rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    assert data.rotation is not None
    np.testing.assert_allclose(Rotation.from_rotvec(data.rotation[1]).as_matrix(), Rz @ Ry @ Rx,
                               atol=1e-12)


def test_temperature_in_kelvin_is_refused_with_its_row(tmp_path: Path) -> None:
    path = tmp_path / "series.csv"
    _semicolon_csv(path, [[1, 0.1, -1.5, 0.3, -1.2, 0.4, 0.5, 23.5, 2000, 100, 10, 0, 0, 0],
                          [2, 0.2, -1.5, 0.3, -1.2, 0.4, 0.5, 296.8, 2000, 100, 10, 0, 0, 0]])
    cols = tmp_path / "ur.toml"
    cols.write_text(UR_MAP)
    with pytest.raises(InputError) as err:
        read_measurements(path, 6, columns=cols)
    assert "row 3, column 'T'" in str(err.value) and "kelvin" in str(err.value)


def test_unknown_orientation_and_marker_gaps_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "series.csv"
    _semicolon_csv(path, [[1, 0.1, -1.5, 0.3, -1.2, 0.4, 0.5, 23.5, 2000, 100, 10, 0, 0, 0]])
    cols = tmp_path / "ur.toml"
    cols.write_text(UR_MAP.replace("euler_xyz", "euler_xzy"))
    with pytest.raises(InputError, match="orientation: got 'euler_xzy'"):
        read_measurements(path, 6, columns=cols)
    csv = tmp_path / "m.csv"
    csv.write_text("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm,x3_mm,y3_mm,z3_mm\n"
                   "0,0,0,0,0,0,1,2,3,4,5,6\n")
    with pytest.raises(InputError, match="marker 2 is missing"):
        read_measurements(csv, 6)


# -- calibrate ------------------------------------------------------------------------------------
R1, T1 = _rot([0.01, -0.02, 0.8]), np.array([1.2, -0.4, 0.3])
R2, T2 = _rot([-0.015, 0.005, -2.1]), np.array([-0.8, 2.1, -0.2])
#: The campaign's joint zero offsets [rad] (joint 1 is absorbed by the registration, and the
#: last joint by the marker positions: left at zero).
DQ = np.array([0.0, 1.5e-3, -1.0e-3, 0.8e-3, -1.2e-3, 0.0])
NOISE_M = 2e-5


def test_calibrate_two_tracker_set_ups_markers_and_repeats(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two files of one robot, each with the tracker elsewhere: calibrate registers each,
    finds the joint offsets, and its held-out error, repeatability and pose accuracy are what
    the noise gives; validate on a third set-up re-registers only its device frame."""
    a = _mat(tmp_path, "a.mat", campaign(1, 8, 3, R1, T1, DQ, NOISE_M))
    b = _mat(tmp_path, "b.mat", campaign(2, 8, 3, R2, T2, DQ, NOISE_M))
    R3, T3 = _rot([0.02, 0.01, 1.7]), np.array([0.3, 1.5, -0.6])
    c = _mat(tmp_path, "c.mat", campaign(3, 16, 1, R3, T3, DQ, NOISE_M))
    cols, fitted = _map(tmp_path), tmp_path / "FITTED.toml"
    assert main(["calibrate", "--robot", "fanuc_r2000ic_165f", "--data", str(a), "--data",
                 str(b), "--columns", str(cols), "--frame", "device", "--max-effects", "0",
                 "--geometry", "kinematic_offsets", "--score", str(c),
                 "--save-robot", str(fitted), "-o", str(tmp_path / "out"), "--json"]) == 0
    j = json.loads(capsys.readouterr().out)
    # the file is what --json prints, without the wall time (the same input, the same bytes)
    assert {k: v for k, v in j.items() if k != "seconds"} == \
        json.loads((tmp_path / "out" / "calibrate.json").read_text())
    assert j["seconds"] > 0
    assert j["markers_per_pose"] == 3 and j["heldout_scheme"] == "leave-one-pose-group-out"
    assert j["heldout_pose_groups"] == 16 and j["effects"] == ["kinematic_offsets"]
    # Nominal model: the offsets show (mm); calibrated, held out: the noise (3-D: sqrt(3) s).
    floor = math.sqrt(3) * NOISE_M * 1e3
    assert j["registration_only_rms_mm"] > 10 * floor
    assert j["heldout_rms_mm"] < 2.0 * floor
    # Repeats: ISO 9283 RP = mean + 3 std of the distances to the barycentre (3 repeats each).
    assert 0.5 * floor < j["repeatability_mm"] < 6 * floor
    assert j["iso9283"]["repeat_rms_3d_mm"] == pytest.approx(floor * math.sqrt(2 / 3), rel=0.3)
    assert j["iso9283"]["AP_max_mm"] < 4 * floor
    # Each file's own registration: the base origin where it was put.
    for f, t in zip(j["files"], (T1, T2), strict=True):
        assert np.allclose(np.array(f["device_frame"]["base_in_device_xyz_mm"]) / 1e3, t,
                           atol=2e-4)
    offsets = {p["name"]: p["value"] for p in j["parameters"]
               if p["effect"] == "kinematic_offsets"}
    for k in (2, 3, 4):
        assert offsets[f"dq{k + 1}"] == pytest.approx(DQ[k] * 1e3, abs=0.1), k
    # Another set-up: only its device frame is registered again (calibrate --score says
    # what validate says).
    assert main(["validate", "--robot", str(fitted), "--data", str(c), "--columns", str(cols),
                 "--frame", "device", "--json", "--no-report"]) == 0
    v = json.loads(capsys.readouterr().out)
    assert v["device_frame"]["registration"] == "fitted" and v["device_frame"]["marker"] == "held"
    assert v["rms_3d_mm"] < 2.5 * floor
    assert j["scores"][0]["rms_3d_mm"] == pytest.approx(v["rms_3d_mm"], rel=1e-6)


def test_calibrate_refuses_a_file_given_twice(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    a = _mat(tmp_path, "a.mat", campaign(1, 5, 1, R1, T1, DQ, NOISE_M))
    assert main(["calibrate", "--robot", "fanuc_r2000ic_165f", "--data", str(a), "--data",
                 str(a), "--columns", str(_map(tmp_path))]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "a file given twice" in err


#: Issue 40's target for the FANUC set, held out (it was 0.381 mm when the fit used the
#: reflectors' centroid only and left the tool's rotation free).
FANUC_TARGET_MM = 0.35


def _fanuc(capsys: pytest.CaptureFixture[str], *extra: str) -> dict[str, object]:
    assert main(["calibrate", "--robot", "fanuc_r2000ic_165f", "--data", str(FANUC),
                 "--columns", str(FANUC_COLUMNS), "--frame", "device", "--json",
                 *extra]) == 0
    j: dict[str, object] = json.loads(capsys.readouterr().out)
    assert j["heldout_scheme"] == "leave-one-pose-group-out" and j["heldout_pose_groups"] == 24
    assert j["markers_per_pose"] == 3
    return j


@pytest.mark.skipif(not FANUC.is_file(), reason="shared/data/fanuc_r2000ic_165f absent")
def test_fanuc_leave_one_pose_out_beats_the_published_in_sample_figure(
        capsys: pytest.CaptureFixture[str]) -> None:
    """The FANUC R-2000iC/165F set: 0.53 mm is upstream's in-sample RMS after geometric
    calibration; ours is held out (each pose group left out of the whole fit). The geometry
    alone (a few seconds: the default run), fitted on every reflector so that the tool's
    rotation is fitted too, is within issue 40's 0.35 mm."""
    j = _fanuc(capsys, "--max-effects", "0")
    assert j["effects"] == ["kinematic_offsets", "link_errors"]
    assert isinstance(j["heldout_rms_mm"], float) and j["heldout_rms_mm"] <= FANUC_TARGET_MM
    assert j["repeatability_mm"] is not None
    iso = j["iso9283"]
    assert isinstance(iso, dict) and iso["repeated_groups"] == 24


@pytest.mark.slow
@pytest.mark.skipif(not FANUC.is_file(), reason="shared/data/fanuc_r2000ic_165f absent")
def test_fanuc_default_selection_through_forward_select(
        capsys: pytest.CaptureFixture[str]) -> None:
    """The documented command (the workbench's forward selection after the geometry, about
    16 s of CPU): still within 0.35 mm held out, and the geometry comes first."""
    j = _fanuc(capsys)
    effects = j["effects"]
    assert isinstance(effects, list) and effects[:2] == ["kinematic_offsets", "link_errors"]
    assert isinstance(j["heldout_rms_mm"], float) and j["heldout_rms_mm"] <= FANUC_TARGET_MM


# -- bundled robots against their public sources ------------------------------------------
def _rz(t: float) -> np.ndarray:
    T = np.eye(4)
    T[:2, :2] = [[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]]
    return T


def _rx(t: float) -> np.ndarray:
    T = np.eye(4)
    T[1:3, 1:3] = [[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]]
    return T


def _tr(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


def _axis(axis: tuple[float, float, float], t: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.array(axis, dtype=float) * t).as_matrix()
    return T


def test_ur10_is_urs_standard_dh() -> None:
    """UR's published standard DH of the UR10 (d1 127.3, a2 -612, a3 -572.3, d4 163.941,
    d5 115.7, d6 92.2 mm; alpha 90, 0, 0, 90, -90, 0 deg), chained here by hand."""
    d = [0.1273, 0, 0, 0.163941, 0.1157, 0.0922]
    a = [0, -0.612, -0.5723, 0, 0, 0]
    alpha = [math.pi / 2, 0, 0, math.pi / 2, -math.pi / 2, 0]
    robot = load_robot("ur10")
    for q in np.random.default_rng(4).uniform(-3, 3, (5, 6)):
        T = np.eye(4)
        for i in range(6):
            T = T @ _rz(q[i]) @ _tr(0, 0, d[i]) @ _tr(a[i], 0, 0) @ _rx(alpha[i])
        np.testing.assert_allclose(robot.fk(q), T, atol=1e-12)


def test_fanuc_r2000ic_165f_is_the_ros_industrial_urdf() -> None:
    """The joint origins and axes of ROS-Industrial's r2000ic165f_macro.xacro, chained here
    by hand, from base_link to tool0 (the faceplate: same origin, z out of the flange)."""
    origins = [(0, 0, 0.670), (0.312, 0, 0), (0, 0, 1.075), (0, 0, 0.225), (1.280, 0, 0),
               (0.215, 0, 0)]
    axes = [(0, 0, 1), (0, 1, 0), (0, -1, 0), (-1, 0, 0), (0, -1, 0), (-1, 0, 0)]
    tool0 = np.eye(4)
    tool0[:3, :3] = Rotation.from_euler("xyz", [math.pi, -math.pi / 2, 0]).as_matrix()
    robot = load_robot("fanuc_r2000ic_165f")
    for q in np.random.default_rng(5).uniform(-1.5, 1.5, (5, 6)):
        T = np.eye(4)
        for o, ax, qi in zip(origins, axes, q, strict=True):
            T = T @ _tr(*o) @ _axis(ax, qi)
        np.testing.assert_allclose(robot.fk(q)[:3, 3], (T @ tool0)[:3, 3], atol=1e-12)
        np.testing.assert_allclose(robot.fk(q)[:3, 2], (T @ tool0)[:3, 2], atol=1e-12)


def test_pose_groups_and_iso9283_by_hand() -> None:
    from rfsw_plan.validation.calibrate import iso9283, pose_groups

    q = np.array([[0.1, 0.2], [0.3, 0.4], [0.1, 0.2], [0.3, 0.4 + 1e-9], [0.1, 0.2]])
    np.testing.assert_array_equal(pose_groups(q), [0, 1, 0, 1, 0])
    # Group 0: three repeats at distances 1, 1, 1 (mm) from their barycentre; group 1: two.
    measured = np.zeros((5, 1, 3))
    measured[[0, 2, 4], 0] = [[1e-3, 0, 0], [-0.5e-3, 0.866e-3, 0], [-0.5e-3, -0.866e-3, 0]]
    measured[[1, 3], 0] = [[0, 0, 2e-3], [0, 0, -2e-3]]
    err = np.zeros((5, 1, 3))
    err[[1, 3], 0, 0] = 3e-3  # group 1's barycentre 3 mm off the prediction
    iso = iso9283(measured, err, pose_groups(q))
    # RP needs 3 repeats: group 0 only, l = 1 mm each, S_l = 0: RP = 1 mm.
    assert iso.rp_max == pytest.approx(1e-3, rel=1e-3) and iso.rp_mean == iso.rp_max
    assert iso.ap_max == pytest.approx(3e-3) and iso.ap_mean == pytest.approx(1.5e-3)
    assert iso.groups == 2 and iso.repeated_groups == 2
    # Deviations from the barycentres: five of 1, 1, 1, 2, 2 mm.
    assert iso.repeat_rms_3d == pytest.approx(math.sqrt((3 * 1 + 2 * 4) / 5) * 1e-3, rel=1e-3)


def test_marker_rows_are_the_kinematics_of_each_marker() -> None:
    """Every marker as a sample of its own (what calibrate fits, the same quantity its held-out
    figure scores): the expanded pose, Jacobian and measured position of marker k are those of
    the robot whose tool point is the marker (Pinocchio's FK with the tool moved to it), the
    logged moment is taken about the marker, and the markers of a pose stay in its group."""
    from dataclasses import replace

    from rfsw_plan.elastostatics.measurement_set import MeasurementSet
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.elastostatics.registration import with_tool_point
    from rfsw_plan.validation.calibrate import marker_layout, marker_rows, pose_groups

    robot = load_robot("fanuc_r2000ic_165f")
    centre = REFLECTORS.mean(axis=0)
    model = ElastostaticModel(with_tool_point(robot, centre))  # tracked point: the centroid
    rng = np.random.default_rng(4)
    q = np.repeat(rng.uniform(-0.8, 0.8, (5, 6)), 2, axis=0)
    T = robot.batch_fk_jacobian(q)[0]
    markers = T[:, None, :3, 3] + np.einsum("mab,kb->mka", T[:, :3, :3], REFLECTORS)
    data = MeasurementSet(q=q, wrench=np.zeros((len(q), 6)), position=markers.mean(axis=1),
                          markers=markers)
    assert np.allclose(marker_layout(model, data), REFLECTORS - centre, atol=1e-12)
    rows, batch = marker_rows(model, data, model.batch_of(data))
    assert len(rows) == 3 * len(q) and rows.markers is None
    Tc = model.batch_of(data).T
    force = rng.normal(0.0, 100.0, (len(q), 3))
    loaded, lb = marker_rows(model, replace(data, wrench=np.column_stack(
        [force, np.zeros((len(q), 3))])), model.batch_of(data))
    for k in range(3):
        sl = slice(k * len(q), (k + 1) * len(q))
        Tk, Jk = with_tool_point(robot, REFLECTORS[k]).batch_fk_jacobian(q)
        assert np.allclose(rows.position[sl], markers[:, k], atol=1e-12)
        assert np.allclose(batch.T[sl], Tk, atol=1e-12)
        assert np.allclose(batch.J[sl], Jk, atol=1e-9)
        # The moment about the marker: M_k = M + r_k x F, r_k from the tracked point.
        arm = lb.T[sl][:, :3, 3] - Tc[:, :3, 3]
        assert np.allclose(loaded.wrench[sl, 3:], np.cross(arm, force), atol=1e-9)
    assert np.array_equal(pose_groups(rows.q), np.tile(pose_groups(q), 3))
    same, _ = marker_rows(model, replace(data, markers=None), model.batch_of(data))
    assert len(same) == len(q)
