"""Measurement CSV files: round trip and every bad-input case of issue 2 §9."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.exceptions import InputError
from rfsw_plan.io.measurements import MeasurementSet, read_measurements, write_measurements

HEADER = "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,fx_N,fy_N,fz_N,x_mm,y_mm,z_mm"
ROW = "10,20,30,40,50,60,100,-200,4800,250.5,-2000.25,660.125"


def write(tmp_path: Path, text: str, name: str = "m.csv") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def sample_set(m: int = 5) -> MeasurementSet:
    rng = np.random.default_rng(0)
    pos = rng.normal(size=(m, 3))
    pos[1, 2] = np.nan
    pos[3, 0] = np.nan
    return MeasurementSet(
        q=rng.uniform(-2, 2, (m, 6)),
        wrench=rng.normal(size=(m, 6)) * 1000.0,
        position=pos,
        t=np.arange(m) * 0.1,
        pose_id=np.array([f"P{i}" for i in range(m)]),
        sigma=np.full(m, 2e-5),
        extra={"temp_C": np.linspace(20, 25, m)},
    )


def test_round_trip(tmp_path: Path) -> None:
    data = sample_set()
    p = write_measurements(tmp_path / "sub" / "out.csv", data)
    back = read_measurements(p, n_joints=6)
    np.testing.assert_allclose(back.q, data.q, atol=1e-9)
    np.testing.assert_allclose(back.wrench, data.wrench, atol=1e-6)
    np.testing.assert_array_equal(np.isnan(back.position), np.isnan(data.position))
    np.testing.assert_allclose(back.position, data.position, atol=1e-9, equal_nan=True)
    assert back.t is not None and back.pose_id is not None and back.sigma is not None
    np.testing.assert_allclose(back.t, data.t)  # type: ignore[arg-type]
    assert list(back.pose_id) == list(data.pose_id)  # type: ignore[arg-type]
    np.testing.assert_allclose(back.sigma, data.sigma)  # type: ignore[arg-type]
    np.testing.assert_allclose(back.extra["temp_C"], data.extra["temp_C"])
    assert back.source == str(p)


def test_minimal_file_units_and_defaults(tmp_path: Path) -> None:
    d = read_measurements(write(tmp_path, f"{HEADER}\n{ROW}\n"), n_joints=6)
    np.testing.assert_allclose(np.degrees(d.q[0]), [10, 20, 30, 40, 50, 60])
    np.testing.assert_allclose(d.wrench[0], [100, -200, 4800, 0, 0, 0])  # moments default 0
    np.testing.assert_allclose(d.position[0], [0.2505, -2.00025, 0.660125])
    assert d.t is None and d.pose_id is None and d.sigma is None


def test_radians_blank_axes_and_ignored_columns(tmp_path: Path) -> None:
    text = (
        "note,q1_rad,q2_rad,q3_rad,q4_rad,q5_rad,q6_rad,fx_N,fy_N,fz_N,mx_Nm,my_Nm,mz_Nm,"
        "x_mm,z_mm\n"
        "first,0.1,0.2,0.3,0.4,0.5,0.6,1,2,3,4,5,6,100,\n"
    )
    d = read_measurements(write(tmp_path, text), n_joints=6)
    np.testing.assert_allclose(d.q[0], [0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    np.testing.assert_allclose(d.wrench[0], [1, 2, 3, 4, 5, 6])
    assert d.position[0, 0] == pytest.approx(0.1)
    assert np.isnan(d.position[0, 1]) and np.isnan(d.position[0, 2])
    assert "note" not in d.extra  # text columns are ignored


@pytest.mark.parametrize(
    ("header", "pattern"),
    [
        (HEADER.replace("fz_N", "fz_n"), r"column 'fz_N'.*missing.*fz_n"),  # misnamed
        (HEADER.replace("fz_N", "fz"), r"column .fz_N.: missing; found .fz.: rename it"),
        (HEADER.replace(",fy_N", ""), r"column 'fy_N'.*missing"),  # missing
        (HEADER.replace("q1_deg", "q1"), r"column 'q1_deg'.*missing"),
        ("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,fx_N,fy_N,fz_N", r"x_mm, y_mm, z_mm"),
    ],
)
def test_missing_or_misnamed_column_is_named(tmp_path: Path, header: str, pattern: str) -> None:
    n_cols = header.count(",") + 1
    row = ",".join(ROW.split(",")[:n_cols])
    p = write(tmp_path, f"{header}\n{row}\n")
    with pytest.raises(InputError, match=pattern) as exc:
        read_measurements(p, n_joints=6)
    assert str(p) in str(exc.value) and "\n" not in str(exc.value)


@pytest.mark.parametrize("bad", ["nan", "NaN", "inf", "abc", ""])
def test_nan_or_bad_number_gives_the_row(tmp_path: Path, bad: str) -> None:
    cells = ROW.split(",")
    cells[7] = bad  # fy_N of the second data row
    p = write(tmp_path, f"{HEADER}\n{ROW}\n{','.join(cells)}\n")
    with pytest.raises(InputError, match=r"row 3, column 'fy_N'"):
        read_measurements(p, n_joints=6)


def test_nan_position_is_an_error_but_blank_is_unmeasured(tmp_path: Path) -> None:
    cells = ROW.split(",")
    cells[10] = "nan"
    with pytest.raises(InputError, match=r"row 2, column 'y_mm'"):
        read_measurements(write(tmp_path, f"{HEADER}\n{','.join(cells)}\n"), n_joints=6)
    cells[10] = ""
    d = read_measurements(write(tmp_path, f"{HEADER}\n{','.join(cells)}\n"), n_joints=6)
    assert np.isnan(d.position[0, 1])


def test_a_device_frame_row_with_a_blank_axis_is_refused(tmp_path: Path) -> None:
    """In the base frame a blank axis is simply not measured; in the device frame a position
    becomes a base position as a whole, so a partial row was silently lost (all NaN): now one
    line naming the row and the blank axis."""
    cells = ROW.split(",")
    cells[10] = ""
    text = f"{HEADER}\n{ROW}\n{','.join(cells)}\n"
    d = read_measurements(write(tmp_path, text), n_joints=6)  # base frame: fine
    assert np.isnan(d.position[1, 1]) and np.isfinite(d.position[1, 0])
    with pytest.raises(InputError, match=r"row 3: y_mm blank while the other axes are given, "
                                         r"in the device frame \(1 row like it\)"):
        read_measurements(write(tmp_path, text), n_joints=6, frame="device")
    whole = read_measurements(write(tmp_path, f"{HEADER}\n{ROW}\n"), n_joints=6,
                              frame="device")
    assert whole.frame == "device" and np.all(np.isfinite(whole.position))


def test_wrong_number_of_joint_values(tmp_path: Path) -> None:
    header = HEADER.replace("q6_deg,", "")
    row = ",".join(c for i, c in enumerate(ROW.split(",")) if i != 5)
    p = write(tmp_path, f"{header}\n{row}\n")
    with pytest.raises(InputError, match="file has 5 joints but the robot has 6"):
        read_measurements(p, n_joints=6)
    assert read_measurements(p).n_joints == 5


def test_empty_and_header_only_files(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="empty"):
        read_measurements(write(tmp_path, ""))
    with pytest.raises(InputError, match="no samples"):
        read_measurements(write(tmp_path, HEADER + "\n"))
    with pytest.raises(InputError, match="cannot read"):
        read_measurements(tmp_path / "missing.csv")


def test_all_positions_blank_and_bad_sigma(tmp_path: Path) -> None:
    cells = ROW.split(",")
    cells[9:12] = ["", "", ""]
    with pytest.raises(InputError, match="every position cell is blank"):
        read_measurements(write(tmp_path, f"{HEADER}\n{','.join(cells)}\n"))
    with pytest.raises(InputError, match=r"row 2, column 'sigma_mm'.*> 0"):
        read_measurements(write(tmp_path, f"{HEADER},sigma_mm\n{ROW},0\n"))


def test_subset() -> None:
    data = sample_set()
    sub = data.subset(np.array([0, 2]))
    assert len(sub) == 2
    np.testing.assert_array_equal(sub.q, data.q[[0, 2]])
    assert list(sub.pose_id) == ["P0", "P2"]  # type: ignore[arg-type]
