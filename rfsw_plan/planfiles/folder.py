"""The one strict reader of a written plan folder: :meth:`PlanFolder.open` -> :class:`PlanFolder`
(its record, its samples, and the plan rebuilt from them: :meth:`PlanFolder.rebuild`).

Every command that takes a plan folder (``export``, ``check``, ``validate-weld``) and the
Python API read it here, so a damaged folder is refused the same way everywhere, with one line
naming the file, key or row and what was expected:

1. ``plan.json`` is decoded as UTF-8 (a UTF-16 or binary file is refused, not guessed) and
   parsed as strict JSON (``NaN``, ``Infinity`` and duplicate keys are refused); it must be an
   object.
2. Its ``status`` must be a verified plan (``optimal``, ``verified``, either ``_nominal``): an
   ``infeasible`` plan is refused with exit 3 naming its reason, any other status (``failed``,
   ``incomplete``, missing) with exit 2.
3. Every file its ``sha256`` table vouches for must be there with those bytes, and
   ``waypoints.csv`` must be among them.
4. The samples of ``waypoints.csv`` that the caller will use are re-verified as numbers: every
   cell of the columns read is a finite number, time never runs backwards, phases are the
   planner's, and (with the robot) every joint value is inside the joint limits. A ``nan``
   in a joint cell whose file hash was updated is therefore one line, never a traceback of a
   later interpolation.

The physical re-verification of the samples (the weld window under the plan's model) is
:func:`rfsw_plan.planning.verify.verify_samples`; ``rfsw-plan check`` runs it on a program.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.files import sha256_file
from rfsw_plan.planfiles.record import VERIFIED_STATUSES, PlanRecord

if TYPE_CHECKING:
    from rfsw_plan.planfiles.rebuild import RebuiltPlan
    from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: Phase names of ``waypoints.csv``, in order.
PHASES = ("approach", "plunge", "dwell", "accelerate", "weld", "decelerate", "stop",
          "retract")
#: Joint values may sit this far outside the limits (the CSV's 1e-6 deg rounding) [rad].
LIMIT_SLACK = 1e-7
#: Program files that a read of a plan folder accepts with other bytes than plan.json vouches
#: for (:func:`touched_programs`).
_TOUCHED: ContextVar[frozenset[str]] = ContextVar("rfsw_plan_touched", default=frozenset())


@contextmanager
def touched_programs(names: Iterable[str]) -> Iterator[None]:
    """Within the block, every read of a plan folder accepts that the program files ``names``
    differ from the bytes ``plan.json`` vouches for (a program touched up inside its plan
    folder; ``rfsw-plan check`` re-verifies it). ``waypoints.csv`` is always checked."""
    token = _TOUCHED.set(_TOUCHED.get() | frozenset(names))
    try:
        yield
    finally:
        _TOUCHED.reset(token)


@dataclass(frozen=True)
class PlanSamples:
    """The verified timed samples of a plan (SI, base frame of the robot description).

    Attributes:
        t: Time [s], (N,).
        phase: Phase per sample, (N,).
        s: Pin arc length along the seam [m], (N,).
        q: Controller joint values [rad], (N, n).
        wrench: Process wrench on the tool at the TCP, base frame [N, N m], (N, 6).
        seam: Seam point, base frame [m], (N, 3).
        spindle_rpm: Commanded spindle speed [rpm], (N,), or None (a plan folder
            written before ``waypoints.csv`` had the column).
        spindle_on: The spindle switched on, (N,) bool, or None (likewise).
    """

    t: FloatArray
    phase: NDArray[np.str_]
    s: FloatArray
    q: FloatArray
    wrench: FloatArray
    seam: FloatArray
    spindle_rpm: FloatArray | None = None
    spindle_on: NDArray[np.bool_] | None = None

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def subset(self, idx: NDArray[np.int_]) -> PlanSamples:
        """The samples at indices ``idx``."""
        return PlanSamples(self.t[idx], self.phase[idx], self.s[idx], self.q[idx],
                           self.wrench[idx], self.seam[idx],
                           None if self.spindle_rpm is None else self.spindle_rpm[idx],
                           None if self.spindle_on is None else self.spindle_on[idx])


@dataclass(frozen=True)
class PlanFolder:
    """A plan folder that passed the strict reader (:meth:`PlanFolder.open`).

    Attributes:
        folder: The folder.
        record: ``plan.json`` (:class:`~rfsw_plan.planfiles.record.PlanRecord`, a verified
            plan's).
        samples: The re-verified samples of ``waypoints.csv``.
    """

    folder: Path
    record: PlanRecord
    samples: PlanSamples = field(repr=False)

    @classmethod
    def open(cls, folder: str | Path, joint_columns: list[str] | None = None,
             limits: tuple[FloatArray, FloatArray] | None = None) -> PlanFolder:
        """Read and check a plan folder (see the module docstring).

        Args:
            folder: Output folder of ``rfsw-plan plan``.
            joint_columns: The joint columns of ``waypoints.csv`` in joint order (the robot's
                controller axes, ``A1_deg``...); default: every ``<letters><digit>_deg``
                column.
            limits: Joint limits (lower, upper) [rad], (n,) each: every sample must be inside.

        Raises:
            InputError: A damaged folder (exit 2): one line naming the file and what is wrong.
            InfeasibleError: The plan's status is ``infeasible`` (exit 3), with its reason.
        """
        folder = Path(folder)
        if not folder.is_dir():
            raise InputError(folder, "", "not a folder",
                             "a plan folder written by rfsw-plan plan")
        path = folder / "plan.json"
        record = PlanRecord.read(path)
        record.check_status(path)
        digests = record.get("sha256")
        if not isinstance(digests, dict) or "waypoints.csv" not in digests:
            raise InputError(path, "sha256", "does not vouch for waypoints.csv",
                             "the sha256 table rfsw-plan plan writes")
        touched = _TOUCHED.get() - {"waypoints.csv"}
        for name, digest in digests.items():
            if str(name) not in touched:
                _check_vouched(folder, str(name), digest)
        samples = read_plan_samples(folder / "waypoints.csv", joint_columns, limits)
        return cls(folder, record, samples)

    @classmethod
    def open_with_robot(cls, folder: str | Path) -> tuple[PlanFolder, Robot]:
        """A plan folder read against the robot it was planned with: ``plan.json`` first (its
        status before anything else), then the robot it names, then every sample of
        ``waypoints.csv`` in that robot's joint columns and inside its joint limits.

        Raises:
            InputError: A damaged folder, no robot named, or an unknown robot (one line,
                exit 2).
            InfeasibleError: The plan's status is ``infeasible`` (exit 3), with its reason.
        """
        from rfsw_plan.robot.kinematics import load_robot

        path = Path(folder) / "plan.json"
        record = PlanRecord.read(path)
        record.check_status(path)  # an infeasible plan is named before its robot is looked for
        name = record.get("robot_file") or record.get("robot")
        if not isinstance(name, str) or not name.strip():
            raise InputError(path, "robot_file", "missing: the plan names no robot",
                             "the robot file or bundled name the plan was made with")
        robot = load_robot(name)
        d = robot.description
        return cls.open(folder, d.convention.column_names(), (d.lower, d.upper)), robot

    @property
    def status(self) -> str:
        """The plan's status (one of :data:`VERIFIED_STATUSES`)."""
        return self.record.status

    @property
    def problem(self) -> str:
        """The problem's name."""
        return self.record.problem

    @property
    def robot_file(self) -> str:
        """The robot description the plan names (``robot_file`` or ``robot``)."""
        return self.record.robot_file

    @property
    def problem_file(self) -> str:
        """The problem it names (``problem_file`` or ``problem``), or ``""``."""
        return self.record.problem_file

    @property
    def waypoints_sha256(self) -> str:
        """Hex SHA-256 of ``waypoints.csv`` (the plan id's source)."""
        return self.record.sha256["waypoints.csv"]

    def rebuild(self, problem: str | None = None) -> RebuiltPlan:
        """The plan rebuilt from its files: the problem it was planned for (``problem``:
        another problem file or bundled name), with the fitted forces of ``plan --forces``,
        on its robot file, its waypoints and its task
        (:func:`rfsw_plan.planfiles.rebuild.rebuild_plan`).

        Raises:
            InputError: No waypoints in the record, no problem named, an unreadable problem or
                robot file (one line, exit 2).
        """
        from rfsw_plan.planfiles.rebuild import rebuild_plan

        return rebuild_plan(self.folder, self.record, problem)

    def write_record(self, record: PlanRecord) -> Path:
        """Replace ``plan.json`` by ``record`` (atomically), e.g. to vouch for added files."""
        return record.write(self.folder / "plan.json")


def read_plan_folder(folder: str | Path, joint_columns: list[str] | None = None,
                     limits: tuple[FloatArray, FloatArray] | None = None) -> PlanFolder:
    """:meth:`PlanFolder.open`: read and check a plan folder (see the module docstring)."""
    return PlanFolder.open(folder, joint_columns, limits)


def read_plan_folder_and_robot(folder: str | Path) -> tuple[PlanFolder, Robot]:
    """:meth:`PlanFolder.open_with_robot`: a plan folder read against its robot."""
    return PlanFolder.open_with_robot(folder)


def sample_time(folder: str | Path) -> float | None:
    """The sample time of a plan folder's ``waypoints.csv`` [s] (its first two rows), read
    before the strict reader; None if it cannot tell (the strict reader names the damage)."""
    try:
        with (Path(folder) / "waypoints.csv").open(newline="", encoding="utf-8") as fh:
            rows = [r for _, r in zip(range(3), csv.DictReader(fh), strict=False)]
        return float(rows[1]["t_s"]) - float(rows[0]["t_s"])
    except (OSError, UnicodeDecodeError, IndexError, KeyError, TypeError, ValueError):
        return None


def _check_vouched(folder: Path, name: str, digest: Any) -> None:
    f = folder / name
    if Path(name).name != name or not isinstance(digest, str) or len(digest) != 64:
        raise InputError(folder / "plan.json", f"sha256.{name}", "malformed entry",
                         "a file name in the folder and 64 hex digits")
    if not f.is_file():
        raise InputError(f, "", "missing beside plan.json", "the file plan.json vouches for")
    if sha256_file(f) != digest:
        raise InputError(f, "", "changed since plan.json was written",
                         "the bytes plan.json vouches for (sha256)")


# --------------------------------------------------------------------------------------------
# waypoints.csv


def csv_rows(text: str) -> list[list[str]]:
    """The rows of a CSV text as the ``csv`` module reads them (``newline=""``). A text
    without quotes and with CRLF line ends only, as ``rfsw-plan plan`` writes
    ``waypoints.csv``, is split at its commas and line ends: the same rows, faster."""
    if '"' not in text and text.count("\n") == text.count("\r\n") == text.count("\r"):
        rows = [line.split(",") for line in text.split("\r\n")]
        if rows[-1] == [""]:  # the last line's end
            rows.pop()
        return [[] if r == [""] else r for r in rows]  # a blank line: csv's empty row
    return list(csv.reader(io.StringIO(text, newline="")))


def read_plan_samples(path: str | Path, joint_columns: list[str] | None = None,
                      limits: tuple[FloatArray, FloatArray] | None = None) -> PlanSamples:
    """The samples of a ``waypoints.csv``, re-verified as numbers (see the module docstring).

    Raises:
        InputError: One line naming the file, row and column.
    """
    p = Path(path)
    try:
        text = p.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(p, f"byte {exc.start}", "not UTF-8 text", "waypoints.csv") from None
    rows = csv_rows(text)
    body, col, joints = _table_shape(p, rows, joint_columns)
    columns = list(zip(*body, strict=True))  # the cells column by column (one pass in C)

    def num(names: list[str]) -> FloatArray:
        idx = [col[c] for c in names]
        try:  # each cell parsed as before; rows first, C order, as the rows were read
            out = np.ascontiguousarray(np.array([columns[i] for i in idx], dtype=float).T)
        except ValueError:
            out = np.array([[_cell(r[i]) for i in idx] for r in body])
        bad = ~np.isfinite(out) | (np.abs(out) > 1e12)
        if np.any(bad):
            k, j = (int(x[0]) for x in np.nonzero(bad))
            raise InputError(p, f"row {k + 2}, column {names[j]}",
                             f"'{body[k][idx[j]][:40]}' is not a finite number", "a number")
        return out

    phase = np.array(columns[col["phase"]])
    bad = [k for k, ph in enumerate(phase) if ph not in PHASES]
    if bad:
        raise InputError(p, f"row {bad[0] + 2}, column phase", f"'{phase[bad[0]][:40]}'",
                         ", ".join(PHASES))
    t = num(["t_s"])[:, 0]
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        raise InputError(p, f"row {back[0] + 3}, column t_s", "time runs backwards",
                         "non-decreasing times")
    q = np.radians(num(joints))
    if limits is not None:
        _check_limits(p, q, joints, limits)
    return PlanSamples(t, phase, num(["s_mm"])[:, 0] * 1e-3, q,
                       num(["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]),
                       num(["seam_x_mm", "seam_y_mm", "seam_z_mm"]) * 1e-3,
                       num(["spindle_rpm"])[:, 0] if "spindle_rpm" in col else None,
                       num(["spindle_on"])[:, 0] > 0 if "spindle_on" in col else None)


def _table_shape(p: Path, rows: list[list[str]], joint_columns: list[str] | None
                 ) -> tuple[list[list[str]], dict[str, int], list[str]]:
    """Body rows, column index and joint columns of a ``waypoints.csv`` whose
    header has every needed column and whose rows have as many cells as the header."""
    if len(rows) < 3:
        raise InputError(p, "", f"{max(len(rows) - 1, 0)} samples",
                         "a waypoints.csv written by rfsw-plan plan")
    header, body = rows[0], rows[1:]
    col = {h: i for i, h in enumerate(header)}
    joints = joint_columns or _joint_columns(header)
    need = ["t_s", "s_mm", "phase", "seam_x_mm", "seam_y_mm", "seam_z_mm", *joints,
            "fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]
    missing = [c for c in need if c not in col]
    if missing or not joints:
        raise InputError(p, "header", f"missing column {missing[0] if missing else 'q1_deg'}",
                         "the columns of waypoints.csv" + (f" ({', '.join(joints)})"
                                                           if joints else ""))
    for k, r in enumerate(body):
        if len(r) != len(header):
            raise InputError(p, f"row {k + 2}", f"{len(r)} cells", f"{len(header)} cells")
    return body, col, joints


def _cell(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan


def _joint_columns(header: list[str]) -> list[str]:
    import re

    found = [(re.fullmatch(r"[A-Za-z]+(\d+)_deg", h), h) for h in header]
    return [h for m, h in sorted(((m, h) for m, h in found if m),
                                 key=lambda x: int(x[0].group(1)))]


def _check_limits(p: Path, q: FloatArray, joints: list[str],
                  limits: tuple[FloatArray, FloatArray]) -> None:
    lo, hi = (np.asarray(x, dtype=float) for x in limits)
    out = (q < lo - LIMIT_SLACK) | (q > hi + LIMIT_SLACK)
    if np.any(out):
        k, j = (int(x[0]) for x in np.nonzero(out))
        raise InputError(p, f"row {k + 2}, column {joints[j]}",
                         f"{math.degrees(q[k, j]):.4f} deg outside the joint limits",
                         f"{math.degrees(lo[j]):g} .. {math.degrees(hi[j]):g} deg")


__all__ = ["PHASES", "VERIFIED_STATUSES", "PlanFolder", "PlanSamples", "read_plan_folder",
           "read_plan_folder_and_robot", "read_plan_samples", "sample_time"]
