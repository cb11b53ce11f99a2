"""Force CSV reader."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.exceptions import InputError
from rfsw_plan.io.force_series import ForceSeries, read_force_series, write_force_series

DATA = Path(__file__).parent / "data"


def test_roundtrip(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    # A weld's forces (kN; the reader refuses a log of a few newtons as kN in *_N columns).
    s = ForceSeries(np.arange(5) * 0.1, 3000.0 * rng.normal(size=(5, 3)),
                    30.0 * rng.normal(size=(5, 3)), "tool")
    back = read_force_series(write_force_series(tmp_path / "f.csv", s))
    np.testing.assert_allclose(back.force, s.force, atol=1e-6)
    assert back.moment is not None and back.frame == "tool"


def test_frame_option_and_bundled_fixture() -> None:
    s = read_force_series(DATA / "process_forces_noframe.csv", frame="seam")
    assert s.frame == "seam" and s.moment is None and len(s) == 3
    with pytest.raises(InputError, match="no frame"):
        read_force_series(DATA / "process_forces_noframe.csv")


@pytest.mark.parametrize(
    ("fixture", "match"),
    [("process_forces_missing_column.csv", "missing column.*fz_N"),
     ("process_forces_nonmonotonic.csv", "row 4, column t_s.*does not increase")],
)
def test_bad_files(fixture: str, match: str) -> None:
    with pytest.raises(InputError, match=match):
        read_force_series(DATA / fixture, frame="base")


def test_bad_cell(tmp_path: Path) -> None:
    p = tmp_path / "f.csv"
    p.write_text("t_s,fx_N,fy_N,fz_N\n0,1,2,3\n0.1,1,x,3\n")
    with pytest.raises(InputError, match=r"row 3, column .fy_N."):
        read_force_series(p, frame="base")


def _log(tmp_path: Path, header: str, scale: float = 1.0, t_scale: float = 1.0) -> Path:
    rows = [header] + [f"{k * 0.01 * t_scale:g},{-200 * scale:g},{150 * scale:g},"
                       f"{-6500 * scale:g},seam" for k in range(50)]
    p = tmp_path / "log.csv"
    p.write_text("\n".join(rows) + "\n")
    return p


def test_units_are_checked_against_the_data(tmp_path: Path) -> None:
    """Issue 25: kN in *_N columns and ms in t_s are caught from the data with what was found;
    kN and ms columns named as such are read in SI; a misspelt force column is refused."""
    ok = read_force_series(_log(tmp_path, "t_s,fx_N,fy_N,fz_N,frame"))
    kn = read_force_series(_log(tmp_path, "t_s,fx_kN,fy_kN,fz_kN,frame", 1e-3))
    np.testing.assert_allclose(kn.force, ok.force)
    ms = read_force_series(_log(tmp_path, "t_ms,fx_N,fy_N,fz_N,frame", t_scale=1e3))
    np.testing.assert_allclose(ms.t, ok.t)
    with pytest.raises(InputError, match=r"largest force in the log is 6.5\d* N.*kN"):
        read_force_series(_log(tmp_path, "t_s,fx_N,fy_N,fz_N,frame", 1e-3))
    with pytest.raises(InputError, match="milliseconds in a seconds column"):
        read_force_series(_log(tmp_path, "t_s,fx_N,fy_N,fz_N,frame", t_scale=1e6))
    with pytest.raises(InputError, match=r"column 'FZ_N'.*looks like fz"):
        read_force_series(_renamed(tmp_path), frame="seam")
    ragged = _log(tmp_path, "t_s,fx_N,fy_N,fz_N,frame")
    ragged.write_text(ragged.read_text().replace(",seam\n", ",seam,1\n", 1))
    with pytest.raises(InputError, match="row 2: 6 cells, the header has 5"):
        read_force_series(ragged)


def _renamed(tmp_path: Path) -> Path:
    p = _log(tmp_path, "t_s,fx_N,fy_N,fz_N,FZ_N")
    p.write_text(p.read_text().replace(",seam", ",-6500"))
    return p
