"""A controller program, independent of the vendor language: points, motions, frames, header.

The program is built from the *verified samples* of a written plan (``waypoints.csv``, every
row checked by the planner before it was written): every program point is one of those
samples, never an interpolation, so each point is a pose the plan verified.

Points (:func:`build_program`):

* the first sample (the approach point, reached with a joint move, PTP / J / MoveJ), the last
  sample of every phase, and in the welding phases (``accelerate``, ``weld``, ``decelerate``) the
  sample nearest to every multiple of the export spacing along the seam (default the plan's
  waypoint spacing: the planned fake targets);
* then, between two neighbouring points, the sample farthest from the straight line the
  controller will run (position distance to the chord, orientation angle to the slerp at the
  same fraction) is added while it is farther than ``path_tol`` (Douglas-Peucker), so every
  verified sample lies within ``path_tol`` of the programmed linear path
  (default 0.01 mm and 0.01 deg).

Motions: a linear move to every point after the first, with the speed that keeps the plan's
time on that segment (chord length / planned duration); a segment over which the pose does not
change (below 1 um and 0.001 deg) is a wait for its planned duration (``WAIT SEC``, ``WAIT``,
``WaitTime``).

Blending rule (what keeps the verified path): only between two segments that both lie in a
welding phase, never at a point that ends the approach, plunge or dwell or starts the retract
(exact stop there: the plunge and dwell are force-controlled by time, and the pin must be at
the planned spot). The blend distance at point k is
``d_k = min(0.4 min(|seg_k-1|, |seg_k|), 2 path_tol / sin(theta_k / 2))`` with theta_k the
direction change between the two segments: a corner rounded over the distance d deviates from
the polyline by at most ``d sin(theta/2) / 2 <= path_tol``, so the rounded path stays within
2 ``path_tol`` of every verified sample. Vendor mapping: KUKA ``C_DIS`` with ``$APO.CDIS = d``,
ABB zonedata with ``pzone_tcp = d``, FANUC ``CNT`` = 100 d / (0.4 min segment) (FANUC's CNT is a
percentage of the corner rounding, not a distance).

Frames: the tool is the planned TCP in the controller's flange frame (KUKA FLANGE, FANUC
faceplate, ABB tool0); the work object (KUKA BASE, FANUC user frame, ABB wobjdata) is a seam
frame in the controller's base frame: origin at the first weld sample's seam point, x along
the seam, z against the tool axis at the first in-material sample (out of the workpiece),
y = z x x. Points are written in that frame, so re-teaching the work object moves the program.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation, Slerp

from rfsw_plan.exceptions import InputError
from rfsw_plan.planning.verify import CONTACT_PHASES
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: Phases in which blending is allowed (the pin travels along the seam).
WELD_PHASES = ("accelerate", "weld", "decelerate")
#: Phase names in program order.
PHASES = ("approach", "plunge", "dwell", "accelerate", "weld", "decelerate", "retract")
#: Below these a segment does not move [m], [rad]: it is a wait.
STILL_POS = 1e-6
STILL_ANG = math.radians(1e-3)


@dataclass(frozen=True)
class Samples:
    """The verified timed samples of a plan (SI, base frame of the robot description).

    Attributes:
        t: Time [s], (N,).
        phase: Phase per sample, (N,).
        s: Pin arc length along the seam [m], (N,).
        q: Controller joint values [rad], (N, n).
        wrench: Process wrench on the tool [N, N m], (N, 6).
        seam: Seam point [m], (N, 3).
    """

    t: FloatArray
    phase: NDArray[np.str_]
    s: FloatArray
    q: FloatArray
    wrench: FloatArray
    seam: FloatArray

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def subset(self, idx: NDArray[np.int_]) -> Samples:
        """The samples at indices ``idx``."""
        return Samples(self.t[idx], self.phase[idx], self.s[idx], self.q[idx],
                       self.wrench[idx], self.seam[idx])


@dataclass(frozen=True)
class ProgramHeader:
    """What every program carries in its header.

    Attributes:
        name: Program name (letters, digits, underscores; vendor limits applied by writers).
        plan_id: ``<problem>-<first 12 hex of the SHA-256 of waypoints.csv>``.
        problem: Problem name.
        robot: Robot name.
        robot_file: File name (no folder: a controller file must not carry a local path) of
            the robot description the plan used, or ``""`` for one built in memory.
        robot_sha256: Hex SHA-256 of that file's bytes (``""`` without a file): names the
            exact description wherever the file was copied to.
        version: rfsw-plan version that wrote the program.
        tolerated_uncertainty: Verified tolerated relative force uncertainty (inf: unbounded).
        requested_uncertainty: Relative force uncertainty the plan was asked to hold.
        window_mm: Weld window (lower, upper) [mm].
        path_tol: Path tolerance of the point selection [m].
        spacing: Point spacing along the seam [m].
    """

    name: str
    plan_id: str
    problem: str
    robot: str
    robot_file: str
    robot_sha256: str
    version: str
    tolerated_uncertainty: float
    requested_uncertainty: float
    window_mm: tuple[float, float]
    path_tol: float
    spacing: float

    def lines(self) -> list[str]:
        """Header lines (without comment markers), the same for every vendor."""
        tol = self.tolerated_uncertainty
        tol_s = "unbounded" if not math.isfinite(tol) else f"+-{100 * tol:.3g} %"
        return [
            f"rfsw-plan program {self.name}",
            f"rfsw-plan version: {self.version}",
            f"problem: {self.problem}",
            f"plan id: {self.plan_id}",
            f"robot: {self.robot}",
            f"robot file: {self.robot_file or 'none (description built in memory)'}",
            f"robot file sha256: {self.robot_sha256 or 'none'}",
            f"verified tolerated force uncertainty: {tol_s}",
            f"requested force uncertainty: +-{100 * self.requested_uncertainty:.3g} %",
            f"weld window: {self.window_mm[0]:+.3f} .. {self.window_mm[1]:+.3f} mm",
            f"points: plan samples every {self.spacing * 1e3:.3g} mm of seam",
            f"path within {self.path_tol * 1e3:.3g} mm of every verified sample",
            "lengths mm, angles deg, joints = controller axes",
        ]

    def comments(self, marker: str, max_len: int | None = None) -> list[str]:
        """The header as comment lines of a vendor language.

        Args:
            marker: Text before each line, e.g. ``"; "`` (KRL), ``"  ! "`` (RAPID).
            max_len: Longest line text (without the marker); a longer line continues on
                the next ones, indented by two spaces, so nothing is lost (FANUC TP
                remarks: the 64 hex of a SHA-256). None: no limit.
        """
        out = []
        for line in self.lines():
            while max_len is not None and len(line) > max_len:
                out.append(marker + line[:max_len])
                line = "  " + line[max_len:]
            out.append(marker + line)
        return out


def controller_name(name: str, *, max_len: int, prefix: str, upper: bool = False) -> str:
    """A program or module name a controller accepts.

    Every character other than a letter, digit or underscore becomes ``_``; a name that does
    not start with a letter gets ``prefix``; the result is cut to ``max_len`` characters.

    Args:
        name: The requested name.
        max_len: The vendor's longest name (KRL 24, RAPID 32, FANUC TP 36).
        prefix: Prepended when the name does not start with a letter.
        upper: Upper-case only (FANUC TP).
    """
    n = re.sub(r"[^A-Z0-9_]" if upper else r"[^A-Za-z0-9_]", "_",
               name.upper() if upper else name)
    if not n[:1].isalpha():
        n = prefix + n
    return n[:max_len]


def phase_comments(phase: str, marker: str, spindle_start: tuple[str, ...],
                   spindle_stop: tuple[str, ...]) -> list[str]:
    """Comment lines that open a phase in a program.

    The phase mark, then before the plunge the spindle start placeholder and at the retract the
    spindle stop placeholder (vendor text, one comment line each).

    Args:
        phase: The phase that starts.
        marker: Comment marker with its indentation, e.g. ``"  ;"`` (KRL).
        spindle_start: Placeholder text lines before the plunge.
        spindle_stop: Placeholder text lines at the retract.
    """
    out = [f"{marker} ---- phase: {phase}"]
    if phase == "plunge":
        out += [f"{marker} {t}" for t in spindle_start]
    if phase == "retract":
        out += [f"{marker} {t}" for t in spindle_stop]
    return out


@dataclass(frozen=True)
class Motion:
    """One program instruction.

    Attributes:
        kind: ``ptp`` (joint move to the point), ``lin`` (linear move) or ``wait``.
        point: Index into :attr:`Program.points` (the target; for ``wait``, the point held).
        phase: Phase of the motion (of its target point).
        speed: TCP speed of a ``lin`` [m/s].
        duration: Planned duration of the segment or wait [s].
        blend: Blend distance at the target [m] (0: exact stop).
    """

    kind: str
    point: int
    phase: str
    speed: float = 0.0
    duration: float = 0.0
    blend: float = 0.0


@dataclass(frozen=True)
class Program:
    """A vendor-neutral controller program.

    Attributes:
        header: The header.
        robot: The robot (kinematics, controller convention).
        sample_index: Index of each point's sample in the plan's samples, (P,).
        samples: The program points' samples (joint values, phases...), length P.
        tool: TCP in the controller's flange frame [m], (4, 4).
        work: Work object (seam frame) in the controller's base frame [m], (4, 4).
        poses: TCP of every point in the work object frame [m], (P, 4, 4).
        motions: The instructions, in order.
        all_samples: Every verified sample (for the stream and the path checks).
    """

    header: ProgramHeader
    robot: Robot
    sample_index: NDArray[np.int_]
    samples: Samples
    tool: FloatArray
    work: FloatArray
    poses: FloatArray
    motions: tuple[Motion, ...]
    all_samples: Samples = field(repr=False)

    def phase_changes(self) -> dict[int, str]:
        """Motion index -> phase, where a new phase starts (for the phase marks)."""
        out: dict[int, str] = {}
        last = ""
        for i, m in enumerate(self.motions):
            if m.phase != last:
                out[i] = m.phase
                last = m.phase
        return out

    def moved_points(self) -> NDArray[np.int_]:
        """Indices of the points a motion moves to (a wait holds the previous point)."""
        return np.array([m.point for m in self.motions if m.kind != "wait"], dtype=int)

    def base_pose(self, pose_work: FloatArray) -> FloatArray:
        """TCP pose(s) in the work object frame -> the description's base frame [m]."""
        conv = self.robot.description.convention
        return np.asarray(conv.base @ self.work @ pose_work)


# --------------------------------------------------------------------------------------------
# Reading a plan folder


def read_samples(path: str | Path, robot: Robot) -> Samples:
    """Read ``waypoints.csv`` (see :mod:`rfsw_plan.planfiles.waypoints`) into :class:`Samples`.

    Raises:
        InputError: A missing column or a non-numeric cell (one line naming the file).
    """
    p = Path(path)
    cols = robot.description.convention.column_names()
    with p.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        raise InputError(p, "", "no samples", "a waypoints.csv written by rfsw-plan plan")
    need = ["t_s", "s_mm", "phase", "seam_x_mm", "seam_y_mm", "seam_z_mm", *cols,
            "fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]
    missing = [c for c in need if c not in rows[0]]
    if missing:
        raise InputError(p, missing[0], "missing column",
                         f"the columns of waypoints.csv for robot {robot.name}")

    def num(names: list[str]) -> FloatArray:
        try:
            return np.array([[float(r[c]) for c in names] for r in rows])
        except ValueError as exc:
            raise InputError(p, ",".join(names), f"not a number ({exc})") from None

    return Samples(
        t=num(["t_s"])[:, 0], phase=np.array([r["phase"] for r in rows]),
        s=num(["s_mm"])[:, 0] * 1e-3, q=np.radians(num(cols)),
        wrench=num(["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]),
        seam=num(["seam_x_mm", "seam_y_mm", "seam_z_mm"]) * 1e-3)


def tolerated_from_record(rec: dict[str, Any]) -> float:
    """The verified tolerated force uncertainty of a ``plan.json`` record.

    ``tolerated_force_uncertainty`` when the record has it; otherwise from the per-waypoint
    margins and worst cases (the worst case is linear in the uncertainty u: tolerated =
    u min_k margin_k / worst_k).
    """
    v = rec.get("tolerated_force_uncertainty")
    if isinstance(v, int | float) and not isinstance(v, bool):
        return float(v)
    if v is None and "tolerated_force_uncertainty" in rec:
        return float("inf")  # strict JSON writes inf as null
    u = float(rec.get("force_uncertainty", 0.0) or 0.0)
    wp = rec.get("waypoints") or {}
    m = np.asarray(wp.get("margin_mm", []), dtype=float)
    w = np.asarray(wp.get("worst_case_mm", []), dtype=float)
    if u <= 0 or m.size == 0 or m.size != w.size:
        return float("nan")
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(w > 0, np.maximum(m, 0.0) * u / w, np.inf)
    return float(np.min(r))


# --------------------------------------------------------------------------------------------
# Building the program


def build_program(
    robot: Robot, samples: Samples, header: ProgramHeader, path_tol: float = 1e-5,
    angle_tol: float = math.radians(0.01),
) -> Program:
    """Select points, motions and blending from verified samples (see the module docstring).

    Args:
        robot: The robot the plan was made for.
        samples: Its verified samples.
        header: Program header (its ``spacing`` is the point spacing along the seam [m]).
        path_tol: Largest distance of a verified sample from the programmed line [m].
        angle_tol: Largest orientation difference of a sample from the programmed slerp [rad].
    """
    if header.spacing <= 0:
        raise InputError("--export-spacing-mm", "", f"got {header.spacing * 1e3:g}", "> 0")
    T = robot.batch_fk_jacobian(samples.q)[0]
    conv = robot.description.convention
    tool = np.linalg.inv(conv.flange) @ robot.description.tool
    work = _work_frame(samples, T, conv.base)
    to_work = np.linalg.inv(conv.base @ work)
    P = to_work[None] @ T  # TCP in the work frame, (N, 4, 4)

    keep = _anchor_points(samples, header.spacing)
    keep = _refine(P, keep, path_tol, angle_tol)
    idx = np.array(sorted(keep), dtype=int)
    motions = _motions(samples, P, idx, path_tol)
    return Program(header, robot, idx, samples.subset(idx), tool, work, P[idx],
                   tuple(motions), samples)


def _work_frame(samples: Samples, T: FloatArray, base: FloatArray) -> FloatArray:
    """Seam frame (see the module docstring) in the controller's base frame, (4, 4)."""
    weld = np.flatnonzero(np.isin(samples.phase, WELD_PHASES))
    contact = np.flatnonzero(np.isin(samples.phase, CONTACT_PHASES))
    if weld.size == 0 or contact.size == 0:
        raise InputError("waypoints.csv", "phase", "no welding samples",
                         "a plan with plunge, dwell and weld")
    o = samples.seam[weld[0]]
    far = np.linalg.norm(samples.seam[weld] - o, axis=1)
    x = samples.seam[weld[int(np.argmax(far))]] - o
    z = -T[contact[0], :3, 2]
    if np.linalg.norm(x) < 1e-9:
        x = T[contact[0], :3, 0]
    x = x - z * (x @ z)
    x /= np.linalg.norm(x)
    z /= np.linalg.norm(z)
    W = np.eye(4)
    W[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    W[:3, 3] = o
    return np.asarray(np.linalg.inv(base) @ W)


def _anchor_points(samples: Samples, spacing: float) -> set[int]:
    """First sample, last sample of every phase, samples nearest to k * spacing while welding."""
    n = len(samples)
    keep = {0, n - 1}
    ph = samples.phase
    ends = np.flatnonzero(ph[:-1] != ph[1:])
    keep |= {int(i) for i in ends}
    weld = np.flatnonzero(np.isin(ph, WELD_PHASES))
    if weld.size:
        s = samples.s[weld]
        for target in np.arange(0.0, s[-1] + 0.5 * spacing, spacing):
            keep.add(int(weld[int(np.argmin(np.abs(s - target)))]))
    return keep


def _deviation(P: FloatArray, i: int, j: int) -> tuple[FloatArray, FloatArray]:
    """Position distance [m] and orientation angle [rad] of samples i..j from the LIN i -> j."""
    p = P[i:j + 1, :3, 3]
    a, b = p[0], p[-1]
    d = b - a
    L2 = float(d @ d)
    f = np.clip(((p - a) @ d) / L2, 0.0, 1.0) if L2 > 0 else np.linspace(0.0, 1.0, len(p))
    pos = np.linalg.norm(p - (a + f[:, None] * d), axis=1)
    R = Rotation.from_matrix(P[[i, j], :3, :3])
    slerp = Slerp([0.0, 1.0], R)
    ang = (slerp(f).inv() * Rotation.from_matrix(P[i:j + 1, :3, :3])).magnitude()
    return pos, ang


def _refine(P: FloatArray, keep: set[int], tol: float, ang_tol: float) -> set[int]:
    """Douglas-Peucker on position and orientation between the kept samples."""
    out = set(keep)
    stack = list(zip(sorted(keep)[:-1], sorted(keep)[1:], strict=True))
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        pos, ang = _deviation(P, i, j)
        excess = np.maximum(pos / tol, ang / ang_tol)
        k = int(np.argmax(excess))
        if excess[k] > 1.0:
            m = i + k
            out.add(m)
            stack += [(i, m), (m, j)]
    return out


def _motions(samples: Samples, P: FloatArray, idx: NDArray[np.int_],
             tol: float) -> list[Motion]:
    motions = [Motion("ptp", 0, str(samples.phase[idx[0]]))]
    seg = np.linalg.norm(np.diff(P[idx, :3, 3], axis=0), axis=1)
    for k in range(1, len(idx)):
        i, j = idx[k - 1], idx[k]
        phase = str(samples.phase[j])
        dt = float(samples.t[j] - samples.t[i])
        ang = (Rotation.from_matrix(P[i, :3, :3]).inv()
               * Rotation.from_matrix(P[j, :3, :3])).magnitude()
        if seg[k - 1] < STILL_POS and ang < STILL_ANG:
            motions.append(Motion("wait", k, phase, duration=dt))
            continue
        speed = seg[k - 1] / dt if dt > 0 else 0.0
        blend = 0.0
        nxt = k + 1 < len(idx) and str(samples.phase[idx[k + 1]]) in WELD_PHASES
        if phase in WELD_PHASES and str(samples.phase[i]) in WELD_PHASES and nxt:
            d0, d1 = P[j, :3, 3] - P[i, :3, 3], P[idx[k + 1], :3, 3] - P[j, :3, 3]
            n0, n1 = float(np.linalg.norm(d0)), float(np.linalg.norm(d1))
            if n0 > STILL_POS and n1 > STILL_POS:
                theta = math.acos(float(np.clip(d0 @ d1 / (n0 * n1), -1.0, 1.0)))
                cap = 0.4 * min(n0, n1)
                blend = cap if theta < 1e-9 else min(cap, 2 * tol / math.sin(theta / 2))
        motions.append(Motion("lin", k, phase, speed=speed, duration=dt, blend=blend))
    return motions
