"""Weld-track CSV reader: both forms, gaps, and one-line errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.exceptions import InputError
from rfsw_plan.io.weld_track import WeldTrack, read_weld_track, write_weld_track


def _w(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "t.csv"
    p.write_text(text)
    return p


def test_seam_form_with_gaps_is_sorted_and_in_metres(tmp_path: Path) -> None:
    t = read_weld_track(_w(tmp_path, "s_mm,e_lat_mm,e_norm_mm\n2,0.2,0.01\n0,0.1,0\n1,,0\n"
                                     "3,0.3,0.02\n"))
    assert t.form == "seam" and t.n_gaps == 1
    np.testing.assert_allclose(t.s, [0.0, 2e-3, 3e-3])
    np.testing.assert_allclose(t.e_lat, [1e-4, 2e-4, 3e-4])
    assert t.e_norm is not None


def test_round_trip_keeps_gaps(tmp_path: Path) -> None:
    tr = WeldTrack("seam", np.array([0.0, 1e-3, 2e-3, 3e-3]),
                   np.array([1e-4, np.nan, 2e-4, 3e-4]), None, None)
    back = read_weld_track(write_weld_track(tmp_path / "r.csv", tr))
    assert back.n_gaps == 1 and len(back) == 3
    base = WeldTrack("base", None, None, None, np.array([[1.0, 2.0, 3.0]] * 3))
    np.testing.assert_allclose(read_weld_track(write_weld_track(tmp_path / "b.csv", base)).xyz,
                               base.xyz)


@pytest.mark.parametrize("text,needle", [
    ("s_mm,s_mm,e_lat_mm\n0,0,0\n", "appears twice"),
    ("s_mm,e_lat_mm\n0,0\n1,0,5\n2,0\n3,0\n", "row 3: 3 cells, the header has 2"),
    ("s_mm,e_lat_mm\n0,0\n1\n2,0\n3,0\n", "row 3: 1 cells"),
    ("s_mm,e_lat_mm\n0," + "1" * 140_000 + "\n1,0\n2,0\n", "longer than"),
    ("x_mm,y_mm,z_mm\n0,-1e308,0\n1,0,0\n2,0,0\n", "within +-100000 mm"),
    ("s_mm,e_lateral_mm\n0,0\n", "expected s_mm, e_lat_mm"),
    ("s_mm,e_lat_mm,quality\n0,0,1\n", "unknown column"),
    ("s_mm,e_lat_mm\n0,abc\n1,0\n2,0\n", "row 2, column e_lat_mm"),
    ("s_mm,e_lat_mm\n0,inf\n1,0\n2,0\n", "finite"),
    ("s_mm,e_lat_mm\n0,0\n1,0\n", "at least 3"),
    ("", "empty"),
])
def test_bad_tracks_are_one_line(tmp_path: Path, text: str, needle: str) -> None:
    with pytest.raises(InputError) as exc:
        read_weld_track(_w(tmp_path, text))
    assert needle in str(exc.value) and "\n" not in str(exc.value)


def test_read_through_the_table_reader(tmp_path: Path) -> None:
    """The one strict table reader: a spreadsheet's semicolons and decimal commas are read, a
    NaN cell is a gap like an empty one."""
    t = read_weld_track(_w(tmp_path, "s_mm;e_lat_mm\n0;0,1\n1;nan\n2;0,2\n3;0,3\n"))
    assert t.n_gaps == 1 and t.e_lat is not None and t.s is not None
    np.testing.assert_allclose(t.e_lat, [1e-4, 2e-4, 3e-4])
    np.testing.assert_allclose(t.s, [0.0, 2e-3, 3e-3])
