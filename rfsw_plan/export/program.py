"""A controller program, independent of the vendor language: points, motions, frames, hooks.

The program is built from the *verified samples* of a written plan (``waypoints.csv``, every
row checked by the planner before it was written): every program point is one of those
samples, never an interpolation, so each point is a pose the plan verified.

Points (:func:`build_program`):

* the first sample (the approach point, a *joint target*: PTP to an E6AXIS, J to a
  joint-defined P[], MoveAbsJ, so no posture flag can send the robot another way), the last
  sample of every phase, and in the welding phases (``accelerate``, ``weld``, ``decelerate``)
  the sample nearest to every multiple of the export spacing along the seam (default the
  plan's waypoint spacing: the planned fake targets);
* then, between two neighbouring points, the sample farthest from the straight line the
  controller will run (position distance to the chord, orientation angle to the slerp at the
  same fraction) is added while it is farther than ``path_tol / 2`` (Douglas-Peucker): half
  the path tolerance for the chords, half for the blending below; over the end stop, where
  the TCP follows the forces' relaxation in time, the sample farthest from the chord's point
  at the same share of the segment's *time* (a LIN runs at one speed).

Motions: a linear move to every point after the first, with the speed that keeps the plan's
time on that segment (chord length / planned duration); a segment over which the pose does not
change (below 1 um and 0.001 deg) is a wait for its planned duration. No move or wait is
shorter than the controller's interpolation cycle (``min_move``, the format's
:attr:`~rfsw_plan.export.format.ControllerFormat.cycle`): the speed split cuts at least a
cycle apart (:func:`_cycle_cuts`) and a shorter move or hold left over is merged into its
neighbour (:func:`_at_least_one_cycle`).

Blending (:func:`blend_distance`), the model of every vendor's approximation used here: the
controller leaves the programmed polyline at most ``d`` before a blended point and rejoins it
at most ``d`` after it, and the rounded contour stays inside the triangle (entry, point,
exit). KUKA documents ``$APO.CDIS`` as that distance (KSS 8 expert programming, "approximate
positioning"), ABB ``zonedata.pzone_tcp`` as the zone radius around the point (RAPID
reference, zonedata). A contour inside the triangle is at most ``d sin(theta) / 2`` from the
polyline (theta the direction change), so ``d = 2 (tol - dev) / sin(theta)`` (capped at 0.4 of
the shorter segment) keeps every verified sample within ``tol`` of the path the controller
runs, where ``dev`` is the samples' largest distance from the two chords
(:func:`path_deviation` checks it sample by sample). FANUC's ``CNT`` rounds a corner by an
amount that depends on speed and acceleration, with no published bound; FANUC programs use
the corner region ``CRy`` instead, whose documented distance fits this model
(:mod:`rfsw_plan.export.fanuc_tp`). Blending is allowed between two segments
inside the plunge, the dwell or the welding phases, so the plunge and the dwell are not a
chain of exact stops; the robot stops exactly where the pin touches down, at the end of the
dwell and at the end of the weld (the retract starts from the planned spot).

Frames: the tool is the planned TCP in the controller's flange frame (KUKA FLANGE, FANUC
faceplate, ABB tool0); the work object (KUKA BASE, FANUC user frame, ABB wobjdata) is the
*plate's* frame in the controller's base frame: origin on the plate's top surface, the plunge
depth above the first weld sample's seam point (the seam is the pin tip's path), x along the
seam (towards its farthest weld point), z the surface normal there (out of the plate),
y = z x x. Every point's Z is its height above the surface (the pin sits at -depth in the
weld). The tool's tilt is in the points, so a base taught with three points on the plate
(origin, +x along the seam, +y on the plate) is this frame, and the depth of the pin along
the whole seam follows it.

Process hooks (:class:`Hooks`), placed by the *predicted pin* (the commanded TCP plus the
model's process deflection, :func:`pin_heights`), never by the commanded TCP: ``home_start``
before the first move, ``spindle_start`` before the plunge (the tip the spindle clearance
above the surface), ``force_on`` at contact, ``force_off`` after the last weld move (the pin
still in), ``spindle_stop`` after the first retract move whose target has the tip clear of the
surface by the spindle clearance, ``home_end`` at the end (the cell's home position is not
known to the plan). By default they are comments that say what belongs there; each starts
with a ``hook <name>`` marker comment (``rfsw-plan check`` finds it by that).
"""

from __future__ import annotations

import hashlib
import itertools
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.numfmt import fixed
from rfsw_plan.planfiles.folder import PlanSamples
from rfsw_plan.planning.verify import CONTACT_PHASES
from rfsw_plan.robot.description import Payload
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: The verified samples of a plan (the plan-folder reader's type).
Samples = PlanSamples

#: Phases in which the pin travels along the seam.
WELD_PHASES = ("accelerate", "weld", "decelerate")
#: Phases inside which blending is allowed (between two segments of the same group).
BLEND_GROUPS = {"plunge": "plunge", "dwell": "dwell", "accelerate": "weld", "weld": "weld",
                "decelerate": "weld", "stop": "stop", "retract": "retract"}
#: Phase names in program order.
PHASES = ("approach", "plunge", "dwell", "accelerate", "weld", "decelerate", "stop",
          "retract")
#: Below these a segment does not move [m], [rad]: it is a wait.
STILL_POS = 1e-6
#: The resolution of the positions every format writes [m] (mm with 4 decimals), and the length
#: below which a move's speed is taken from its ends as written [m] (at 0.1 mm the rounding of
#: its ends reaches 0.17 % of its length, a tenth of the 2 % timing tolerance of ``check``).
WRITTEN_POSITION = 1e-7
SHORT_MOVE = 1e-4
STILL_ANG = math.radians(1e-3)
#: Largest blend distance as a share of the shorter neighbouring segment.
BLEND_SHARE = 0.4
#: Hook names in the order they occur.
HOOKS = ("home_start", "spindle_start", "force_on", "force_off", "spindle_stop", "home_end")
#: A commanded TCP speed that differs from the predicted pin's by more than this share gets a
#: comment saying why (deflection compensation), so no programmer "fixes" it.
SPEED_NOTE = 0.05


@dataclass(frozen=True)
class Hooks:
    """Process hooks: per hook name, per format name, the lines to insert (vendor text).

    A hook without lines for a format gets that format's default comment, which says exactly
    what belongs there (:attr:`ControllerFormat` writers' ``DEFAULT_HOOKS``).
    """

    lines: dict[str, dict[str, tuple[str, ...]]] = field(default_factory=dict)

    def get(self, hook: str, fmt: str) -> tuple[str, ...] | None:
        """The user's lines of ``hook`` for format ``fmt``, or None (use the default)."""
        return self.lines.get(hook, {}).get(fmt)

    def render(self, hook: str, fmt: str, default: tuple[str, ...], indent: str,
               comment: str) -> list[str]:
        """The program lines of ``hook``: a marker comment ``hook <name>`` (``rfsw-plan check``
        finds the hook by it), then the user's lines, indented, or else the format's default
        text as comment lines (``indent + comment + " " + text``)."""
        user = self.get(hook, fmt)
        mark = f"{indent}{comment} hook {hook}"
        if user is not None:
            return [mark, *(indent + x for x in user)]
        return [mark, *(f"{indent}{comment} {x}" for x in default)]


def read_hooks(path: str | Path) -> Hooks:
    """Read a hooks file: a TOML table per hook with a list of lines per format, e.g.::

        [spindle_start]
        krl = ["$OUT[1] = TRUE", "WAIT FOR $IN[1]"]
        rapid = ["SetDO doSpindle, 1;", "WaitDI diSpindleAtSpeed, 1;"]

    Raises:
        InputError: Not TOML, an unknown hook, or lines that are not a list of strings.
    """
    p = Path(path)
    try:
        data = tomllib.loads(p.read_bytes().decode("utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(p, "", f"not a readable TOML file ({exc})", "a hooks file") from None
    out: dict[str, dict[str, tuple[str, ...]]] = {}
    for hook, per in data.items():
        if hook not in HOOKS or not isinstance(per, dict):
            raise InputError(p, hook, "unknown hook", ", ".join(HOOKS))
        out[hook] = {}
        for fmt, lines in per.items():
            if not isinstance(lines, list) or not all(isinstance(x, str) and "\n" not in x
                                                      for x in lines):
                raise InputError(p, f"{hook}.{fmt}", "not a list of one-line strings",
                                 '["line 1", "line 2"]')
            out[hook][fmt] = tuple(lines)
    return Hooks(out)


@dataclass(frozen=True)
class ProgramOptions:
    """What the programmer chooses for the controller.

    By default a program leaves the cell's numbered data alone: KRL sets ``$TOOL``, ``$BASE``
    and ``$LOAD`` from its own values (they act for this run only), FANUC selects the user
    frame and tool frame by number (``UFRAME_NUM``, ``UTOOL_NUM``) and lists the values to
    enter, RAPID uses its module-local data. ``cell_data`` writes them into the controller's
    numbered data instead (KUKA ``TOOL_DATA[n]``, ``BASE_DATA[n]``, ``LOAD_DATA[n]``; FANUC
    ``UFRAME[n]``, ``UTOOL[n]`` through ``PR[91]``/``PR[92]`` and ``PAYLOAD[n]``), which
    persist and replace what the cell had taught there; the header says so.

    Attributes:
        tool_number: Tool number (KUKA TOOL_DATA[n], FANUC UTOOL n; RAPID uses a named tool).
        base_number: Base number (KUKA BASE_DATA[n], FANUC UFRAME n; RAPID a named wobjdata).
        hooks: The process hooks.
        cell_data: Write the tool, base and load into the cell's numbered data (above).
        speed_register: FANUC numeric register the TP sets before a move whose speed is not
            a whole mm/sec (``R[n]=v`` then ``L P[k] R[n]mm/sec``).
    """

    tool_number: int = 1
    base_number: int = 1
    hooks: Hooks = field(default_factory=Hooks)
    cell_data: bool = False
    speed_register: int = 20


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
        robot_sha256: Hex SHA-256 of that file's bytes (``""`` without a file).
        version: rfsw-plan version that wrote the program.
        tolerated_uncertainty: Verified tolerated relative force uncertainty (inf: unbounded).
        requested_uncertainty: Relative force uncertainty the plan was asked to hold.
        window_mm: Weld window (lower, upper) [mm].
        path_tol: Path tolerance of the program [m].
        spacing: Point spacing along the seam [m].
        notes: Extra lines: what the tool cannot know and the programmer must check.
        set_force: The axial set force of a force-controlled plan [N] (``plan.json``
            ``envelope.set_force_N``); 0: the plan is in position control.
        plan_tolerated: NaN, or the plan's own tolerated uncertainty when
            ``tolerated_uncertainty`` is the lower level this program holds as its controller
            runs it (:func:`rfsw_plan.export.check.judge_program`), limited by ``held_by``.
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
    notes: tuple[str, ...] = ()
    set_force: float = 0.0
    plan_tolerated: float = math.nan
    held_by: str = ""

    def lines(self) -> list[str]:
        """Header lines (without comment markers), the same for every vendor."""
        tol = self.tolerated_uncertainty
        tol_s = "unbounded" if not math.isfinite(tol) else f"+-{100 * tol:.3g} %"
        if not math.isnan(self.plan_tolerated):  # the program as run holds less than the plan
            tol_s += (f" as this program runs ({self.held_by} first; the plan's samples hold "
                      f"+-{100 * self.plan_tolerated:.3g} %)")
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
            "Z of every point is its height above the plate surface (the pin tip sits at "
            "-depth in the weld)",
            ("axial control: FORCE, set force "
             f"{self.set_force:.0f} N along the tool axis (force-control hooks)"
             if self.set_force > 0 else "axial control: position (no force control)"),
            *self.notes,
        ]

    def comments(self, marker: str, max_len: int | None = None,
                 extra: list[str] | tuple[str, ...] = ()) -> list[str]:
        """The header (and ``extra`` lines) as comment lines of a vendor language.

        Args:
            marker: Text before each line, e.g. ``"; "`` (KRL), ``"  ! "`` (RAPID).
            max_len: Longest line text (without the marker); a longer line continues on
                the next ones, indented by two spaces, so nothing is lost. None: no limit.
            extra: Format-specific lines (set-up steps, warnings) after the header.
        """
        out = []
        for line in [*self.lines(), *extra]:
            while max_len is not None and len(line) > max_len:
                cut = line.rfind(" ", 20, max_len)
                cut = max_len if cut < 0 else cut
                out.append(marker + line[:cut])
                line = "  " + line[cut:].lstrip()
            out.append(marker + line)
        return out


def controller_name(name: str, *, max_len: int, prefix: str, upper: bool = False) -> str:
    """A program or module name a controller accepts, unique for every ``name``.

    Every character other than a letter, digit or underscore becomes ``_``; a name that does
    not start with a letter gets ``prefix``. A longer name than ``max_len`` is cut and ends
    with ``_`` and four hex digits of the SHA-256 of ``name`` (KRL's 24 characters would
    otherwise give ``fanuc_laser_1400mm_yminus`` and ``_yplus`` one name).
    """
    n = re.sub(r"[^A-Z0-9_]" if upper else r"[^A-Za-z0-9_]", "_",
               name.upper() if upper else name)
    if not n[:1].isalpha():
        n = prefix + n
    if len(n) > max_len:
        h = hashlib.sha256(name.encode("utf-8")).hexdigest()[:4]
        n = f"{n[:max_len - 5].rstrip('_')}_{h.upper() if upper else h}"
    return n


@dataclass(frozen=True)
class Motion:
    """One program instruction.

    Attributes:
        kind: ``joint`` (joint move to a joint target), ``lin`` (linear move), ``wait``, or
            ``hook`` (process lines, see :class:`Hooks`).
        point: Index into :attr:`Program.points` (the target; for ``wait``, the point held).
        phase: Phase of the motion (of its target point).
        speed: TCP speed of a ``lin`` [m/s].
        duration: Planned duration of the segment or wait [s].
        blend: Blend distance at the target [m] (0: exact stop).
        hook: The hook's name (``kind == "hook"``).
        pin_speed: The predicted pin's speed over the segment [m/s] when it differs from
            the commanded ``speed`` by more than :data:`SPEED_NOTE` (the writers then say
            why before the motion: :func:`speed_note`), else None.
    """

    kind: str
    point: int
    phase: str
    speed: float = 0.0
    duration: float = 0.0
    blend: float = 0.0
    hook: str = ""
    pin_speed: float | None = None


@dataclass(frozen=True)
class Program:
    """A vendor-neutral controller program.

    Attributes:
        header: The header.
        robot: The robot (kinematics, controller convention).
        sample_index: Index of each point's sample in the plan's samples, (P,).
        samples: The program points' samples (joint values, phases...), length P.
        tool: TCP in the controller's flange frame [m], (4, 4).
        work: Work object (the plate frame) in the controller's base frame [m], (4, 4).
        poses: TCP of every point in the work object frame [m], (P, 4, 4).
        motions: The instructions, in order.
        all_samples: Every verified sample (for the stream and the path checks).
        payload: The tool's load (None: unknown, the header says so).
        options: Tool/base numbers and hooks.
        stream: The samples of a stream file at the controller cycle (None: the plan's).
        cycle: The stream's controller cycle [s].
        build_args: The arguments of :func:`build_program` that made it (for
            :meth:`rebuilt`).
        pin_height: The predicted pin tip's height above the plate surface at every plan
            sample [m], (N,) (:func:`pin_heights`; the hooks are placed by it).
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
    payload: Payload | None = None
    options: ProgramOptions = field(default_factory=ProgramOptions)
    stream: Samples | None = field(default=None, repr=False)
    cycle: float = 0.0
    build_args: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    pin_height: FloatArray | None = field(default=None, repr=False, compare=False)

    def rebuilt(self, extra: frozenset[int]) -> Program:
        """The same program with the samples ``extra`` as points too (the same frames and
        options; :func:`build_program` with the arguments this one was built with)."""
        if not self.build_args:
            raise ValueError("a program not made by build_program cannot be rebuilt")
        return build_program(**self.build_args, extra=extra)

    def phase_changes(self) -> dict[int, str]:
        """Motion index -> phase, where a new phase starts (for the phase marks)."""
        out: dict[int, str] = {}
        last = ""
        for i, m in enumerate(self.motions):
            if m.kind == "hook":
                continue
            if m.phase != last:
                out[i] = m.phase
                last = m.phase
        return out

    def moved_points(self) -> NDArray[np.int_]:
        """Indices of the points a motion moves to (a wait or hook holds the previous one)."""
        return np.array([m.point for m in self.motions if m.kind in ("joint", "lin")],
                        dtype=int)

    def base_pose(self, pose_work: FloatArray) -> FloatArray:
        """TCP pose(s) in the work object frame -> the description's base frame [m]."""
        conv = self.robot.description.convention
        return np.asarray(conv.base @ self.work @ pose_work)

    def force_ramp(self) -> tuple[float, float]:
        """The axial set force [N] (0: position control) and the time [s] over which the
        force-control hook ramps it from 0, from contact to the end of the plunge (the
        plunge is a force ramp under force control)."""
        f = self.header.set_force
        h, ph, t = self.pin_height, self.all_samples.phase, self.all_samples.t
        plunge = np.flatnonzero(ph == "plunge")
        if f <= 0 or h is None or plunge.size == 0:
            return f, 0.0
        touch = plunge[h[plunge] <= 0.0]
        start = int(touch[0]) if touch.size else int(plunge[0])
        return f, float(t[plunge[-1]] - t[start])

    def hook_notes(self, fmt: str) -> list[str]:
        """Header lines that say where the spindle I/O and the force control are set for the
        format ``fmt``: in this program (the user's hooks) or still to be written at the hook
        comments."""
        h = self.options.hooks
        spindle = all(h.get(k, fmt) for k in ("spindle_start", "spindle_stop"))
        out = ["SPINDLE I/O: set in this program (hooks file)" if spindle else
               "SPINDLE I/O: NOT in this program: write it in the comments of the spindle "
               "start and stop hooks"]
        f, ramp = self.force_ramp()
        if f > 0:
            force = all(h.get(k, fmt) for k in ("force_on", "force_off"))
            out.append(f"FORCE CONTROL ({f:.0f} N axial, ramp {ramp:.2f} s over the plunge): "
                       + ("set in this program (hooks file)" if force else
                          "NOT in this program: write it at the force-control on and off "
                          "hook comments"))
        return out

    def maker_note(self, maker: str) -> list[str]:
        """One warning line when the robot's maker is not ``maker`` (empty otherwise)."""
        own = self.robot.description.convention.maker
        if not maker or own.upper() == maker.upper():
            return []
        return [f"WARNING: robot {self.robot.name} is not a {maker} robot "
                f"({own or 'maker not stated'}): check axis directions, frames and limits "
                "on the real controller before running"]


# --------------------------------------------------------------------------------------------
# Building the program


def build_program(
    robot: Robot, samples: Samples, header: ProgramHeader, path_tol: float = 1e-5,
    angle_tol: float = math.radians(0.01), normal: FloatArray | None = None,
    payload: Payload | None = None, options: ProgramOptions | None = None,
    stream: Samples | None = None, cycle: float = 0.0, extra: frozenset[int] = frozenset(),
    depth: float = 0.0, pin: FloatArray | None = None, min_move: float = 0.0,
) -> Program:
    """Select points, motions, blending and hooks from verified samples (module docstring).

    Args:
        robot: The robot the plan was made for.
        samples: Its verified samples.
        header: Program header (its ``spacing`` is the point spacing along the seam [m]).
        path_tol: Largest distance of a verified sample from the path the controller runs [m].
        angle_tol: Largest orientation difference of a sample from the programmed slerp [rad].
        normal: The plate's surface normal at the first weld point, base frame, (3,). None:
            the plane through the weld seam points if they span one, else the tool axis at
            touch-down (the header then says the work object's z is not the plate normal).
        payload: The tool's load for the controller (None: the header says it is unknown).
        options: Tool/base numbers and hooks.
        stream: Samples of the stream file (default: ``samples``).
        cycle: Stream cycle [s] (default: the samples' step).
        extra: Sample indices that are points too (a format that needs shorter segments:
            :func:`rfsw_plan.export.fanuc_tp.tp_program`).
        depth: The pin's plunge depth [m]: the seam points lie this far below the plate
            surface, so the work object's origin is this far above the first weld sample's
            seam point, on the surface.
        pin: The predicted (loaded) pin tip of every sample, base frame [m], (N, 3): the
            TCP plus the model's process deflection (``waypoints.csv`` x + dx). None: the
            TCP (no deflection known). The hooks are placed by it (:func:`_with_hooks`).
        min_move: The shortest move or wait the controllers run as written [s] (their
            interpolation cycle, :attr:`ControllerFormat.cycle`): no two points closer in
            plan time (:func:`_speed_refine` cuts at least this far apart,
            :func:`_at_least_one_cycle` merges what is left). 0: no minimum.
    """
    args = dict(robot=robot, samples=samples, header=header, path_tol=path_tol,
                angle_tol=angle_tol, normal=normal, payload=payload, options=options,
                stream=stream, cycle=cycle, depth=depth, pin=pin, min_move=min_move)
    if header.spacing <= 0:
        raise InputError("export_spacing", "", f"got {header.spacing * 1e3:g}", "> 0")
    T = sample_fk(robot, samples.q)
    conv = robot.description.convention
    tool = np.linalg.inv(conv.flange) @ robot.description.tool
    work, notes = work_frame(samples, T, conv.base, normal, depth)
    to_work = np.linalg.inv(conv.base @ work)
    P = to_work[None] @ T  # TCP in the work frame, (N, 4, 4)
    h = pin_heights(samples, T[:, :3, 3] if pin is None else pin, (conv.base @ work)[:3, 2],
                    depth)

    hooks = _hook_points(samples, h)
    keep = _anchor_points(samples, header.spacing) | hooks
    keep = _refine(P, keep | {int(i) for i in extra}, 0.5 * path_tol, angle_tol)
    keep = _timed_refine(P, samples.t, keep, np.flatnonzero(samples.phase == "stop"),
                         0.5 * path_tol)
    keep = _speed_refine(P, samples, keep, np.asarray(to_work[:3, :3], dtype=float),
                         min_move)
    idx = _without_stops(samples, P, np.array(sorted(keep), dtype=int))
    idx = _at_least_one_cycle(samples, idx, min_move, hooks)
    motions = _motions(samples, P, idx, path_tol, T[:, :3, 3] if pin is None else pin)
    motions = _with_hooks(motions, idx, h, samples)
    if payload is None:
        notes.append("PAYLOAD UNKNOWN: the robot file has no [payload] table and no "
                     "payload_gravity effect; enter the spindle's load on the controller")
    else:
        if payload_assumed(payload):
            notes.append(f"PAYLOAD ASSUMED (robot file: {payload.source}): check the "
                         "spindle's mass and centre of mass before running")
        if payload.inertia is None:
            notes.append("PAYLOAD INERTIA UNKNOWN: written as 0; identify it on the "
                         "controller (load identification)")
    header = ProgramHeader(**{**header.__dict__, "notes": (*header.notes, *notes)})
    if stream is None:
        stream = samples
        cycle = cycle or float(np.median(np.diff(samples.t)))
    return Program(header, robot, idx, samples.subset(idx), tool, work, P[idx],
                   tuple(motions), samples, payload, options or ProgramOptions(), stream,
                   cycle, args, h)


def payload_assumed(payload: Payload) -> bool:
    """Are any of the payload's values an assumption (its source says ``ASSUMED``)?"""
    return "ASSUMED" in payload.source.upper()


def plate_frame(origin: FloatArray, toward: FloatArray, normal: FloatArray) -> FloatArray:
    """The plate frame (4, 4): origin, x towards ``toward`` projected on the plate, z = normal.

    Args:
        origin: First weld point, (3,) [m].
        toward: A point farther along the seam, (3,) [m].
        normal: Surface normal (out of the plate), (3,).
    """
    z = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    x = np.asarray(toward, dtype=float) - origin
    x = x - z * (x @ z)
    if np.linalg.norm(x) < 1e-9:
        raise InputError("seam", "", "the seam runs along the surface normal",
                         "a seam on the plate")
    x /= np.linalg.norm(x)
    W = np.eye(4)
    W[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    W[:3, 3] = origin
    return W


def work_frame(samples: Samples, T: FloatArray, base: FloatArray,
               normal: FloatArray | None, depth: float = 0.0) -> tuple[FloatArray, list[str]]:
    """The plate frame in the controller's base frame (origin on the surface, ``depth``
    above the first weld sample's seam point along the normal), and notes for the header."""
    weld = np.flatnonzero(np.isin(samples.phase, WELD_PHASES))
    contact = np.flatnonzero(np.isin(samples.phase, CONTACT_PHASES))
    if weld.size == 0 or contact.size == 0:
        raise InputError("waypoints.csv", "phase", "no welding samples",
                         "a plan with plunge, dwell and weld")
    o = samples.seam[weld[0]]
    far = samples.seam[weld[int(np.argmax(np.linalg.norm(samples.seam[weld] - o, axis=1)))]]
    tool_axis = -T[contact[0], :3, 2]
    notes: list[str] = []
    if normal is None:
        normal = _fitted_normal(samples.seam[weld])
        if normal is None:
            normal = tool_axis
            notes.append("WORK OBJECT z IS THE TOOL AXIS at touch-down, not a known plate "
                         "normal: do not re-teach it on the plate")
    normal = np.asarray(normal, dtype=float)
    if normal @ tool_axis < 0:
        normal = -normal
    if np.linalg.norm(far - o) < 1e-9:
        far = o + T[contact[0], :3, 0]
    n = normal / np.linalg.norm(normal)
    return np.asarray(np.linalg.inv(base) @ plate_frame(o + depth * n, far + depth * n,
                                                      normal)), notes


def _fitted_normal(points: FloatArray) -> FloatArray | None:
    """Normal of the plane through points (m, 3) if they span one (not a line), else None."""
    c = points - points.mean(axis=0)
    if len(points) < 3:
        return None
    _, sv, vt = np.linalg.svd(c, full_matrices=False)
    if sv[1] < 1e-6 * max(sv[0], 1e-12) or sv[1] < 1e-4:
        return None
    return np.asarray(vt[2])


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
        targets = np.arange(0.0, s[-1] + 0.5 * spacing, spacing)
        pos = np.clip(np.searchsorted(s, targets), 1, len(s) - 1)
        nearest = np.where(np.abs(s[pos - 1] - targets) <= np.abs(s[pos] - targets), pos - 1,
                           pos)
        keep |= {int(weld[k]) for k in nearest}
    return keep


def _timed_refine(P: FloatArray, t: FloatArray, keep: set[int], rows: NDArray[np.int_],
                  tol: float) -> set[int]:
    """Douglas-Peucker in time over ``rows`` (the end stop, with the sample before it): a
    segment is split where a sample is farther than ``tol`` [m] from the chord's point at the
    same share of the segment's *time*, since the controller runs a LIN at one speed and the
    end stop's TCP follows the forces' relaxation (fast first, then slower): one LIN over the
    stop put the pin up to 0.5 mm off the spot where it stands (zk500_table6_seam)."""
    if not len(rows):
        return keep
    out = set(keep)
    lo, hi = max(int(rows[0]) - 1, 0), int(rows[-1])
    out |= {lo, hi}
    inside = sorted(i for i in out if lo <= i <= hi)
    stack = list(itertools.pairwise(inside))
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        f = (t[i:j + 1] - t[i]) / (t[j] - t[i])
        a, b = P[i, :3, 3], P[j, :3, 3]
        dev = np.linalg.norm(P[i:j + 1, :3, 3] - (a + f[:, None] * (b - a)), axis=1)
        k = int(np.argmax(dev))
        if dev[k] > tol:
            out.add(i + k)
            stack += [(i, i + k), (i + k, j)]
    return out


#: Largest change a LIN's chord may make to the pin's speed along the seam, against the plan's
#: TCP path [share of the weld speed] (:func:`_speed_refine`). Douglas-Peucker bounds the
#: chord's distance from the path (path_tol / 2), not how fast that distance changes: on
#: zk500_table6_seam a 5 um bulge over a 0.13 s segment of the weld-start acceleration swung
#: the pin's speed by -2.8 / +2.3 % of the weld speed, and the program as run held +-5.65 %
#: force uncertainty against the plan's +-7.24 %. Measured on the bundled plans (KRL and TP,
#: as run by ``rfsw-plan check``): 1 % left fanuc_butt_1700mm's programs at +-2.47 / 2.42 %
#: against the plan's +-2.83 % (its speed claim has the least slack: a nominal change of 1 %
#: of the weld speed costs it 0.6 points), 0.5 % at +-2.73 %, 0.25 % at +-2.77 %, 0.1 % holds
#: the claim on both (split at the bulge's apex: zk500 96 -> 206 KRL points, fanuc 144 ->
#: 192). The moves it makes can be one 10 ms sample long (fanuc's weld start, where the
#: claim's slack is smallest): a shortest move of 20 ms left fanuc's programs at +-2.62 %
#: (apex splits), +-2.73 % with :func:`_cycle_cuts`' minimax cuts, which the KRL and RAPID
#: programs need (12 ms cycle: ``check`` fails them on the three FANUC plans; the TP, 8 ms,
#: keeps the 10 ms moves and holds).
SPEED_SPLIT = 0.001


def _speed_refine(P: FloatArray, samples: Samples, keep: set[int], to_work: FloatArray,
                  min_move: float = 0.0) -> set[int]:
    """Split the travel's segments (accelerate, weld, decelerate) where the chord changes
    the TCP's speed along the seam by more than :data:`SPEED_SPLIT` of the weld speed: the
    TCP on the chord at the fraction nearest to the plan's (as the controller runs a LIN, see
    :func:`rfsw_plan.export.check.run_as_controller`) differs from the plan's by w, and its
    speed along the seam by d(a . w)/dt, a the direction the seam point moves (work frame,
    ``to_work`` the base-to-work rotation). Split at the largest a . w, until no change
    exceeds it. A cut leaves at least ``min_move`` [s] of plan time on either side (the
    controller's interpolation cycle: the apex among the samples that do; a segment shorter
    than two cycles is not cut). Each segment's verdict is remembered for the same poses,
    samples, frame and ``min_move`` (:func:`_segment_memo`): a rebuilt program judges only the
    segments it has not seen."""
    rows = np.flatnonzero(np.isin(samples.phase, WELD_PHASES))
    if len(rows) < 3:
        return keep
    inputs = hashlib.blake2b(digest_size=16)
    for x in (samples.seam, samples.t, samples.s, to_work):
        inputs.update(np.ascontiguousarray(x, dtype=float).tobytes())
    memo = _segment_memo(P, "speed " + inputs.hexdigest(), SPEED_SPLIT, min_move)
    r0, r1 = int(rows[0]), int(rows[-1])
    t = samples.t
    a = np.gradient(np.asarray(samples.seam, float)[r0:r1 + 1], t[r0:r1 + 1], axis=0)
    n = np.linalg.norm(a, axis=1, keepdims=True)
    a = np.where(n > 0, a / np.maximum(n, 1e-300), 0.0) @ to_work.T
    limit = SPEED_SPLIT * float(np.max(np.gradient(samples.s[r0:r1 + 1], t[r0:r1 + 1])))
    out = set(keep) | {r0, r1}

    def change(i: int, j: int) -> tuple[FloatArray, FloatArray]:
        """a . w over the chord i -> j [m] and its rate [m/s]."""
        _, f = _chord_fraction(P, i, j)
        p0, p1 = P[i, :3, 3], P[j, :3, 3]
        w = P[i:j + 1, :3, 3] - (p0 + f[:, None] * (p1 - p0))
        along = np.einsum("ki,ki->k", a[i - r0:j - r0 + 1], w)
        return along, np.gradient(along, t[i:j + 1])

    stack = list(itertools.pairwise(sorted(i for i in out if r0 <= i <= r1)))
    if min_move > 0:
        for i, j in stack:
            if j - i >= 2:
                if (i, j) not in memo:
                    memo[i, j] = _cycle_cuts(
                        change, t, i, j, limit, min_move,
                        lambda i, j: _window_rates(P, a[i - r0:j - r0 + 1], t, i, j,
                                                   CUT_SAMPLES))
                out |= set(memo[i, j])
        return out
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        if (i, j) not in memo:
            along, _ = change(i, j)
            # split at the bulge's apex (as Douglas-Peucker does), not where it changes
            # fastest: that is at the segment's ends, and splitting there cascades into
            # one-sample moves; only where both parts last a cycle at least
            tt = t[i:j + 1]
            ok = (tt - tt[0] >= min_move - 1e-9) & (tt[-1] - tt >= min_move - 1e-9)
            ok[0] = ok[-1] = False
            memo[i, j] = (i + int(np.argmax(np.where(ok, np.abs(along), -1.0)))
                          if ok.any() and np.max(np.abs(np.gradient(along, tt))) > limit
                          else -1)
        m = memo[i, j]
        if m >= 0:
            out.add(m)
            stack += [(i, m), (m, j)]
    return out


def _cycle_cuts(change: Any, t: FloatArray, i: int, j: int, limit: float, min_move: float,
                rates: Any = None) -> tuple[int, ...]:
    """The cuts of segment i..j (samples, times t [s]) into moves of at least ``min_move``
    [s] whose largest speed change (``change(i, j)[1]``, [m/s]) is smallest, and as few moves
    as reach that (a change below ``limit`` counts as ``limit``): a shortest-path search over
    the samples (minimax), each move at most :data:`CUT_SAMPLES` samples long unless the
    segment is kept whole. ``rates(i, j)``, if given, is every move's largest change at once
    (:func:`_window_rates`, the same numbers as ``change``)."""
    worst0 = float(np.max(np.abs(change(i, j)[1])))
    if worst0 <= limit or t[j] - t[i] < 2 * min_move - 1e-9:
        return ()
    n = j - i
    if rates is not None:
        table = rates(i, j)
        return _minimax_cuts(t, i, n, limit, min_move, worst0,
                             lambda m, k: float(table[k, k - m]))
    return _minimax_cuts(t, i, n, limit, min_move, worst0,
                         lambda m, k: float(np.max(np.abs(change(i + m, i + k)[1]))))


def _minimax_cuts(t: FloatArray, i: int, n: int, limit: float, min_move: float,
                  worst0: float, worst: Any) -> tuple[int, ...]:
    """:func:`_cycle_cuts`' search over samples i..i+n; ``worst(m, k)`` the largest speed
    change [m/s] of the move from sample i+m to i+k."""
    best: list[tuple[float, int, int]] = [(0.0, 0, -1)] + [(math.inf, 0, -1)] * n
    for k in range(1, n + 1):
        for m in range(max(0, k - CUT_SAMPLES), k):
            if t[i + k] - t[i + m] < min_move - 1e-9 or best[m][0] == math.inf:
                continue
            e = max(best[m][0], max(limit, worst(m, k)))
            if (e, best[m][1] + 1) < best[k][:2]:
                best[k] = (e, best[m][1] + 1, m)
    if best[n][0] >= max(worst0, limit):
        return ()
    cuts, k = [], n
    while best[k][2] > 0:
        k = best[k][2]
        cuts.append(i + k)
    return tuple(sorted(cuts))


#: Longest move :func:`_cycle_cuts` considers [samples].
CUT_SAMPLES = 40


def _window_rates(P: FloatArray, a: FloatArray, t: FloatArray, i: int, j: int,
                  longest: int) -> FloatArray:
    """Every move's largest speed change [m/s] in segment i..j, the numbers of
    :func:`_speed_refine`'s ``change(m, k)`` (``max |d(a . w)/dt|``, w the samples' offset
    from the chord at :func:`_chord_fraction`'s fractions, the rate as :func:`numpy.gradient`
    takes it over the move's own times) for all moves m -> k, ``k - m <= longest``, at once:
    the moves of one length are stacked and take the same operations element by element
    (the chord products through the same BLAS calls, one per move, by ``matmul`` on the
    stack). ``a``: the unit directions of samples i..j, (j - i + 1, 3).

    Returns:
        (j - i + 1, longest + 1): entry [k, l] the move from sample i + k - l to i + k
        (NaN where there is none).
    """
    n = j - i
    out = np.full((n + 1, longest + 1), np.nan)
    p_all = np.ascontiguousarray(P[i:j + 1, :3, 3])
    tt = t[i:j + 1]
    dt = np.diff(tt)
    # numpy.gradient's coefficients at each interior sample (uneven steps)
    dx1, dx2 = dt[:-1], dt[1:]
    ca = -(dx2) / (dx1 * (dx1 + dx2))
    cb = (dx2 - dx1) / (dx1 * dx2)
    cc = dx1 / (dx2 * (dx1 + dx2))
    for length in range(1, min(longest, n) + 1):
        idx = np.arange(n - length + 1)[:, None] + np.arange(length + 1)[None, :]
        p = p_all[idx]  # (moves, length + 1, 3)
        p0, p1 = p[:, 0], p[:, -1]
        d = p1 - p0
        L2 = (d[:, None, :] @ d[:, :, None])[:, 0, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            f = np.clip(((p - p0[:, None]) @ d[:, :, None])[..., 0] / L2[:, None], 0.0, 1.0)
        still = ~(L2 > 0)
        if still.any():
            f[still] = np.linspace(0.0, 1.0, length + 1)
        w = p - (p0[:, None] + f[..., None] * (p1 - p0)[:, None])
        along = np.einsum("mki,mki->mk", a[idx], w)
        steps = dt[idx[:, :-1]]
        grad = np.empty_like(along)
        grad[:, 0] = (along[:, 1] - along[:, 0]) / steps[:, 0]
        grad[:, -1] = (along[:, -1] - along[:, -2]) / steps[:, -1]
        if length >= 2:
            mid = idx[:, 1:-1] - 1
            grad[:, 1:-1] = np.where(
                (steps == steps[:, :1]).all(axis=1)[:, None],
                (along[:, 2:] - along[:, :-2]) / (2.0 * steps[:, :1]),
                ca[mid] * along[:, :-2] + cb[mid] * along[:, 1:-1] + cc[mid] * along[:, 2:])
        out[np.arange(length, n + 1), length] = np.max(np.abs(grad), axis=1)
    return out


def _at_least_one_cycle(samples: Samples, idx: NDArray[np.int_], min_move: float,
                        hooks: set[int]) -> NDArray[np.int_]:
    """The points without those that end a move or wait shorter than ``min_move`` [s] of
    plan time (the controller's interpolation cycle: a shorter move cannot run as written,
    the controller slows down or stops). Of two points closer than that the later goes,
    unless it must stay (the first and last sample, a phase's last sample, a hook's point:
    :func:`_hook_points`), then the earlier; the merged move runs at the speed that keeps
    the plan's time between its ends. Two points that must both stay are kept (the export's
    checks judge the result)."""
    if min_move <= 0 or len(idx) < 3:
        return idx
    ph, t = samples.phase, samples.t
    n = len(samples)
    fixed = {0, n - 1} | set(hooks) | {int(i) for i in np.flatnonzero(ph[:-1] != ph[1:])}
    out = [int(idx[0])]
    for j in (int(x) for x in idx[1:]):
        if t[j] - t[out[-1]] >= min_move - 1e-9:
            out.append(j)
        elif j not in fixed:
            continue
        elif out[-1] not in fixed and len(out) > 1:
            out[-1] = j
        else:
            out.append(j)
    return np.array(out, dtype=int)


def _chord_fraction(P: FloatArray, i: int, j: int) -> tuple[FloatArray, FloatArray]:
    """Position distance [m] of samples i..j from the chord i -> j, and the fraction of the
    chord at which each is nearest (0 to 1; evenly spread on a chord of zero length)."""
    p = P[i:j + 1, :3, 3]
    a, b = p[0], p[-1]
    d = b - a
    L2 = float(d @ d)
    f = np.clip(((p - a) @ d) / L2, 0.0, 1.0) if L2 > 0 else np.linspace(0.0, 1.0, len(p))
    return np.linalg.norm(p - (a + f[:, None] * d), axis=1), f


def _deviation(P: FloatArray, i: int, j: int) -> tuple[FloatArray, FloatArray]:
    """Position distance [m] and orientation angle [rad] of samples i..j from the LIN i -> j."""
    from scipy.spatial.transform import Rotation, Slerp

    pos, f = _chord_fraction(P, i, j)
    R = Rotation.from_matrix(P[[i, j], :3, :3])
    slerp = Slerp([0.0, 1.0], R)
    ang = (slerp(f).inv() * Rotation.from_matrix(P[i:j + 1, :3, :3])).magnitude()
    return pos, ang


def _refine(P: FloatArray, keep: set[int], tol: float, ang_tol: float) -> set[int]:
    """Douglas-Peucker on position and orientation between the kept samples.

    A segment is split or kept by its own samples alone, so the segments of one round are
    judged together (:func:`_slerp_angles`: one rotation computation for all of them, the
    numbers of :func:`_deviation` one segment at a time); the kept set is the same. For the
    same reason each segment's verdict is remembered for the same poses and tolerances
    (:func:`_segment_memo`): a program rebuilt with more points (:meth:`Program.rebuilt`)
    judges only the segments it has not seen.
    """
    memo = _segment_memo(P, "split", tol, ang_tol)
    out = set(keep)
    stack = list(zip(sorted(keep)[:-1], sorted(keep)[1:], strict=True))
    while stack:
        segs = [(i, j) for i, j in stack if j - i >= 2]
        stack = []
        todo = [s for s in segs if s not in memo]
        chords = [_chord_fraction(P, i, j) for i, j in todo]
        angles = _slerp_angles(P, todo, [f for _, f in chords])
        for (i, j), (pos, _), ang in zip(todo, chords, angles, strict=True):
            excess = np.maximum(pos / tol, ang / ang_tol)
            k = int(np.argmax(excess))
            memo[i, j] = i + k if excess[k] > 1.0 else -1
        for i, j in segs:
            m = memo[i, j]
            if m >= 0:
                out.add(m)
                stack += [(i, m), (m, j)]
    return out


_MEMOS: list[tuple[bytes, dict[tuple[int, int], Any]]] = []


def _segment_memo(P: FloatArray, what: str, *params: float) -> dict[tuple[int, int], Any]:
    """Remembered per-segment results (segment (i, j) -> result) of ``what`` for these poses
    and parameters: :func:`_refine`'s verdicts (the sample a segment is split at, -1 kept
    whole), :func:`_speed_refine`'s (the same, its other inputs' hash in ``what``),
    :func:`_chord_distances`' distances. The last few, by a hash of the poses'
    bytes: a rebuilt program (:meth:`Program.rebuilt`) has the same poses."""
    h = hashlib.blake2b(np.ascontiguousarray(P).tobytes(), digest_size=16)
    h.update(what.encode())
    h.update(np.array([*params, len(P)], dtype=float).tobytes())
    key = h.digest()
    for k, known in _MEMOS:
        if k == key:
            return known
    memo: dict[tuple[int, int], Any] = {}
    _MEMOS[:] = [*_MEMOS[-7:], (key, memo)]
    return memo


def _slerp_angles(P: FloatArray, segs: list[tuple[int, int]], fracs: list[FloatArray]
                  ) -> list[FloatArray]:
    """:func:`_deviation`'s orientation angles [rad] of several segments at once: for segment
    (i, j) and chord fractions f (j - i + 1,), the angle of sample k from the slerp of
    R_i -> R_j at f_k, ``|log((R_i exp(f_k log(R_i^T R_j)))^T R_k)|`` (SciPy's ``Slerp``
    written out, element by element the same operations)."""
    from rfsw_plan.robot.rotation import Rotation

    if not segs:
        return []
    first = np.array([i for i, _ in segs])
    last = np.array([j for _, j in segs])
    r_first = Rotation.from_matrix(P[first, :3, :3])
    rotvec = (r_first.inv() * Rotation.from_matrix(P[last, :3, :3])).as_rotvec()
    counts = [len(f) for f in fracs]
    seg = np.repeat(np.arange(len(segs)), counts)
    f = np.concatenate(fracs)
    at = r_first[seg] * Rotation.from_rotvec(rotvec[seg] * f[:, None])
    idx = np.concatenate([np.arange(i, j + 1) for i, j in segs])
    ang = (at.inv() * Rotation.from_matrix(P[idx, :3, :3])).magnitude()
    return np.split(ang, np.cumsum(counts)[:-1])


def blend_distance(d0: FloatArray, d1: FloatArray, tol: float, dev: float) -> float:
    """Blend distance [m] at a point between segments d0 and d1 (vectors [m], (3,)).

    ``d = min(BLEND_SHARE min(|d0|, |d1|), 2 (tol - dev) / sin(theta))``: a contour inside the
    triangle (entry, point, exit) is at most ``d sin(theta) / 2`` from the polyline, so with the
    chords' own largest sample distance ``dev`` every sample stays within ``tol``. 0 when the
    chords already use the whole tolerance.
    """
    n0, n1 = float(np.linalg.norm(d0)), float(np.linalg.norm(d1))
    if n0 <= STILL_POS or n1 <= STILL_POS or dev >= tol:
        return 0.0
    cap = BLEND_SHARE * min(n0, n1)
    sin_t = math.sqrt(max(0.0, 1.0 - float(np.clip(d0 @ d1 / (n0 * n1), -1.0, 1.0)) ** 2))
    return cap if sin_t < 1e-12 else min(cap, 2.0 * (tol - dev) / sin_t)


def _without_stops(samples: Samples, P: FloatArray, idx: NDArray[np.int_]) -> NDArray[np.int_]:
    """The points without those a blend group holds still at (the pose of the point before,
    the next point in the same group): the controller then runs the pause into the next
    move at the speed that keeps the plan's time, instead of an exact stop and a wait in the
    material. A phase's last point stays."""
    from rfsw_plan.robot.rotation import Rotation

    out = [int(idx[0])]
    for k in range(1, len(idx)):
        i, j = out[-1], int(idx[k])
        nxt = int(idx[k + 1]) if k + 1 < len(idx) else -1
        group = BLEND_GROUPS.get(str(samples.phase[j]))
        still = (np.linalg.norm(P[j, :3, 3] - P[i, :3, 3]) < STILL_POS
                 and (Rotation.from_matrix(P[i, :3, :3]).inv()
                      * Rotation.from_matrix(P[j, :3, :3])).magnitude() < STILL_ANG)
        if (still and nxt >= 0 and group is not None
                and BLEND_GROUPS.get(str(samples.phase[nxt])) == group
                and BLEND_GROUPS.get(str(samples.phase[i])) == group):
            continue
        out.append(j)
    return np.array(out, dtype=int)


def _motions(samples: Samples, P: FloatArray, idx: NDArray[np.int_],
             tol: float, pin: FloatArray) -> list[Motion]:
    from rfsw_plan.robot.rotation import Rotation

    motions = [Motion("joint", 0, str(samples.phase[idx[0]]))]
    pts = P[idx, :3, 3]
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    # A creep shorter than SHORT_MOVE (the end stop's first moves: a few micrometres) runs at
    # the speed that gives the plan's time between its ends as written (every format writes mm
    # with 4 decimals, WRITTEN_POSITION m): their rounding is several per cent of its length.
    written = np.round(pts / WRITTEN_POSITION) * WRITTEN_POSITION
    seg = np.where(seg < SHORT_MOVE, np.linalg.norm(np.diff(written, axis=0), axis=1), seg)
    dev = np.array([float(np.max(c)) for c in _segment_chords(P, idx)])
    # the rotation between consecutive points, all at once
    turn = ((Rotation.from_matrix(P[idx[:-1], :3, :3]).inv()
             * Rotation.from_matrix(P[idx[1:], :3, :3])).magnitude() if len(idx) > 1
            else np.zeros(0))
    for k in range(1, len(idx)):
        i, j = idx[k - 1], idx[k]
        phase = str(samples.phase[j])
        dt = float(samples.t[j] - samples.t[i])
        ang = turn[k - 1]
        if seg[k - 1] < STILL_POS and ang < STILL_ANG:
            motions.append(Motion("wait", k, phase, duration=dt))
            continue
        speed = seg[k - 1] / dt if dt > 0 else 0.0
        blend = 0.0
        group = BLEND_GROUPS.get(phase)
        if (k + 1 < len(idx) and group is not None
                and BLEND_GROUPS.get(str(samples.phase[idx[k + 1]])) == group):
            blend = blend_distance(pts[k] - pts[k - 1], pts[k + 1] - pts[k], tol,
                                   max(dev[k - 1], dev[k]))
        vp = None
        if phase in CONTACT_PHASES and dt > 0:
            vp = _pin_speed(speed, float(np.linalg.norm(pin[j] - pin[i])) / dt)
        motions.append(Motion("lin", k, phase, speed=speed, duration=dt, blend=blend,
                              pin_speed=vp))
    return motions


def pin_heights(samples: Samples, pin: FloatArray, normal: FloatArray,
                depth: float) -> FloatArray:
    """Height of the predicted pin tip above the plate surface at every sample [m], (N,).

    ``h = (pin - seam) . n - depth``: the seam point of a sample lies ``depth`` below the
    surface along the plate normal ``n`` (base frame, (3,)), so ``h`` is -depth with the pin
    plunged and 0 with its tip on the surface.
    """
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    return np.asarray((np.asarray(pin) - samples.seam) @ n - depth)


def spindle_clearance(samples: Samples, h: FloatArray) -> float:
    """The spindle clearance [m]: the pin tip's height where the plunge starts (the end of
    the approach, where the spindle starts; ``spindle_clearance`` of the plan options)."""
    plunge = np.flatnonzero(samples.phase == "plunge")
    return float(h[max(int(plunge[0]) - 1, 0)]) if plunge.size else 0.0


def _hook_points(samples: Samples, h: FloatArray) -> set[int]:
    """The samples the hooks need as points: contact (the first plunge sample with the
    predicted tip at or below the surface) and clear (the first retract sample with the tip
    the spindle clearance above it)."""
    out: set[int] = set()
    ph = samples.phase
    contact = np.flatnonzero((ph == "plunge") & (h <= 0.0))
    if contact.size:
        out.add(int(contact[0]))
    clear = np.flatnonzero((ph == "retract") & (h >= spindle_clearance(samples, h) - 1e-9))
    if clear.size:
        out.add(int(clear[0]))
    return out


def speed_note(m: Motion, short: bool = False) -> str:
    """The comment before a motion whose commanded TCP speed differs from the predicted
    pin's (:attr:`Motion.pin_speed`), "" for the others: the speed is the deflection
    compensation's, so nobody "fixes" it. ``short``: within 32 characters (FANUC remarks)."""
    if m.pin_speed is None:
        return ""
    v, p = m.speed * 1e3, m.pin_speed * 1e3
    if short:
        return f"TCP {v:.2f}/pin {p:.2f}mm/s:defl.comp"
    return (f"TCP {v:.2f} mm/s, pin {p:.2f} mm/s: deflection compensation, keep this "
            "speed")


def _pin_speed(commanded: float, pin: float) -> float | None:
    """``pin`` when it differs from ``commanded`` [m/s] by more than :data:`SPEED_NOTE` and
    0.1 mm/s."""
    if abs(commanded - pin) <= max(SPEED_NOTE * pin, 1e-4):
        return None
    return pin


def _with_hooks(motions: list[Motion], idx: NDArray[np.int_], h: FloatArray,
                samples: Samples) -> list[Motion]:
    """Insert the hooks by the predicted pin tip (height ``h`` above the surface per sample):

    * ``home_start`` before the first move;
    * ``spindle_start`` before the first plunge motion: the robot waits at the end of the
      approach, the tip the spindle clearance above the surface;
    * ``force_on`` at contact: after the motion to the first plunge point whose tip is at or
      below the surface (a point of its own, :func:`_hook_points`);
    * ``force_off`` after the last weld motion, before the retract: the pin is still in;
    * ``spindle_stop`` after the first retract motion whose target has the tip clear of the
      surface by the spindle clearance (never while the pin is in the material);
    * ``home_end`` at the end.
    """
    hp = h[idx]
    clear = spindle_clearance(samples, h) - 1e-9
    out: list[Motion] = [Motion("hook", 0, motions[0].phase, hook="home_start")]
    placed: set[str] = set()
    for k, m in enumerate(motions):
        if m.phase == "plunge" and "spindle_start" not in placed:
            out.append(Motion("hook", m.point, "plunge", hook="spindle_start"))
            placed.add("spindle_start")
        if (m.kind == "lin" and "force_on" not in placed and k > 0
                and m.phase in ("plunge", "dwell") and hp[motions[k - 1].point] <= 0.0):
            out.append(Motion("hook", motions[k - 1].point, m.phase, hook="force_on"))
            placed.add("force_on")
        if m.phase == "retract" and "force_off" not in placed:
            out.append(Motion("hook", m.point, "retract", hook="force_off"))
            placed.add("force_off")
        if m.kind == "lin" and m.phase == "retract" and "spindle_stop" not in placed \
                and hp[m.point] >= clear:
            out += [m, Motion("hook", m.point, "retract", hook="spindle_stop")]
            placed.add("spindle_stop")
            continue
        out.append(m)
    if "spindle_stop" not in placed:
        out.append(Motion("hook", motions[-1].point, motions[-1].phase, hook="spindle_stop"))
    out.append(Motion("hook", motions[-1].point, motions[-1].phase, hook="home_end"))
    return out


# --------------------------------------------------------------------------------------------
# Checks of a program


_FK: list[tuple[Robot, bytes, FloatArray]] = []


def sample_fk(robot: Robot, q: FloatArray) -> FloatArray:
    """TCP poses of joint values q [rad], (N, n), in the description's base frame, (N, 4, 4)
    [m] (:meth:`Robot.batch_fk_jacobian`), read-only, remembered for the last few joint arrays
    by their bytes and layout: a program, its rebuilt versions (the TP's shorter segments),
    the path checks, the stream and ``check`` ask for the poses of the same verified samples
    many times (issue 41)."""
    a = np.asarray(q, dtype=float)
    h = hashlib.blake2b(a.tobytes(), digest_size=16)
    h.update(repr((a.shape, a.strides)).encode())
    key = h.digest()
    for r, k, T in _FK:
        if r is robot and k == key:
            return T
    T = robot.batch_fk_jacobian(a)[0]
    T.setflags(write=False)
    _FK[:] = [*_FK[-3:], (robot, key, T)]
    return T


_POSES: list[tuple[Program, FloatArray]] = []


def sample_poses(program: Program) -> FloatArray:
    """The TCP pose of every verified sample in the program's base frame, (N, 4, 4) [m]
    (forward kinematics once per program: the path checks ask for it many times)."""
    for src, P in _POSES:
        if src is program:
            return P
    P = np.linalg.inv(program.base_pose(np.eye(4)))[None] @ \
        sample_fk(program.robot, program.all_samples.q)
    P.setflags(write=False)
    _POSES[:] = [*_POSES[-7:], (program, P)]
    return P


_CHORDS: list[tuple[Program, list[FloatArray]]] = []


def _segment_chords(P: FloatArray, idx: NDArray[np.int_]) -> list[FloatArray]:
    """Per segment k, the distance [m] of samples idx[k]..idx[k + 1] (poses P, (N, 4, 4))
    from the chord between its ends (:func:`_chord_fraction`, remembered per segment for the
    same poses: :func:`_segment_memo`)."""
    memo = _segment_memo(P, "chord")
    chords = []
    for i, j in zip(idx[:-1].tolist(), idx[1:].tolist(), strict=True):
        if (i, j) not in memo:
            memo[i, j] = _chord_fraction(P, i, j)[0]
            memo[i, j].setflags(write=False)
        chords.append(memo[i, j])
    return chords


def _chord_distances(program: Program) -> list[FloatArray]:
    """Per segment k of the program, the distance [m] of its samples idx[k]..idx[k + 1] from
    the chord between its points (once per program: the blend search asks many times)."""
    for src, chords in _CHORDS:
        if src is program:
            return chords
    chords = _segment_chords(sample_poses(program), program.sample_index)
    _CHORDS[:] = [*_CHORDS[-7:], (program, chords)]
    return chords


def path_deviation(program: Program, blends: dict[int, float] | None = None) -> FloatArray:
    """Bound of every verified sample's distance to the path the controller runs [m], (N,).

    Sample by sample: the distance to the chord of its segment, plus, for a sample on either
    half of a blended corner (within the blend distance d of the point), the blend model's
    ``d sin(theta) / 2`` (module docstring). Samples before the first point or on waits: 0.

    Args:
        program: The program.
        blends: Point index -> blend distance [m] a format rounds with (default: the
            program's own, :attr:`Motion.blend`).
    """
    return BlendBound(program, blends).bound.copy()


class BlendBound:
    """:func:`path_deviation` of a program with a set of blends, kept up to date while the
    blends are removed one by one (:meth:`remove`): removing the blend at point c changes only
    the two segments that end at c, so only the samples from point c - 1 to c + 1 are summed
    again (the same operations in the same order: the same bits as a whole new bound)."""

    def __init__(self, program: Program, blends: dict[int, float] | None = None) -> None:
        P = sample_poses(program)
        self._idx = idx = program.sample_index
        self._P, self._pts = P, P[idx, :3, 3]
        self._chords = _chord_distances(program)
        blend = {m.point: m.blend for m in program.motions if m.kind == "lin"} \
            if blends is None else blends
        self._corner = [self._corner_bound(c, blend.get(c, 0.0)) for c in range(len(idx))]
        self._seg = [self._segment(k) for k in range(len(idx) - 1)]
        #: The bound of every verified sample [m], (N,).
        self.bound = np.zeros(len(program.all_samples))
        for k, pos in enumerate(self._seg):
            i, j = int(idx[k]), int(idx[k + 1])
            self.bound[i:j + 1] = np.maximum(self.bound[i:j + 1], pos)

    def _corner_bound(self, c: int, d: float) -> tuple[float, float]:
        """(d [m], the blend model's ``d sin(theta) / 2`` [m]) at point c, (0, 0) unblended."""
        pts = self._pts
        if d <= 0 or not 0 < c < len(pts) - 1:
            return 0.0, 0.0
        a, b = pts[c] - pts[c - 1], pts[c + 1] - pts[c]
        cos_t = float(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0))
        return d, d * math.sqrt(max(0.0, 1.0 - cos_t * cos_t)) / 2.0

    def _segment(self, k: int) -> FloatArray:
        """The bound of the samples of segment k (points k -> k + 1) [m]."""
        i, j = int(self._idx[k]), int(self._idx[k + 1])
        p = self._P[i:j + 1, :3, 3]
        pos = self._chords[k]
        for c in (k, k + 1):
            d, extra = self._corner[c]
            if d > 0:
                pos = pos + (np.linalg.norm(p - self._pts[c], axis=1) <= d + 1e-12) * extra
        return pos

    def remove(self, c: int) -> None:
        """Drop the blend at point c (the point becomes exact) and update :attr:`bound`."""
        if self._corner[c][0] <= 0:
            return
        self._corner[c] = (0.0, 0.0)
        idx, last = self._idx, len(self._idx) - 1
        for k in (c - 1, c):
            if 0 <= k < last:
                self._seg[k] = self._segment(k)
        lo, hi = int(idx[max(c - 1, 0)]), int(idx[min(c + 1, last)])
        self.bound[lo:hi + 1] = 0.0
        for k in np.flatnonzero((idx[:-1] <= hi) & (idx[1:] >= lo)).tolist():
            i, j = int(idx[k]), int(idx[k + 1])
            a, b = max(i, lo), min(j, hi)
            self.bound[a:b + 1] = np.maximum(self.bound[a:b + 1], self._seg[k][a - i:b - i + 1])


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


def number(x: float, digits: int) -> str:
    """Fixed-point text without a negative zero (identical text for +-1e-17 on every machine):
    :func:`rfsw_plan.numfmt.fixed`, the one formatter of every writer."""
    return fixed(x, digits)
