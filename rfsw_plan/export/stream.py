"""Stream file for real-time interfaces (KUKA RSI, ABB EGM): one row per controller cycle.

The verified samples (10 ms in ``waypoints.csv``) are resampled at the controller cycle
(default 4 ms, RSI's and EGM's fastest cycle) by a shape-preserving interpolation in time
(PCHIP per joint: between two samples every joint value stays between theirs, no overshoot);
the pose is the forward kinematics of the resampled joint values. The resampled rows are
checked like the plan's samples before the file is written (the caller's ``check``).

Columns: ``t_s, phase, x_mm, y_mm, z_mm, qw, qx, qy, qz`` (the commanded TCP, i.e. the
fake target, in the controller's base frame: KUKA ROBROOT, FANUC world, ABB base), the maker's
Euler angles where the robot has them (``A_deg, B_deg, C_deg`` or ``W_deg, P_deg, R_deg``),
then the controller joint values (``A1_deg`` ... / ``J1_deg`` ...).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import PchipInterpolator
from scipy.spatial.transform import Rotation

from rfsw_plan.exceptions import InputError
from rfsw_plan.export.program import Samples
from rfsw_plan.io.files import atomic_path
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: Default controller cycle [s].
DEFAULT_CYCLE = 0.004


def resample(samples: Samples, cycle: float = DEFAULT_CYCLE) -> Samples:
    """The samples at a fixed cycle [s] (see the module docstring)."""
    if not cycle > 0:
        raise InputError("--stream-cycle-ms", "", f"got {cycle * 1e3:g}", "> 0")
    t = samples.t
    tn = np.arange(t[0], t[-1] + 0.5 * cycle, cycle)
    tn = tn[tn <= t[-1] + 1e-12]
    q = PchipInterpolator(t, samples.q, axis=0)(tn)
    idx = np.clip(np.searchsorted(t, tn, side="right") - 1, 0, len(t) - 1)

    def lin(a: FloatArray) -> FloatArray:
        return np.stack([np.interp(tn, t, a[:, i]) for i in range(a.shape[1])], axis=1)

    return Samples(tn, samples.phase[idx], np.interp(tn, t, samples.s), q,
                   lin(samples.wrench), lin(samples.seam))


def write_stream(path: str | Path, robot: Robot, stream: Samples) -> Path:
    """Write the stream CSV atomically (columns in the module docstring)."""
    from rfsw_plan.io.waypoints import EULER_COLUMNS, maker_euler

    conv = robot.description.convention
    T = robot.batch_fk_jacobian(stream.q)[0]
    T = np.linalg.inv(conv.base)[None] @ T
    quat = Rotation.from_matrix(T[:, :3, :3]).as_quat()
    header = ["t_s", "phase", "x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"]
    cols = [stream.t, stream.phase, *(T[:, :3, 3] * 1e3).T, quat[:, 3], *quat[:, :3].T]
    euler = robot.description.euler
    if euler in EULER_COLUMNS:
        header += list(EULER_COLUMNS[euler])
        cols += list(np.degrees(maker_euler(T[:, :3, :3], euler)).T)
    header += conv.column_names()
    cols += list(np.degrees(stream.q).T)
    p = Path(path)
    with atomic_path(p) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for k in range(len(stream)):
            w.writerow([c[k] if isinstance(c[k], str) else f"{float(c[k]):.6f}" for c in cols])
    return p
