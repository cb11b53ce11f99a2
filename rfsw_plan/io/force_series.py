"""Measured process-force time series (CSV).

Format: header row, one sample per row.

* ``t_s``: time from the start of the process (plunge start, or approach start if the
  problem has an approach) [s], strictly increasing.
* ``fx_N, fy_N, fz_N``: force the workpiece applies to the tool at the TCP [N].
* optional ``mx_Nm, my_Nm, mz_Nm``: moment on the tool at the TCP [N m] (missing = not
  measured).
* optional ``frame``: the frame of the vectors, the same on every row: ``base`` (robot base),
  ``seam`` (x = travel t, y = lateral l toward the advancing side, z = tool axis n, up) or
  ``tool`` (commanded TCP frame: z into the workpiece, x along travel at tool rotation 0). A
  ``frame`` option given by the caller overrides a missing column; if both are given they must
  agree.

The data type, :class:`~rfsw_plan.process.force_series.ForceSeries`, lives in ``process/``
(the force fit uses it); it is re-exported here.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.numfmt import fixed
from rfsw_plan.process.force_series import FORCE_FRAMES, ForceSeries
from rfsw_plan.table import Quantity, read_table

FloatArray = NDArray[np.float64]

REQUIRED = ("t_s", "fx_N", "fy_N", "fz_N")
MOMENTS = ("mx_Nm", "my_Nm", "mz_Nm")


def read_force_series(path: str | Path, frame: str | None = None) -> ForceSeries:
    """Read a force CSV.

    Args:
        path: CSV file (format in the module docstring).
        frame: Frame of the vectors if the file has no ``frame`` column.

    Raises:
        InputError: Unreadable file, missing columns, non-numeric cells, unknown or
            inconsistent frame, fewer than 2 rows, or time not strictly increasing; the
            message names the file, row and column.
    """
    path = Path(path)
    if frame is not None and frame not in FORCE_FRAMES:
        raise InputError("--forces-frame", "", f"unknown frame '{frame}'",
                         " | ".join(FORCE_FRAMES))
    tab = read_table(path)
    header = tab.header
    quantities = {name: Quantity(name.split("_")[0], {name.split("_")[1]: 1.0})
                  for name in (*REQUIRED, *MOMENTS)}
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        hint = tab.missing(quantities[missing[0]]).problem.removeprefix("missing")
        raise InputError(path, "header", f"missing column(s) {', '.join(missing)}{hint}",
                         "t_s, fx_N, fy_N, fz_N[, mx_Nm, my_Nm, mz_Nm][, frame]")
    present_m = [c for c in MOMENTS if c in header]
    if present_m and len(present_m) != 3:
        raise InputError(path, "header", f"only {', '.join(present_m)} of the moment columns",
                         "all of mx_Nm, my_Nm, mz_Nm or none")
    if len(tab) < 2:
        raise InputError(path, "", f"{len(tab)} sample row(s)", "at least 2 samples")
    numeric = list(REQUIRED) + present_m
    data = np.stack([tab.numbers(name) for name in numeric], axis=1)
    frames_seen: set[str] = set(tab.texts("frame")) if "frame" in header else set()
    t = data[:, 0]
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        r = tab.row_numbers[int(bad[0]) + 1]
        raise InputError(path, f"row {r}, column t_s",
                         f"time {t[bad[0] + 1]:g} s does not increase (previous {t[bad[0]]:g} s)",
                         "strictly increasing time")
    if frames_seen:
        if len(frames_seen) > 1:
            raise InputError(path, "column frame", f"several frames {sorted(frames_seen)}",
                             "the same frame on every row")
        f_file = frames_seen.pop()
        if f_file not in FORCE_FRAMES:
            raise InputError(path, "column frame", f"unknown frame '{f_file}'",
                             " | ".join(FORCE_FRAMES))
        if frame is not None and frame != f_file:
            raise InputError(path, "column frame", f"file says '{f_file}' but '{frame}' was "
                             "requested", "the same frame")
        frame = f_file
    if frame is None:
        raise InputError(path, "header", "no frame column and no frame option",
                         "a 'frame' column or --forces-frame base|seam|tool")
    moment = data[:, 4:7].copy() if present_m else None
    return ForceSeries(t=t.copy(), force=data[:, 1:4].copy(), moment=moment, frame=frame,
                       source=str(path))


def write_force_series(path: str | Path, series: ForceSeries) -> Path:
    """Write a force series in the format read by :func:`read_force_series`."""
    from rfsw_plan.files import atomic_path

    path = Path(path)
    header = list(REQUIRED) + (list(MOMENTS) if series.moment is not None else []) + ["frame"]
    with atomic_path(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for k in range(len(series)):
            row = [fixed(series.t[k], 6), *(fixed(v, 6) for v in series.force[k])]
            if series.moment is not None:
                row += [fixed(v, 6) for v in series.moment[k]]
            w.writerow([*row, series.frame])
    return path


__all__ = ["FORCE_FRAMES", "ForceSeries", "read_force_series", "write_force_series"]
