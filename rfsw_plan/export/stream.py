"""Stream file for real-time interfaces (KUKA RSI, ABB EGM): one row per controller cycle.

The rows are the plan's trajectory timed at the controller cycle (default 4 ms, RSI's and
EGM's fastest cycle) by the planner's own time parameterisation (``plan --export stream``
re-times the verified plan with ``dt`` = the cycle), never an interpolation of the 10 ms
samples: resampling 10 ms samples at 4 ms makes a new trajectory whose finite-difference jerk
breaks the joint limits (measured on zk500_table6_seam: 1866 deg/s^3 against 1800 with PCHIP).
The rows pass the planner's sample check before the file is written (the caller's ``check``);
the pose is the forward kinematics of the joint values.

Each piece of the plan (approach, plunge, dwell, ramps, weld, retract) is sampled with the
whole number of cycles that covers it, so a piece whose duration is not a multiple of the
cycle is stretched by less than one cycle when the rows are sent one per cycle (slower, so
every velocity, acceleration and jerk limit checked on the planned times still holds):
``t_s`` is the stream clock (row k at k cycles), ``t_plan_s`` the planned time of the row.

Columns: ``t_s, t_plan_s, phase, x_mm, y_mm, z_mm, qw, qx, qy, qz`` (the commanded TCP, i.e. the
fake target, in the controller's base frame: KUKA ROBROOT, FANUC world, ABB base), the maker's
Euler angles where the robot has them (``A_deg, B_deg, C_deg`` or ``W_deg, P_deg, R_deg``),
then the controller joint values (``A1_deg`` ... / ``J1_deg`` ...), then the spindle state
``spindle_on`` (1 on, 0 off) and speed ``spindle_rpm`` (as in ``waypoints.csv``), then the
process state the plan expects at the row: the pin's arc length ``s_mm`` and the process
wrench on the tool at the TCP ``fx_N, fy_N, fz_N, mx_Nm, my_Nm, mz_Nm`` in the controller's
base frame (a reference for a force loop or for the measured forces; ``rfsw-plan check``
judges each row under it, after checking it against ``waypoints.csv``).
"""

from __future__ import annotations

import csv
import hashlib
import io
import re
from collections.abc import Hashable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.export.format import ControllerFormat, ReadPoint, ReadProgram
from rfsw_plan.export.program import PHASES, Program, Samples, sample_fk
from rfsw_plan.files import atomic_path, program_text
from rfsw_plan.numfmt import fixed_many
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: The process state columns (arc length, then the wrench in the controller's base frame).
STATE_COLUMNS = ("s_mm", "fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm")

#: Default controller cycle [s].
DEFAULT_CYCLE = 0.004


def samples_of(trajectory: object, seam: FloatArray) -> Samples:
    """:class:`Samples` of a timed trajectory (``t, phase, s, q, wrench``, the spindle)
    and its seam points [m], (N, 3)."""
    tr = trajectory
    return Samples(np.asarray(tr.t), np.asarray(tr.phase).astype(str),  # type: ignore[attr-defined]
                   np.asarray(tr.s), np.asarray(tr.q), np.asarray(tr.wrench),  # type: ignore[attr-defined]
                   np.asarray(seam, dtype=float),
                   spindle_rpm=np.asarray(tr.spindle_rpm),  # type: ignore[attr-defined]
                   spindle_on=np.asarray(tr.spindle_on))  # type: ignore[attr-defined]


def write_stream(path: str | Path, robot: Robot, stream: Samples, cycle: float) -> Path:
    """Write the stream CSV atomically (columns in the module docstring)."""
    from rfsw_plan.planfiles.waypoints import EULER_COLUMNS, maker_euler
    from rfsw_plan.robot.rotation import Rotation

    conv = robot.description.convention
    T = sample_fk(robot, stream.q)
    T = np.linalg.inv(conv.base)[None] @ T
    quat = Rotation.from_matrix(T[:, :3, :3]).as_quat()
    header = ["t_s", "t_plan_s", "phase", "x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"]
    clock = stream.t[0] + cycle * np.arange(len(stream))
    cols = [clock, stream.t, stream.phase, *(T[:, :3, 3] * 1e3).T, quat[:, 3], *quat[:, :3].T]
    euler = robot.description.euler
    if euler in EULER_COLUMNS:
        header += list(EULER_COLUMNS[euler])
        cols += list(np.degrees(maker_euler(T[:, :3, :3], euler)).T)
    header += conv.column_names()
    cols += list(np.degrees(stream.q).T)
    if stream.spindle_rpm is not None and stream.spindle_on is not None:
        header += ["spindle_on", "spindle_rpm"]
        cols += [np.where(stream.spindle_on, "1", "0"), stream.spindle_rpm]
    R = np.linalg.inv(conv.base)[:3, :3]  # the wrench's force and moment into the base frame
    header += list(STATE_COLUMNS)
    cols += [stream.s * 1e3, *(stream.wrench[:, :3] @ R.T).T, *(stream.wrench[:, 3:] @ R.T).T]
    body = _rows_text(cols)
    p = Path(path)
    with atomic_path(p) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        if body is None:  # a text cell the CSV writer quotes: cell by cell
            text = [_column_text(c) for c in cols]
            w.writerows(zip(*text, strict=True))
        else:
            fh.write(body)
    return p


#: Characters that make the CSV writer quote a cell (its delimiter, quote and line ends).
_QUOTED = frozenset(',"\r\n')


def _rows_text(cols: list[Any]) -> str | None:
    """The rows as :func:`csv.writer` writes them (``\\r\\n`` after each row), numbers as
    :func:`~rfsw_plan.numfmt.fixed` with 6 decimals (``%.6f`` is the same text as
    ``{:.6f}``; a number that would read ``-0.000000`` is written as 0): one format per
    row instead of one call per cell. None where a text cell would be quoted (then the
    caller writes cell by cell).

    Raises:
        ValueError: A number is NaN or infinite (as :func:`_column_text`).
    """
    kinds: list[str] = []
    values: list[list[Any]] = []
    for column in cols:
        a = np.asarray(column)
        if a.dtype.kind in "USO":
            cells = [str(v) for v in a.tolist()]
            if any(_QUOTED.intersection(c) for c in set(cells)):
                return None
            kinds.append("%s")
            values.append(cells)
            continue
        if not np.isfinite(a).all():
            raise ValueError(f"cannot write the non-finite number {a[~np.isfinite(a)][0]!r} "
                             "as text")
        a = np.array(a, dtype=float).ravel()
        for k in np.flatnonzero((a <= 0.0) & (a > -1e-6)).tolist():
            if f"{a[k]:.6f}" == "-0.000000":
                a[k] = 0.0
        kinds.append("%.6f")
        values.append(a.tolist())
    row = ",".join(kinds) + "\r\n"
    return "".join([row % cells for cells in zip(*values, strict=True)])


def _column_text(column: Any) -> list[str]:
    """A stream column as its cells: text as it is, numbers as
    :func:`~rfsw_plan.numfmt.fixed` (6 decimals).

    Raises:
        ValueError: A number is NaN or infinite (as :func:`~rfsw_plan.numfmt.fixed`).
    """
    a = np.asarray(column)
    if a.dtype.kind in "USO":
        return [str(v) for v in a.tolist()]
    if not np.isfinite(a).all():
        raise ValueError(f"cannot write the non-finite number {a[~np.isfinite(a)][0]!r} as text")
    return fixed_many(a, 6)


@dataclass(frozen=True)
class StreamRows:
    """A stream file as its rows (:func:`read_stream`): what the real-time interface sends,
    one row per controller cycle.

    Attributes:
        t: The stream clock [s], (R,): row k is sent at ``t[0] + k`` cycles.
        t_plan: The planned time of each row [s], (R,), on the plan's own clock
            (``waypoints.csv``'s ``t_s``).
        phase: The phase of each row, (R,).
        q: Controller joint values [rad], (R, n).
        spindle_on: The spindle switched on, (R,) bool, or None (no such column).
        spindle_rpm: The commanded spindle speed [rpm], (R,), or None.
        state: The process state the file states for each row, (R, 7): arc length [m] and
            the wrench in the controller's base frame [N, N m]; None (a stream written
            before the columns).
    """

    t: FloatArray
    t_plan: FloatArray
    phase: NDArray[np.str_]
    q: FloatArray
    spindle_on: NDArray[np.bool_] | None = None
    spindle_rpm: FloatArray | None = None
    state: FloatArray | None = None

    @staticmethod
    def name(k: int) -> str:
        """Row k's name as ``check`` reports it (its line in the file: ``row 2`` is the first
        row after the header)."""
        return f"row {k + 2}"


def read_stream(path: str | Path) -> StreamRows:
    """Read a stream file's rows (columns in the module docstring): the numbers by numpy's
    C reader (:func:`numpy.loadtxt`, a 70 000-row stream in a tenth of a second), a file it
    refuses again cell by cell for the one-line error.

    Raises:
        InputError: One line naming the file and the row or column: no rows, a missing
            ``t_s``, ``t_plan_s``, ``phase`` or joint column, a row of another length than
            the header, a cell that is not a number, a phase the plan does not have, a
            ``spindle_on`` other than 0 or 1.

    The same bytes read again (export's round trip, then its judge; ``check``) are the rows
    read the first time (the last two files by their SHA-256), their arrays read-only.
    """
    raw = Path(path).read_bytes()
    key = hashlib.sha256(raw).digest()
    for seen, rows in _READ:  # export's round trip and its judge read the same file
        if seen == key:
            return rows
    rows = _parse_stream(path, program_text(raw))
    for a in (rows.t, rows.t_plan, rows.phase, rows.q, rows.spindle_on, rows.spindle_rpm,
              rows.state):
        if a is not None:  # shared by every reader of these bytes: nobody changes them
            a.setflags(write=False)
    _READ[:] = [*_READ[-1:], (key, rows)]
    return rows


#: The last stream files read, by the SHA-256 of their bytes, and their rows.
_READ: list[tuple[bytes, StreamRows]] = []


def _parse_stream(path: str | Path, text: str) -> StreamRows:
    """:func:`read_stream` of the file's text."""
    lines = text.splitlines()
    if len(lines) < 2:
        raise InputError(path, "", "no rows", "a stream file")
    head = next(csv.reader(lines[:1]))
    joints = [i for i, h in enumerate(head) if re.fullmatch(r"[A-Za-z]+\d+_deg", h)]
    missing = [c for c in ("t_s", "t_plan_s", "phase") if c not in head]
    if not joints or missing:
        raise InputError(path, "header", f"no {', '.join(missing) or 'joint'} column",
                         "a stream file (t_s, t_plan_s, phase, ..., A1_deg ...)")
    extra = [c for c in ("spindle_on", "spindle_rpm", *STATE_COLUMNS) if c in head]
    use = [head.index("t_s"), head.index("t_plan_s"), *joints, *(head.index(c) for c in extra)]
    try:
        if any(line.count(",") != len(head) - 1 for line in lines[1:]):
            raise ValueError("a row of another length")
        data = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1, usecols=use,
                          quotechar='"', ndmin=2, dtype=float, encoding=None)
        phase = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1,
                           usecols=head.index("phase"), quotechar='"', ndmin=1, dtype=str,
                           encoding=None)
    except ValueError:
        raise _first_bad_cell(path, head, lines, use) from None
    odd = np.flatnonzero(~np.isin(phase, PHASES))
    if odd.size:
        k = int(odd[0])
        raise InputError(path, f"row {k + 2}", f"phase = {str(phase[k])[:40]!r}",
                         ", ".join(PHASES))
    n = len(joints)
    named = dict(zip(extra, data[:, 2 + n:].T, strict=True))
    return StreamRows(data[:, 0].copy(), data[:, 1].copy(), phase,
                      np.radians(np.ascontiguousarray(data[:, 2:2 + n])),
                      _spindle_on(path, named.get("spindle_on")), named.get("spindle_rpm"),
                      _state(named))


def _spindle_on(path: str | Path, on: FloatArray | None) -> NDArray[np.bool_] | None:
    """The ``spindle_on`` column as booleans (None: no column).

    Raises:
        InputError: A value other than 0 or 1 (its row).
    """
    if on is None:
        return None
    bad = np.flatnonzero(~np.isin(on, (0.0, 1.0)))
    if bad.size:
        k = int(bad[0])
        raise InputError(path, f"row {k + 2}", f"spindle_on = {on[k]:g}", "0 or 1")
    return np.asarray(on == 1.0)


def _state(named: dict[str, FloatArray]) -> FloatArray | None:
    """The process state columns (:data:`STATE_COLUMNS`) as (R, 7), arc length in metres;
    None unless the file has them all."""
    if not all(c in named for c in STATE_COLUMNS):
        return None
    state = np.column_stack([named[c] for c in STATE_COLUMNS])
    state[:, 0] *= 1e-3
    return state


def _first_bad_cell(path: str | Path, head: list[str], lines: list[str], use: list[int]
                    ) -> InputError:
    """The one-line error of the first row a stream file's reader refuses: its length, or
    its first numeric cell that is not a number."""
    for k, row in enumerate(csv.reader(lines[1:]), start=2):
        if len(row) != len(head):
            return InputError(path, f"row {k}", f"{len(row)} cells", f"{len(head)} as the header")
        for i in use:
            if not _is_number(row[i]):
                return InputError(path, f"row {k}", f"{head[i]} = {row[i]!r}", "a number")
    return InputError(path, "", "unreadable rows", "a stream file")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


class StreamFormat(ControllerFormat):
    """One row per controller cycle (CSV) for real-time interfaces: joint targets only."""

    name = "stream"
    order = 40
    description = "stream CSV at the controller cycle (KUKA RSI, ABB EGM)"
    suffix = "_stream.csv"
    runs_rows = True

    def file_name(self, program: Program) -> str:
        return f"{program.header.name}_stream.csv"

    def posture(self, robot: Robot, q: FloatArray) -> Hashable:
        return None  # joint values: no posture to state

    def write(self, program: Program, folder: Path) -> list[Path]:
        assert program.stream is not None
        return [write_stream(Path(folder) / self.file_name(program), program.robot,
                             program.stream, program.cycle)]

    def read(self, path: Path) -> ReadProgram:
        rows = read_stream(path)
        dt = np.diff(rows.t, prepend=rows.t[0])
        pts = [ReadPoint(rows.name(k), q=rows.q[k], kind="joint", duration=float(dt[k]))
               for k in range(len(rows.t))]
        return ReadProgram(np.eye(4), np.eye(4), pts, (Path(path),))

    def path_deviation(self, program: Program) -> FloatArray:
        """The rows are the samples themselves: no path between them to bound."""
        return np.zeros(len(program.all_samples))

    def expected(self, program: Program) -> Samples:
        assert program.stream is not None
        return program.stream
