"""Measured weld tracks (CSV): where the weld actually went.

Two forms, told apart by the header (one row per measured point, units in the names):

* ``s_mm, e_lat_mm[, e_norm_mm]``: the offset of the weld centreline from the joint line at
  arc length s from the seam start, seam frame: ``e_lat`` toward the advancing side positive
  (the sign of the weld window), ``e_norm`` along the tool axis n (up) positive. This is what
  seed 000's measurement of the lateral offset gives (Figs. 15-17, Delta y = D1 - D2), or a
  laser line scan of the bead already referred to the joint line.
* ``x_mm, y_mm, z_mm``: the weld centreline in the robot base frame (a laser scan registered
  to the robot); it is projected onto the seam by the validation (lateral offset only: a
  surface scan does not see the pin depth).

Empty cells are gaps (scanner drop-outs) and are skipped; rows need not be sorted. Anything
else (unknown or duplicated columns, text, inf) is a one-line :class:`InputError`.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError

FloatArray = NDArray[np.float64]

SEAM_FORM = ("s_mm", "e_lat_mm")
SEAM_OPTIONAL = ("e_norm_mm",)
BASE_FORM = ("x_mm", "y_mm", "z_mm")
_EXPECTED = "s_mm, e_lat_mm[, e_norm_mm] (seam frame) or x_mm, y_mm, z_mm (base frame)"


@dataclass(frozen=True)
class WeldTrack:
    """A measured weld track (SI units).

    Attributes:
        form: ``seam`` (s, e_lat[, e_norm]) or ``base`` (x, y, z).
        s: Arc length from the seam start [m], shape (N,) (``seam`` form; None for ``base``).
        e_lat: Lateral offset, + toward the advancing side [m], shape (N,) (``seam``).
        e_norm: Offset along the tool axis n [m], shape (N,), or None.
        xyz: Centreline points, base frame [m], shape (N, 3) (``base`` form; else None).
        source: File the track came from.
        n_gaps: Rows skipped because a cell was empty.
    """

    form: str
    s: FloatArray | None
    e_lat: FloatArray | None
    e_norm: FloatArray | None
    xyz: FloatArray | None
    source: str = "<memory>"
    n_gaps: int = 0

    def __len__(self) -> int:
        return int(self.xyz.shape[0] if self.xyz is not None else self.s.shape[0])  # type: ignore[union-attr]


#: Largest coordinate or offset accepted [mm]: 100 m, beyond any robot cell's reach.
MAX_MM = 1e5


def read_weld_track(path: str | Path) -> WeldTrack:
    """Read a weld-track CSV (format in the module docstring) through the strict table reader
    (:func:`rfsw_plan.table.read_table`: delimiter and decimal comma detected, duplicated or
    empty column names, ragged rows and over-long cells refused).

    Raises:
        InputError: Unreadable file, unknown/duplicated/missing columns, a row with a cell too
            few or too many, a cell that is not a number or beyond +-:data:`MAX_MM` mm, fewer
            than 3 complete rows; the message names the file, row and column.
    """
    from rfsw_plan.table import read_table

    path = Path(path)
    tab = read_table(path)
    header = tab.header
    if set(SEAM_FORM) <= set(header):
        form, cols = "seam", [*SEAM_FORM, *(c for c in SEAM_OPTIONAL if c in header)]
    elif set(BASE_FORM) <= set(header):
        form, cols = "base", list(BASE_FORM)
    else:
        raise InputError(path, "header", f"columns {', '.join(header)}", _EXPECTED)
    unknown = [h for h in header if h not in cols]
    if unknown:
        raise InputError(path, "header", f"unknown column(s) {', '.join(unknown)} in a "
                         f"{form}-frame track", ", ".join(cols))
    col = [header.index(name) for name in cols]
    data: list[list[float]] = []
    gaps = 0
    for row, line in zip(tab.rows, tab.row_numbers, strict=True):
        vals = [_cell(path, row[i], line, name, tab.decimal) for i, name in zip(col, cols,
                                                                             strict=True)]
        if any(math.isnan(v) for v in vals):
            gaps += 1
        else:
            data.append(vals)
    if len(data) < 3:
        raise InputError(path, "", f"{len(data)} complete row(s)", "at least 3 measured points")
    a = np.asarray(data, dtype=float) * 1e-3
    if form == "base":
        return WeldTrack("base", None, None, None, a, str(path), gaps)
    order = np.argsort(a[:, 0], kind="stable")
    a = a[order]
    e_norm = a[:, 2].copy() if a.shape[1] > 2 else None
    return WeldTrack("seam", a[:, 0].copy(), a[:, 1].copy(), e_norm, None, str(path), gaps)


def _cell(path: Path, cell: str, line: int, name: str, decimal: str) -> float:
    """One track cell [mm]; NaN for a gap (empty or ``nan``)."""
    if cell == "" or cell.lower() == "nan":
        return math.nan
    try:
        v = float(cell.replace(",", ".") if decimal == "," else cell)
    except ValueError:
        raise InputError(path, f"row {line}, column {name}", f"'{cell[:40]}' is not a number",
                         "a number in mm, or an empty cell for a gap") from None
    if not math.isfinite(v) or abs(v) > MAX_MM:
        raise InputError(path, f"row {line}, column {name}", f"'{cell[:40]}'",
                         f"a finite number in mm within +-{MAX_MM:g} mm")
    return v


def write_weld_track(path: str | Path, track: WeldTrack) -> Path:
    """Write a track in the format :func:`read_weld_track` reads (atomically); NaN = gap."""
    from rfsw_plan import numfmt
    from rfsw_plan.files import atomic_path

    path = Path(path)

    def cell(v: float) -> str:
        return numfmt.cell(v * 1e3, 5)

    with atomic_path(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        if track.form == "base":
            assert track.xyz is not None
            w.writerow(BASE_FORM)
            for p in track.xyz:
                w.writerow([cell(v) for v in p])
        else:
            assert track.s is not None and track.e_lat is not None
            norm = track.e_norm is not None
            w.writerow([*SEAM_FORM, *(SEAM_OPTIONAL if norm else ())])
            for k in range(len(track.s)):
                row = [cell(track.s[k]), cell(track.e_lat[k])]
                if track.e_norm is not None:
                    row.append(cell(track.e_norm[k]))
                w.writerow(row)
    return path
