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
from rfsw_plan.table import Quantity, Table, read_table, refuse_near_misses

FloatArray = NDArray[np.float64]

REQUIRED = ("t_s", "fx_N", "fy_N", "fz_N")
MOMENTS = ("mx_Nm", "my_Nm", "mz_Nm")


#: A friction stir weld presses the tool with kilonewtons (seed 001 Table 6: 4-9 kN axial): a
#: log whose largest force is below this [N] holds kN in *_N columns (or no weld at all).
MIN_WELD_FORCE_N = 100.0
#: A weld log longer than this [s] (4 h) holds milliseconds in its t_s column.
MAX_LOG_DURATION_S = 4 * 3600.0

_FORCES = tuple(Quantity(k, {"N": 1.0, "kN": 1e3}) for k in ("fx", "fy", "fz"))
_MOMENTS = tuple(Quantity(k, {"Nm": 1.0, "kNm": 1e3}) for k in ("mx", "my", "mz"))
_TIME = Quantity("t", {"s": 1.0, "ms": 1e-3})
_FRAME = Quantity("frame", {"": 1.0}, text=True)


def read_force_series(path: str | Path, frame: str | None = None) -> ForceSeries:
    """Read a force CSV through the strict table reader (:func:`rfsw_plan.table.read_table`).

    Forces may be given in ``fx_N`` or ``fx_kN``, moments in ``mx_Nm`` or ``mx_kNm``, time in
    ``t_s`` or ``t_ms``; a column that looks like one of these under another spelling
    (``FZ_N``, ``fz__N``) is refused, never ignored. Units are checked against the data: a
    largest force below :data:`MIN_WELD_FORCE_N` (kN logged in ``*_N`` columns) and a log
    longer than :data:`MAX_LOG_DURATION_S` (ms logged in ``t_s``) are refused with what was
    found.

    Args:
        path: CSV file (format in the module docstring).
        frame: Frame of the vectors if the file has no ``frame`` column.

    Raises:
        InputError: Unreadable file, missing or misspelt columns, a ragged row, non-numeric
            cells, unknown or inconsistent frame, fewer than 2 rows, time not strictly
            increasing, forces or time in the wrong unit; the message names the file, row and
            column.
    """
    path = Path(path)
    if frame is not None and frame not in FORCE_FRAMES:
        raise InputError("forces_frame", "", f"unknown frame '{frame}'",
                         " | ".join(FORCE_FRAMES))
    tab = read_table(path)
    hits = {q.key: tab.find(q) for q in (_TIME, *_FORCES, *_MOMENTS, _FRAME)}
    missing = [q for q in (_TIME, *_FORCES) if hits[q.key] is None]
    if missing:
        hint = tab.missing(missing[0]).problem.removeprefix("missing")
        raise InputError(path, "header", "missing column(s) "
                         f"{', '.join(q.default() for q in missing)}{hint}",
                         "t_s, fx_N, fy_N, fz_N[, mx_Nm, my_Nm, mz_Nm][, frame]")
    present_m = [q for q in _MOMENTS if hits[q.key] is not None]
    if present_m and len(present_m) != 3:
        raise InputError(path, "header", "only "
                         f"{', '.join(hits[q.key][0] for q in present_m)} of the moment "  # type: ignore[index]
                         "columns", "all of mx_Nm, my_Nm, mz_Nm or none")
    used = {h[0] for h in hits.values() if h is not None}
    refuse_near_misses(tab, [_TIME, *_FORCES, *_MOMENTS], used)
    if len(tab) < 2:
        raise InputError(path, "", f"{len(tab)} sample row(s)", "at least 2 samples")
    t = tab.numbers(*hits["t"])  # type: ignore[misc]
    force = np.stack([tab.numbers(*hits[q.key]) for q in _FORCES], axis=1)  # type: ignore[misc]
    moment = (np.stack([tab.numbers(*hits[q.key]) for q in _MOMENTS], axis=1)  # type: ignore[misc]
              if present_m else None)
    _check_time(tab, t, hits["t"][0])  # type: ignore[index]
    _check_force_unit(tab, force, [hits[q.key][0] for q in _FORCES])  # type: ignore[index]
    frame = _frame(tab, hits["frame"], frame)
    return ForceSeries(t=t, force=force, moment=moment, frame=frame, source=str(path))


def _check_time(tab: Table, t: FloatArray, name: str) -> None:
    """Strictly increasing time, over a weld's duration, not milliseconds."""
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        r = tab.row_numbers[int(bad[0]) + 1]
        raise InputError(tab.path, f"row {r}, column {name}",
                         f"time {t[bad[0] + 1]:g} s does not increase (previous {t[bad[0]]:g} s)",
                         "strictly increasing time")
    span = float(t[-1] - t[0])
    if span > MAX_LOG_DURATION_S:
        raise InputError(tab.path, f"column {name}", f"the log spans {span:g} s "
                         f"({span / 3600:.3g} h): milliseconds in a seconds column?",
                         "seconds in t_s (or name the column t_ms)")


def _check_force_unit(tab: Table, force: FloatArray, names: list[str]) -> None:
    """A weld log whose largest force is a few newtons holds kN in *_N columns."""
    peak = float(np.max(np.linalg.norm(force, axis=1)))
    if 0 < peak < MIN_WELD_FORCE_N and all(n.endswith("_N") for n in names):
        raise InputError(tab.path, f"columns {', '.join(names)}",
                         f"the largest force in the log is {peak:.3g} N; a friction stir weld "
                         "presses with kilonewtons: kN in *_N columns?",
                         "forces in N in *_N columns (or name them fx_kN, fy_kN, fz_kN)")


def _frame(tab: Table, hit: tuple[str, float] | None, frame: str | None) -> str:
    """The frame from the ``frame`` column and the option (they must agree)."""
    frames_seen = set(tab.texts(hit[0])) if hit is not None else set()
    if frames_seen:
        if len(frames_seen) > 1:
            raise InputError(tab.path, "column frame", f"several frames {sorted(frames_seen)}",
                             "the same frame on every row")
        f_file = frames_seen.pop()
        if f_file not in FORCE_FRAMES:
            raise InputError(tab.path, "column frame", f"unknown frame '{f_file}'",
                             " | ".join(FORCE_FRAMES))
        if frame is not None and frame != f_file:
            raise InputError(tab.path, "column frame", f"file says '{f_file}' but '{frame}' "
                             "was requested", "the same frame")
        frame = f_file
    if frame is None:
        raise InputError(tab.path, "header", "no frame column and no frame option",
                         "a 'frame' column or `forces_frame` base|seam|tool")
    return frame


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
