"""Measurement and force-log readers on lab files (issue 12 §1, §3, §6; issue 9 §4)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rfsw_plan.cli.main import main
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import load_model
from rfsw_plan.exceptions import InputError
from rfsw_plan.io.force_series import read_force_series
from rfsw_plan.io.measurements import read_measurements, write_measurements

Q = [0.0, 10.0, -10.0, 0.0, 80.0, 0.0]


def _campaign(n: int = 12, seed: int = 0) -> MeasurementSet:
    model = load_model("zk500")
    rng = np.random.default_rng(seed)
    q = np.radians(Q) + rng.normal(scale=0.3, size=(n, 6))
    w = np.zeros((n, 6))
    w[:, :3] = rng.normal(size=(n, 3)) * 3000.0
    return MeasurementSet(q, w, model.predict_position(q, w), pose_id=np.array(
        [f"P{i}" for i in range(n)]))


@pytest.fixture()
def good_csv(tmp_path: Path) -> Path:
    return write_measurements(tmp_path / "good.csv", _campaign())


def _one_line(code: int, err: str, *needles: str) -> None:
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in lines[0], lines[0]


def test_semicolon_decimal_comma_and_tab_read_the_same(good_csv: Path, tmp_path: Path) -> None:
    ref = read_measurements(good_csv, 6)
    assert ref.dialect == "comma-separated, decimal point"
    text = good_csv.read_text()
    german = tmp_path / "de.csv"
    german.write_text(text.replace(",", ";").replace(".", ","))
    tab = tmp_path / "tab.csv"
    tab.write_text(text.replace(",", "\t"))
    for path, dialect in ((german, "semicolon-separated, decimal comma"),
                          (tab, "tab-separated, decimal point")):
        d = read_measurements(path, 6)
        assert d.dialect == dialect
        np.testing.assert_allclose(d.q, ref.q)
        np.testing.assert_allclose(d.position, ref.position)


def test_duplicated_column_is_rejected(good_csv: Path, tmp_path: Path) -> None:
    lines = good_csv.read_text().splitlines()
    p = tmp_path / "dup.csv"
    p.write_text("\n".join([lines[0].replace("y_mm", "x_mm"), *lines[1:]]) + "\n")
    with pytest.raises(InputError, match="column 'x_mm' appears twice"):
        read_measurements(p, 6)
    f = tmp_path / "forces.csv"
    f.write_text("t_s,fx_N,fy_N,fz_N,fz_N\n0,1,2,3,4\n1,1,2,3,4\n")
    with pytest.raises(InputError, match="appears twice"):
        read_force_series(f, frame="base")


def test_rename_hint_only_for_the_same_quantity(good_csv: Path, tmp_path: Path) -> None:
    lines = good_csv.read_text().splitlines()
    cols = lines[0].split(",")
    i = cols.index("fz_N")
    dropped = [",".join(c for k, c in enumerate(ln.split(",")) if k != i) for ln in lines]
    p = tmp_path / "nofz.csv"
    p.write_text("\n".join(dropped) + "\n")
    with pytest.raises(InputError) as exc:
        read_measurements(p, 6)
    assert "column 'fz_N': missing" in str(exc.value) and "rename it" not in str(exc.value)
    p.write_text("\n".join([lines[0].replace("fz_N", "fz_kN"), *lines[1:]]) + "\n")
    d = read_measurements(p, 6)  # another unit of the same quantity is read, in SI
    np.testing.assert_allclose(d.wrench[:, 2], read_measurements(good_csv, 6).wrench[:, 2] * 1e3)
    p.write_text("\n".join([lines[0].replace("fz_N", "Fz"), *lines[1:]]) + "\n")
    with pytest.raises(InputError, match="found 'Fz': rename it to 'fz_N'"):
        read_measurements(p, 6)
    f = tmp_path / "forces.csv"
    f.write_text("t_s,fx_N,fy_N\n0,1,2\n1,1,2\n")
    with pytest.raises(InputError) as exc2:
        read_force_series(f, frame="base")
    assert "rename it" not in str(exc2.value) and "did you mean" not in str(exc2.value)


@pytest.mark.parametrize("cell", ["1e300", "-1e300", "x" * 200_000])
def test_huge_cells_give_one_line_and_no_robot_file(
    good_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], cell: str
) -> None:
    lines = good_csv.read_text().splitlines()
    cols = lines[1].split(",")
    cols[lines[0].split(",").index("fx_N")] = cell
    p = tmp_path / "huge.csv"
    p.write_text("\n".join([lines[0], ",".join(cols), *lines[2:]]) + "\n")
    out = tmp_path / "robot.toml"
    code = main(["identify", "--robot", "zk500", "--data", str(p), "--json", "-o", str(out)])
    captured = capsys.readouterr()
    _one_line(code, captured.err, "huge.csv", "row 2")
    assert captured.out == "" and not out.exists()


def test_orientation_columns(good_csv: Path, tmp_path: Path) -> None:
    d = _campaign()
    rv = np.random.default_rng(1).normal(scale=0.01, size=(len(d), 3))
    full = write_measurements(tmp_path / "o.csv", MeasurementSet(
        d.q, d.wrench, d.position, pose_id=d.pose_id, rotation=rv))
    back = read_measurements(full, 6)
    assert back.rotation is not None
    np.testing.assert_allclose(back.rotation, rv, atol=1e-9)
    lines = full.read_text().splitlines()
    partial = tmp_path / "partial.csv"
    partial.write_text("\n".join([lines[0].replace("rz_mrad", "temp_C"), *lines[1:]]) + "\n")
    with pytest.raises(InputError, match=r"rz_mrad.*missing.*rotation vector needs all"):
        read_measurements(partial, 6)
    # A quaternion gives the same rotation vectors.
    ang = np.linalg.norm(rv, axis=1)
    quat = np.column_stack([np.cos(ang / 2), rv / ang[:, None] * np.sin(ang / 2)[:, None]])
    header = lines[0].split(",")
    k = header.index("rx_mrad")
    rows = [ln.split(",") for ln in lines[1:]]
    header[k:k + 3] = ["quat_w", "quat_x", "quat_y", "quat_z"]
    for r, row in enumerate(rows):
        row[k:k + 3] = [f"{v:.15f}" for v in quat[r]]
    qfile = tmp_path / "quat.csv"
    qfile.write_text("\n".join(",".join(x) for x in [header, *rows]) + "\n")
    np.testing.assert_allclose(read_measurements(qfile, 6).rotation, rv, atol=1e-9)


def test_wrench_frames(good_csv: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    model = load_model("zk500")
    d = read_measurements(good_csv, 6)
    R = model.robot.batch_fk_jacobian(d.q)[0][:, :3, :3]
    tool = d.wrench.copy()
    tool[:, :3] = np.einsum("mba,mb->ma", R, d.wrench[:, :3])  # R^T f
    p = write_measurements(tmp_path / "tool.csv", MeasurementSet(d.q, tool, d.position,
                                                                 pose_id=d.pose_id))
    back = read_measurements(p, 6, wrench_frame="tool",
                             tool_rotation=lambda q: model.robot.batch_fk_jacobian(q)[0][:, :3, :3])
    np.testing.assert_allclose(back.wrench, d.wrench, atol=1e-5)
    # A sensor 100 mm behind the TCP, turned 90 deg about z: f_s = Rs^T f_t, m_s = -(p x f).
    Rs = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    ps = np.array([0.0, 0.0, -0.1])
    f_t = tool[:, :3]
    sens = np.zeros_like(tool)
    sens[:, :3] = f_t @ Rs
    sens[:, 3:] = -np.cross(ps, f_t) @ Rs
    s = write_measurements(tmp_path / "sensor.csv", MeasurementSet(d.q, sens, d.position,
                                                                   pose_id=d.pose_id))
    base = ["identify", "--robot", "zk500", "--data", str(s), "--json"]
    assert main([*base, "--wrench-frame", "sensor", "--sensor-pose", "0,0,-100,0,0,90"]) == 0
    capsys.readouterr()
    _one_line(main([*base, "--wrench-frame", "sensor"]), capsys.readouterr().err,
              "sensor frame without a sensor pose")
    _one_line(main([*base, "--sensor-pose", "0,0,-100,0,0,90"]), capsys.readouterr().err,
              "--sensor-pose")


def test_column_mapping(tmp_path: Path) -> None:
    d = _campaign()
    csv_path = tmp_path / "lab.csv"
    rows = ["J1;J2;J3;J4;J5;J6;FX;FY;FZ;X;Y;Z"]
    for i in range(len(d)):
        vals = [*d.q[i], *(d.wrench[i, :3] / 1e3), *d.position[i]]  # rad, kN, m
        rows.append(";".join(f"{v:.12g}".replace(".", ",") for v in vals))
    csv_path.write_text("\n".join(rows) + "\n")
    mapping = tmp_path / "cols.toml"
    entries = [f'q{j} = {{ name = "J{j}", unit = "rad" }}' for j in range(1, 7)]
    entries += [f'f{a} = {{ name = "F{a.upper()}", unit = "kN" }}' for a in "xyz"]
    entries += [f'{a} = {{ name = "{a.upper()}", unit = "m" }}' for a in "xyz"]
    mapping.write_text("[columns]\n" + "\n".join(entries) + "\n")
    back = read_measurements(csv_path, 6, columns=mapping)
    np.testing.assert_allclose(back.q, d.q, rtol=1e-10)
    np.testing.assert_allclose(back.wrench, d.wrench, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(back.position, d.position, rtol=1e-10)
    mapping.write_text("[columns]\nq1 = { name = 'J1', unit = 'furlong' }\n")
    with pytest.raises(InputError, match="unit 'furlong'"):
        read_measurements(csv_path, 6, columns=mapping)
    mapping.write_text("colums = 1\n[columns]\nq1 = { name = 'J1', unit = 'rad' }\n")
    with pytest.raises(InputError, match="colums: unknown key"):
        read_measurements(csv_path, 6, columns=mapping)


@pytest.mark.parametrize(("change", "needle"), [
    ("metres", "positions look like metres: median |x|"),
    ("radians", "q values look like radians"),
    ("kN", "force units"),
    ("robot", "wrong robot or frame, try --frame device"),
])
def test_sanity_before_fitting(tmp_path: Path, capsys: pytest.CaptureFixture[str], change: str,
                               needle: str) -> None:
    d = _campaign(20)
    robot = "zk500"
    if change == "metres":
        d = MeasurementSet(d.q, d.wrench, d.position / 1000.0, pose_id=d.pose_id)
    elif change == "radians":
        d = MeasurementSet(np.radians(d.q), d.wrench, d.position, pose_id=d.pose_id)
    elif change == "kN":
        d = MeasurementSet(d.q, d.wrench / 1000.0, d.position, pose_id=d.pose_id)
    else:
        robot = "fanuc_s900ib_400"
    p = write_measurements(tmp_path / "bad.csv", d)
    out = tmp_path / "r.toml"
    for cmd in (["identify", "-o", str(out)], ["validate", "--no-report", "--save-robot",
                                               str(out)]):
        code = main([cmd[0], "--robot", robot, "--data", str(p), *cmd[1:]])
        _one_line(code, capsys.readouterr().err, needle)
        assert not out.exists()


# --------------------------------------------------------------------------------------------
# Mutation fuzzer: every mutated file ends in exit 0, 2 or 3 with no traceback.

_MUTATIONS = st.sampled_from(["drop_col", "dup_col", "rename", "cell", "blank", "huge",
                              "truncate", "delim", "bom", "swap"])
_CELLS = st.sampled_from(["nan", "inf", "-inf", "1e300", "", "x", "1,5", "0x10", "1e-320",
                          "  3  ", "\x00", "é", "1;2", '"', "9" * 400])


def _mutate(text: str, kind: str, cell: str, k: int) -> str:
    lines = text.splitlines()
    head = lines[0].split(",")
    rows = [ln.split(",") for ln in lines[1:]]
    c = k % len(head)
    r = k % max(len(rows), 1)
    if kind == "drop_col":
        head.pop(c)
        for row in rows:
            row.pop(c)
    elif kind == "dup_col":
        head.append(head[c])
        for row in rows:
            row.append(row[c])
    elif kind == "rename":
        head[c] = head[c][:-1] + "Z"
    elif kind in ("cell", "blank", "huge"):
        rows[r][c] = {"cell": cell, "blank": "", "huge": "1e300"}[kind]
    elif kind == "truncate":
        return "\n".join(lines[: 1 + r])[: max(1, len(text) // (k % 7 + 2))]
    elif kind == "delim":
        return text.replace(",", ";", k % 5 + 1)
    elif kind == "bom":
        return "\ufeff" + text
    elif kind == "swap":
        head[c], head[(c + 1) % len(head)] = head[(c + 1) % len(head)], head[c]
    return "\n".join(",".join(x) for x in [head, *rows]) + "\n"


def _fuzz(tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str, cell: str, k: int,
          base_text: str, force_text: str) -> None:
    p = tmp_path / "m.csv"
    p.write_text(_mutate(base_text, kind, cell, k), encoding="utf-8")
    out = tmp_path / "r.toml"
    code = main(["identify", "--robot", "zk500", "--data", str(p), "--json", "-o", str(out)])
    err = capsys.readouterr().err
    assert code in (0, 2, 3) and "Traceback" not in err, err
    if code != 0:
        assert len(err.strip().splitlines()) == 1 and not out.exists(), err
    out.unlink(missing_ok=True)
    f = tmp_path / "f.csv"
    f.write_text(_mutate(force_text, kind, cell, k), encoding="utf-8")
    try:
        series = read_force_series(f, frame="base")
        assert np.all(np.isfinite(series.force)) and np.all(np.diff(series.t) > 0)
    except InputError as exc:
        assert "\n" not in str(exc)


FORCE_TEXT = "t_s,fx_N,fy_N,fz_N,mx_Nm,my_Nm,mz_Nm\n" + "".join(
    f"{0.1 * i:.1f},{10 + i},{-20 - i},{3000 + i},1,2,3\n" for i in range(8))


def _run_fuzz(tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str],
              examples: int) -> None:
    base_dir = tmp_path_factory.mktemp("fuzz")
    base_text = write_measurements(base_dir / "base.csv", _campaign(10)).read_text()

    @settings(max_examples=examples, deadline=None, derandomize=True,
              suppress_health_check=list(HealthCheck))
    @given(kind=_MUTATIONS, cell=_CELLS, k=st.integers(0, 10_000))
    def case(kind: str, cell: str, k: int) -> None:
        _fuzz(base_dir, capsys, kind, cell, k, base_text, FORCE_TEXT)

    case()


def test_reader_fuzz_bounded(tmp_path_factory: pytest.TempPathFactory,
                             capsys: pytest.CaptureFixture[str]) -> None:
    _run_fuzz(tmp_path_factory, capsys, 25)


@pytest.mark.slow
def test_reader_fuzz_long(tmp_path_factory: pytest.TempPathFactory,
                          capsys: pytest.CaptureFixture[str]) -> None:
    _run_fuzz(tmp_path_factory, capsys, 400)


@pytest.mark.parametrize("value", ["1e300", "-1e300", "1e400", "inf", "nan"])
def test_huge_and_non_finite_values_are_refused_by_the_readers(tmp_path: Path,
                                                               value: str) -> None:
    """The readers, not float(), refuse a value float() takes (1e300 is finite, 1e400 is
    inf): one line naming the file, the row (the header is row 1) and the column."""
    lines = write_measurements(tmp_path / "m.csv", _campaign()).read_text().splitlines()
    cells = lines[3].split(",")
    cells[lines[0].split(",").index("fx_N")] = value
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([*lines[:3], ",".join(cells), *lines[4:]]) + "\n")
    with pytest.raises(InputError) as exc:
        read_measurements(bad, 6)
    msg = str(exc.value)
    assert "\n" not in msg and str(bad) in msg and "row 4, column 'fx_N'" in msg, msg
    force = FORCE_TEXT.splitlines()
    cells = force[3].split(",")
    cells[3] = value  # fz_N
    f = tmp_path / "f.csv"
    f.write_text("\n".join([*force[:3], ",".join(cells), *force[4:]]) + "\n")
    with pytest.raises(InputError) as exc:
        read_force_series(f, frame="base")
    msg = str(exc.value)
    assert "\n" not in msg and str(f) in msg and "row 4, column 'fz_N'" in msg, msg


def test_orientation_makes_joint_6_identifiable(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """Seed 000's 6-D measurements: with the tool orientation, joint 6's stiffness (whose axis
    passes through the TCP) is identified; from positions alone it is not."""
    from scipy.spatial.transform import Rotation

    model = load_model("zk500")
    d = _campaign(40, seed=3)
    w = d.wrench.copy()
    w[:, 3:] = np.random.default_rng(5).normal(scale=300.0, size=(len(d), 3))  # loads joint 6
    d = MeasurementSet(d.q, w, model.predict_position(d.q, w), pose_id=d.pose_id)
    batch = model.batch(d.q)
    dX = model.deflection_batch(batch, d.wrench)
    R = Rotation.from_rotvec(dX[:, 3:]).as_matrix() @ batch.T[:, :3, :3]
    rv = Rotation.from_matrix(R).as_rotvec()
    p = write_measurements(tmp_path / "six.csv", MeasurementSet(
        d.q, d.wrench, d.position, pose_id=d.pose_id, rotation=rv))
    pos_only = write_measurements(tmp_path / "three.csv", d)
    for path, ident in ((pos_only, False), (p, True)):
        assert main(["identify", "--robot", "zk500", "--data", str(path), "--json"]) == 0
        rep = json.loads(capsys.readouterr().out)
        j6 = rep["joints"][5]
        assert j6["identified"] is ident, j6
        if ident:
            k6 = load_model("zk500").stiffness[5]
            assert j6["stiffness_Nm_per_rad"] == pytest.approx(k6, rel=1e-3)
