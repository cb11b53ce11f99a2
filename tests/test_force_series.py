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
    s = ForceSeries(np.arange(5) * 0.1, rng.normal(size=(5, 3)), rng.normal(size=(5, 3)),
                    "tool")
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
