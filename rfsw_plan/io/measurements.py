"""Measurement files: joint values, wrench at the TCP and measured TCP position.

Format (CSV, header row, one sample per row; documented in the README):

* ``q1_deg ... qN_deg`` (or ``q1_rad ... qN_rad``): encoder joint values.
* ``fx_N, fy_N, fz_N`` and optional ``mx_Nm, my_Nm, mz_Nm``: the wrench the environment applies
  to the tool at the TCP, robot base frame. Missing moment columns mean 0.
* ``x_mm, y_mm, z_mm``: measured TCP position, base frame; a blank cell means "not measured".
* Optional ``t_s`` (time [s]), ``pose_id`` (text), ``sigma_mm`` (1-sigma noise of the position
  measurement of that row). Any other numeric column is kept as an *extra* (temperature...).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from difflib import get_close_matches
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.io.files import atomic_path

FloatArray = NDArray[np.float64]

FORCE_COLUMNS = ("fx_N", "fy_N", "fz_N")
MOMENT_COLUMNS = ("mx_Nm", "my_Nm", "mz_Nm")
POSITION_COLUMNS = ("x_mm", "y_mm", "z_mm")


@dataclass(frozen=True)
class MeasurementSet:
    """Samples of a load campaign or a weld log (SI units inside).

    Attributes:
        q: Encoder joint values [rad], shape (m, n).
        wrench: Wrench at the TCP, base frame [N, N m], shape (m, 6).
        position: Measured TCP position, base frame [m], shape (m, 3); NaN = not measured.
        t: Time stamps [s], shape (m,), or None.
        pose_id: Pose labels, shape (m,), or None.
        sigma: Per-row 1-sigma position noise [m], shape (m,), or None.
        extra: Other numeric columns by name, each shape (m,).
        source: File the data came from.
    """

    q: FloatArray
    wrench: FloatArray
    position: FloatArray
    t: FloatArray | None = None
    pose_id: NDArray[np.str_] | None = None
    sigma: FloatArray | None = None
    extra: dict[str, FloatArray] = field(default_factory=dict)
    source: str = "<memory>"

    def __len__(self) -> int:
        return int(self.q.shape[0])

    @property
    def n_joints(self) -> int:
        """Number of joint columns."""
        return int(self.q.shape[1])

    @property
    def measured(self) -> NDArray[np.bool_]:
        """Mask of measured position axes, shape (m, 3)."""
        return np.isfinite(self.position)

    def subset(self, idx: NDArray[np.int_] | NDArray[np.bool_]) -> MeasurementSet:
        """Rows ``idx`` as a new set."""
        return MeasurementSet(
            q=self.q[idx],
            wrench=self.wrench[idx],
            position=self.position[idx],
            t=None if self.t is None else self.t[idx],
            pose_id=None if self.pose_id is None else self.pose_id[idx],
            sigma=None if self.sigma is None else self.sigma[idx],
            extra={k: v[idx] for k, v in self.extra.items()},
            source=self.source,
        )


def _missing(path: Path, name: str, header: list[str]) -> InputError:
    """Error for a missing column, with a hint at the column the user probably meant.

    A header that is the name without its unit (``fz`` for ``fz_N``) or with another unit
    (``fz_kN``) is preferred over a merely similar spelling.
    """
    base = name.rsplit("_", 1)[0].lower()
    same_quantity = [h for h in header if h.lower() == base or h.lower().startswith(base + "_")]
    close = same_quantity or get_close_matches(name, header, n=1)
    hint = ""
    if close and close[0] != name:
        hint = f"; found '{close[0]}': rename it to '{name}' (units in the column name)"
    return InputError(path, f"column '{name}'", f"missing{hint}", f"a column named '{name}'")


def read_measurements(path: str | Path, n_joints: int | None = None) -> MeasurementSet:
    """Read a measurement CSV (see module docstring).

    Args:
        path: CSV file.
        n_joints: Expected joint count (the robot's); None accepts what the file has.

    Raises:
        InputError: Unreadable file, missing column (named), non-numeric or NaN value (row
            given, counting the header as row 1), joint count mismatch, no measured axis.
    """
    p = Path(path)
    try:
        with p.open(newline="") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(p, "", f"cannot read file: {exc}") from None
    rows = [r for r in rows if any(c.strip() for c in r)]
    if not rows:
        raise InputError(p, "", "file is empty", "a header row and samples")
    header = [h.strip() for h in rows[0]]
    body = rows[1:]
    if not body:
        raise InputError(p, "", "no samples after the header row")
    col = {h: i for i, h in enumerate(header)}

    unit = "deg" if "q1_deg" in col else "rad" if "q1_rad" in col else None
    if unit is None:
        raise _missing(p, "q1_deg", header)
    n_file = 0
    while f"q{n_file + 1}_{unit}" in col:
        n_file += 1
    if n_joints is not None and n_file != n_joints:
        raise InputError(
            p, f"columns q1_{unit}..q{n_file}_{unit}",
            f"file has {n_file} joints but the robot has {n_joints}",
            f"q1_{unit} ... q{n_joints}_{unit}",
        )
    for name in FORCE_COLUMNS:
        if name not in col:
            raise _missing(p, name, header)
    present_pos = [c for c in POSITION_COLUMNS if c in col]
    if not present_pos:
        raise InputError(p, "columns x_mm, y_mm, z_mm", "no measured TCP axis in the file",
                         "at least one of x_mm, y_mm, z_mm")

    def numbers(name: str, allow_blank: bool) -> FloatArray:
        i = col[name]
        out = np.empty(len(body))
        for r, row in enumerate(body):
            cell = row[i].strip() if i < len(row) else ""
            if cell == "" and allow_blank:
                out[r] = math.nan
                continue
            try:
                v = float(cell)
            except ValueError:
                raise InputError(p, f"row {r + 2}, column '{name}'", f"'{cell}' is not a number"
                                 ) from None
            if not math.isfinite(v):
                raise InputError(p, f"row {r + 2}, column '{name}'", f"value is {cell}",
                                 "a finite number (leave position cells blank if not measured)")
            out[r] = v
        return out

    q = np.stack([numbers(f"q{j + 1}_{unit}", False) for j in range(n_file)], axis=1)
    if unit == "deg":
        q = np.radians(q)
    wrench = np.zeros((len(body), 6))
    for k, name in enumerate(FORCE_COLUMNS + MOMENT_COLUMNS):
        if name in col:
            wrench[:, k] = numbers(name, False)
    position = np.full((len(body), 3), math.nan)
    for k, name in enumerate(POSITION_COLUMNS):
        if name in col:
            position[:, k] = numbers(name, True) / 1000.0
    if not np.any(np.isfinite(position)):
        raise InputError(p, "columns x_mm, y_mm, z_mm", "every position cell is blank",
                         "at least one measured value")
    t = numbers("t_s", False) if "t_s" in col else None
    sigma = numbers("sigma_mm", False) / 1000.0 if "sigma_mm" in col else None
    if sigma is not None and np.any(sigma <= 0):
        r = int(np.nonzero(sigma <= 0)[0][0])
        raise InputError(p, f"row {r + 2}, column 'sigma_mm'", "must be > 0")
    pose_id = None
    if "pose_id" in col:
        i = col["pose_id"]
        pose_id = np.array([row[i].strip() if i < len(row) else "" for row in body])
    known = {f"q{j + 1}_{unit}" for j in range(n_file)} | set(FORCE_COLUMNS) | set(
        MOMENT_COLUMNS) | set(POSITION_COLUMNS) | {"t_s", "pose_id", "sigma_mm"}
    extra: dict[str, FloatArray] = {}
    for name in header:
        if name in known or not name:
            continue
        try:
            extra[name] = numbers(name, False)
        except InputError:
            continue  # non-numeric extra columns are ignored, as documented
    return MeasurementSet(q, wrench, position, t, pose_id, sigma, extra, str(p))


def write_measurements(path: str | Path, data: MeasurementSet) -> Path:
    """Write a measurement set in the documented CSV format (mm, deg)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    n = data.n_joints
    header = ([] if data.t is None else ["t_s"]) + ([] if data.pose_id is None else ["pose_id"])
    header += [f"q{j + 1}_deg" for j in range(n)]
    header += list(FORCE_COLUMNS + MOMENT_COLUMNS + POSITION_COLUMNS)
    header += [] if data.sigma is None else ["sigma_mm"]
    header += list(data.extra)
    with atomic_path(p) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for i in range(len(data)):
            row: list[str] = []
            if data.t is not None:
                row.append(f"{data.t[i]:.4f}")
            if data.pose_id is not None:
                row.append(str(data.pose_id[i]))
            row += [f"{np.degrees(v):.8f}" for v in data.q[i]]
            row += [f"{v:.6f}" for v in data.wrench[i]]
            row += ["" if not np.isfinite(v) else f"{v * 1000.0:.6f}" for v in data.position[i]]
            if data.sigma is not None:
                row.append(f"{data.sigma[i] * 1000.0:.6f}")
            row += [f"{data.extra[k][i]:.6g}" for k in data.extra]
            w.writerow(row)
    return p
