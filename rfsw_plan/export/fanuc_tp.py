"""FANUC TP program in ASCII form (``.ls``) of a :class:`~rfsw_plan.export.program.Program`.

Format conventions followed (FANUC R-30iB HandlingTool operator's manual, program structure
and the ASCII ``.ls`` listing that ``ASCII Upload`` / ``MAKETP`` accept; the layout RoboDK's
R-30iA post-processor writes): the sections ``/PROG name``, ``/ATTR`` (``OWNER``,
``COMMENT``, ``PROG_SIZE``, ``CREATE``, ``MODIFIED``, ``FILE_NAME``, ``VERSION``,
``LINE_COUNT``, ``MEMORY_SIZE``, ``PROTECT``, ``TCD``, ``DEFAULT_GROUP``, ``CONTROL_CODE``),
``/MN`` with numbered lines ``   n:  instruction ;``, ``/POS`` and ``/END``.

* The first point ``P[1]`` is a joint target (``J1 = .. deg`` ... in ``/POS``): the first move
  cannot take another posture. The others are Cartesian with ``CONFIG : 'N U T, 0, 0, 0'``
  (:func:`rfsw_plan.export.config.fanuc_config`: F if J5 > 0, N if J5 < 0, checked against
  RoboDK's post-processor and a ROBOGUIDE table in ``tests/data/vendor``).
* Frames: the program selects the user frame and tool frame by number (``UFRAME_NUM``,
  ``UTOOL_NUM``) and writes none of the cell's numbered data: the header lists the values to
  enter there (two remark lines each, ``! UFRAME[n] X .. Y .. Z ..`` and ``! UFRAME[n] W ..
  P .. R ..``, which :func:`read_tp` reads) and the payload for the payload screen (FANUC
  units: kg, cm, kgf cm s^2). With ``cell_data`` (``--cell-data``) it writes them as before:
  the plate frame and the TCP element by element into position registers (``PR[i]=LPOS``
  makes the register Cartesian, then ``PR[i,1..6]``), then ``UFRAME[uf]=PR[i]``,
  ``UTOOL[ut]=PR[j]`` and ``PAYLOAD[ut]``; the header says so.
* Termination: ``CRn`` (corner region, n whole millimetres) at a point inside the plunge,
  the dwell or the weld where the rounding keeps every verified sample within the path
  tolerance, ``FINE`` elsewhere (the phase ends: approach, end of plunge, end of dwell, end
  of weld, retract, and a plunge or dwell corner the bound does not allow). In the welding
  phases a corner that even 1 mm would round too much gets shorter segments instead
  (:func:`tp_program` adds the verified samples halfway to its neighbours as points).
  ``CNT`` is not used: it rounds a corner by an amount that depends on speed, acceleration
  and override, with no published bound. ``CRy`` (FANUC R-30iB teach pendant help /
  operator's manual, "Corner Region Termination Type", quoted in
  ``tests/data/vendor/syntax_facts.csv``): the corner path starts and ends at most y mm from
  the taught point, y from 0 to 1000, limited to half the segment; it belongs to the
  Advanced Constant Path option (which needs Constant Path, and ``$CZCDCFG.$CD_ENABLE =
  FALSE``: Corner Distance and Corner Region exclude each other). Without the option,
  replace every ``CRn`` by ``FINE``. The bound (:func:`corner_regions`, checked at export by
  :meth:`FanucTpFormat.path_deviation`) is the vendor-neutral blend model with that distance.
* ``L P[n] v mm/sec`` when the speed is a whole mm/s, else ``R[n]=v`` and ``L P[k]
  R[n]mm/sec`` (the speed register ``n``: :attr:`ProgramOptions.speed_register`), never a
  motion time (the controller stretches a timed move it cannot run); ``WAIT t(sec)``;
  remarks ``! text`` within :data:`REMARK_LEN` characters, plain ASCII (:func:`remarks`).
  ``FINE`` only at the phase ends: a corner inside a phase that no region fits is ``CR0``.

W, P, R (R = Rz(R) Ry(P) Rx(W), deg) are unwrapped along the program: each angle is moved by
whole turns to be within 180 deg of the previous point's.

A program longer than :data:`MAX_LINES` lines of ``/MN`` keeps its header, frames and payload
in the main program and moves its motions, in order, into called programs ``<NAME>_S1``,
``<NAME>_S2``... (``CALL <NAME>_S1 ;``), one ``.ls`` file each, with the points they move to
(their global ``P[n]`` numbers) in their own ``/POS``. Load every file; run the main one.
:func:`read_tp` follows the calls.
"""

from __future__ import annotations

import math
import re
from collections.abc import Hashable
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.export.config import fanuc_config, fanuc_configs
from rfsw_plan.export.format import ControllerFormat, FormatLimits, ReadPoint, ReadProgram
from rfsw_plan.export.krl import unwrap_angles
from rfsw_plan.export.program import (
    BLEND_GROUPS,
    BlendBound,
    Program,
    Samples,
    _chord_distances,
    controller_name,
    number,
    payload_assumed,
    speed_note,
)
from rfsw_plan.files import read_program_text, write_text
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: Lines of ``/MN`` one TP program holds (R-30iB), before its motions move into called programs.
MAX_LINES = 9999
#: Position registers the program writes the user frame and tool frame into.
PR_UFRAME = 91
PR_UTOOL = 92
#: FANUC's interpolation period (ITP) [s]: 8 ms on R-30iA, R-30iB, R-30iB Plus (public
#: source: industrialmonitordirect.com knowledge base, "FANUC Robot Cycle Time Deviation:
#: ITP-Based Resolution": a motion's time is rounded up to whole ITPs, 16 ms selectable).
#: No move or WAIT of a program is shorter (:attr:`ControllerFormat.cycle`).
ITP_CYCLE = 0.008
#: Joint speed of the move to the approach point [%].
J_PERCENT = 10
#: CREATE/MODIFIED stamp (fixed: the same plan gives the same bytes on every machine).
STAMP = datetime(2000, 1, 1, tzinfo=UTC)
#: kg m^2 -> kgf cm s^2 (FANUC's payload inertia unit): 1 kgf cm s^2 = 0.0980665 kg m^2.
KGFCMS2 = 0.0980665
#: Default hook remarks.
DEFAULT_HOOKS = {
    "home_start": ("HOME: move to the cell's home first,", " e.g. J PR[1:HOME] 10% FINE"),
    "home_end": ("HOME: back to the cell's home,", " e.g. J PR[1:HOME] 10% FINE"),
    "spindle_start": ("SPINDLE START: spindle on and wait at speed,",
                      " e.g. DO[1]=ON and WAIT DI[1]=ON"),
    "force_on": ("FORCE CONTROL: none (the plan is verified in position control)",),
    "force_off": ("FORCE CONTROL: none (position control)",),
    "spindle_stop": ("SPINDLE STOP: the pin has left the material,", " e.g. DO[1]=OFF"),
}


def frame_to_xyzwpr(T: FloatArray) -> FloatArray:
    """4x4 pose [m] -> (X, Y, Z [mm], W, P, R [deg]) with R = Rz(R) Ry(P) Rx(W)."""
    Rm = T[:3, :3]
    P = math.atan2(-Rm[2, 0], math.hypot(Rm[0, 0], Rm[1, 0]))
    R = math.atan2(Rm[1, 0], Rm[0, 0])
    W = math.atan2(Rm[2, 1], Rm[2, 2])
    return np.array([*(T[:3, 3] * 1e3), math.degrees(W), math.degrees(P), math.degrees(R)])


def xyzwpr_to_frame(v: FloatArray | list[float]) -> FloatArray:
    """Inverse of :func:`frame_to_xyzwpr` (any number of turns in W, P, R)."""
    from rfsw_plan.export.krl import xyzabc_to_frame

    X, Y, Z, W, P, R = (float(x) for x in v)
    return xyzabc_to_frame([X, Y, Z, R, P, W])


def unwrap_wpr(wpr: FloatArray) -> FloatArray:
    """W, P, R rows [deg], (m, 3), each moved by whole turns to follow the previous row."""
    return unwrap_angles(wpr)


def tp_name(name: str) -> str:
    """A valid TP program name (upper-case letters, digits, underscore; starts with a letter)."""
    return controller_name(name, max_len=36, prefix="P", upper=True)


#: Longest remark text (after ``!``) [characters]: the pendant's limit for a comment line.
REMARK_LEN = 32


def remarks(text: str) -> list[str]:
    """``text`` as remark lines (``! ...``) in plain ASCII, each within :data:`REMARK_LEN`
    characters (cut at spaces where possible; nothing is lost)."""
    import unicodedata

    text = text.replace("\u00a7", "sec. ")
    text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    text = " ".join(text.replace(";", ",").split())
    out = []
    while len(text) > REMARK_LEN:
        cut = text.rfind(" ", 8, REMARK_LEN + 1)
        cut = REMARK_LEN if cut < 0 else cut
        out.append("! " + text[:cut].rstrip())
        text = text[cut:].lstrip()
    return [*out, "! " + text] if text or not out else out


def _speed(speed: float, duration: float, register: int) -> tuple[list[str], str]:
    """The speed of a linear move: ``v mm/sec`` when it is a whole mm/s (within 0.1 %; the
    pendant takes 1 to 2000 mm/sec in whole numbers), else ``R[n]mm/sec`` after ``R[n]=v``
    (a numeric register holds a real; the speed register ``n`` is an export option). Never a
    motion time (``msec``): the controller stretches a timed move it cannot run, so the
    verified timing would not hold and the pendant would hide the real speed.

    Returns:
        (lines before the move, the speed text).
    """
    v = speed * 1e3
    if v >= 1.0 and abs(v - round(v)) <= 1e-3 * v and round(v) <= 2000:
        return [], f"{round(v)}mm/sec"
    if v <= 0:  # a move that takes no time (never written: such a segment is a wait)
        return [], f"{max(round(duration * 1e3), 1)}msec"
    return [f"R[{register}]={number(v, 6)}"], f"R[{register}]mm/sec"


class FanucTpFormat(ControllerFormat):
    """FANUC TP in ASCII (``.ls``), R-30iB."""

    name = "fanuc_tp"
    order = 20
    description = "FANUC TP ASCII (.ls, R-30iB)"
    suffix = ".ls"
    maker = "FANUC"
    limits = FormatLimits(name_length=36, max_lines=MAX_LINES)
    cycle = ITP_CYCLE

    def file_name(self, program: Program) -> str:
        return tp_name(program.header.name) + ".ls"

    def header_text(self, path: Path, lines: int = 80) -> str:
        """The remarks of the first ``lines`` lines as one text; a remark that
        :func:`remarks` cut inside a word (:data:`REMARK_LEN` characters, no space after the
        eighth) is joined to the next one without a space (the plan id of a long problem
        name spans two remarks)."""

        remark = re.compile(r"^\s*(?:\d+:)?\s*!\s?(.*?)\s*;?\s*$")
        text = ""
        cut = False
        with Path(path).open(encoding="ascii", errors="replace") as fh:
            for _, line in zip(range(lines), fh, strict=False):
                m = remark.match(line)
                if m is None:
                    continue
                part = m.group(1)
                text += ("" if cut or not text else " ") + part
                cut = len(part) == REMARK_LEN and " " not in part[8:]
        return text

    def posture(self, robot: Robot, q: FloatArray) -> Hashable:
        return fanuc_config(robot, q)

    def postures(self, robot: Robot, Q: FloatArray) -> list[Hashable]:
        return list(fanuc_configs(robot, Q))

    def write(self, program: Program, folder: Path) -> list[Path]:
        return write_tp(tp_program(program), folder)

    def read(self, path: Path) -> ReadProgram:
        return read_tp(path)

    def path_deviation(self, program: Program) -> FloatArray:
        return corner_regions(tp_program(program))[1]

    def expected(self, program: Program) -> Samples:
        tp = tp_program(program)
        return tp.samples.subset(tp.moved_points())


#: Rounds of :func:`tp_program` (each halves the segments around a weld point still FINE).
TP_SPLITS = 6
_TP_CACHE: list[tuple[Program, Program]] = []


def tp_program(program: Program) -> Program:
    """The program the TP writes: the vendor-neutral one with, around every point of the
    welding phases that the path bound would make ``FINE`` (:func:`corner_regions`), the plan
    samples halfway to its neighbours as points too, for up to :data:`TP_SPLITS` rounds.
    Shorter segments shorten the corner region FANUC allows (half the segment) and the
    direction change, so the pin does not stop in the weld where 1 mm of rounding cannot
    follow the path (the lateral ramp at the start of the weld, a curved seam). Every added
    point is a verified sample."""
    for src, out in _TP_CACHE:
        if src is program:
            return out
    prog = program
    extra: set[int] = set()
    for _ in range(TP_SPLITS if program.build_args else 0):
        cr, _ = corner_regions(prog)
        idx = prog.sample_index
        new: set[int] = set()
        for m in prog.motions:
            c = m.point
            if (m.kind == "lin" and m.phase in BLEND_GROUPS and cr.get(c, 0) == 0
                    and 0 < c < len(idx) - 1
                    and BLEND_GROUPS.get(str(prog.samples.phase[c + 1]))
                    == BLEND_GROUPS[m.phase]):
                for a, b in ((idx[c - 1], idx[c]), (idx[c], idx[c + 1])):
                    if b - a >= 2:
                        new.add(int((a + b) // 2))
        if not new - extra:
            break
        extra |= new
        prog = program.rebuilt(frozenset(extra))
    _TP_CACHE[:] = [*_TP_CACHE[-3:], (program, prog)]
    return prog


#: Largest corner region [mm] (the manual's range: 0 to 1000 mm).
CR_MAX = 1000


def corner_regions(program: Program) -> tuple[dict[int, int], FloatArray]:
    """The ``CR`` value [mm] of every rounded point (point index -> y; the others ``FINE``)
    and the resulting bound of every verified sample's distance to the path [m], (N,).

    FANUC's corner region y (R-30iB operator's manual, "Corner Region Termination Type
    (CRy)", quoted in tests/data/vendor/SOURCE.md): the corner path starts and ends at most y
    from the taught point, and a y larger than half the segment distance is limited to half
    the segment. The bound is then the blend model of
    :func:`rfsw_plan.export.program.path_deviation` with ``d = min(y, max(L0, L1) / 2)``
    (L0, L1 the two segments). Every point the vendor-neutral program blends (inside the
    plunge, the dwell or the weld) gets the largest whole y (1 mm at least, 1000 at most)
    whose ``d`` keeps the samples within the path tolerance:
    ``d <= 2 (tol - dev) / sin(theta)``, dev the two chords' own largest sample distance; a
    point inside a phase where even ``min(1 mm, max(L0, L1) / 2)`` does not is ``CR0`` (the
    corner region 0 mm: the corner path starts and ends at the point, no rounding),
    and so is, one by one, the larger of two regions whose bounds add up beyond the
    tolerance on the segment between them. ``FINE`` is left for the phase ends.
    """
    for src, cr0, bound0 in _CR_CACHE:
        if src is program:
            return dict(cr0), bound0
    tol = program.header.path_tol
    pts = program.poses[:, :3, 3]
    idx = program.sample_index
    chords = _chord_distances(program)
    cr: dict[int, int] = {}
    blends: dict[int, float] = {}
    phase = program.samples.phase
    for m in program.motions:
        c = m.point
        if (m.kind != "lin" or not 0 < c < len(pts) - 1 or m.phase not in BLEND_GROUPS
                or BLEND_GROUPS.get(str(phase[c + 1])) != BLEND_GROUPS[m.phase]):
            continue
        cr[c] = 0  # inside a phase: CR0 unless a rounding fits (below)
        if m.blend <= 0:
            continue
        a, b = pts[c] - pts[c - 1], pts[c + 1] - pts[c]
        la, lb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
        dev = max(float(np.max(chords[k])) for k in (c - 1, c))
        ax, ay, az = a.tolist()
        bx, by, bz = b.tolist()  # np.cross's operations, without its overhead
        axb = np.array([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx])
        sin_t = float(np.linalg.norm(axb)) / max(la * lb, 1e-30)
        d_max = math.inf if sin_t < 1e-12 else 2.0 * (tol - dev) / sin_t
        half = 0.5 * max(la, lb)
        if dev >= tol or min(1e-3, half) > d_max:
            continue
        y = int(min(CR_MAX, max(1.0, math.floor(min(d_max, 1.0) * 1e3 + 1e-9))))
        cr[c] = y
        blends[c] = min(y * 1e-3, half)
    path = BlendBound(program, blends)  # only the samples next to a removed blend change
    while True:  # two regions that meet on one segment add their bounds there
        over = np.flatnonzero(path.bound > tol * (1 + 1e-9))
        if over.size == 0 or not blends:
            bound = path.bound.copy()
            bound.setflags(write=False)
            _CR_CACHE[:] = [*_CR_CACHE[-3:], (program, dict(cr), bound)]
            return cr, bound
        k = np.clip(np.searchsorted(idx, over), 1, len(idx) - 1)
        near = {int(c) for c in np.concatenate([k - 1, k]) if int(c) in blends}
        c = max(near or blends, key=lambda c: blends[c])
        cr[c] = 0
        del blends[c]
        path.remove(c)


#: The last programs' :func:`corner_regions` (the TP build, its path check and its writer ask
#: for the same program's).
_CR_CACHE: list[tuple[Program, dict[int, int], FloatArray]] = []


def _frame_remarks(program: Program) -> list[str]:
    """The frame values to enter on the controller, one remark line per value, each within
    :data:`REMARK_LEN` (read back by :func:`read_tp` when the program does not write the
    frames)."""
    o = program.options
    out = []
    for what, n, T in (("UFRAME", o.base_number, program.work),
                       ("UTOOL", o.tool_number, program.tool)):
        v = frame_to_xyzwpr(T)
        out += [f"! {what}[{n}] {k} {number(x, 4)}" for k, x in zip("XYZWPR", v, strict=True)]
    return out


def _frames(program: Program) -> list[str]:
    o = program.options
    out = []
    if o.cell_data:
        for pr, what, T in ((PR_UFRAME, "plate frame in world", program.work),
                            (PR_UTOOL, "TCP in faceplate", program.tool)):
            v = frame_to_xyzwpr(T)
            out += [f"! PR[{pr}] = {what}", f"PR[{pr}]=LPOS"]
            out += [f"PR[{pr},{j + 1}]={number(x, 4)}" for j, x in enumerate(v)]
        out += [f"UFRAME[{o.base_number}]=PR[{PR_UFRAME}]",
                f"UTOOL[{o.tool_number}]=PR[{PR_UTOOL}]"]
    else:
        out += _frame_remarks(program)
    out += [f"UFRAME_NUM={o.base_number}", f"UTOOL_NUM={o.tool_number}"]
    if program.payload is not None and o.cell_data:
        out.append(f"PAYLOAD[{o.tool_number}]")
    return out


def _header_extra(program: Program, cr: dict[int, int]) -> list[str]:
    o = program.options
    if o.cell_data:
        data = (f"WRITES THE CELL'S DATA (export option cell_data): UFRAME[{o.base_number}], "
                f"UTOOL[{o.tool_number}], PR[{PR_UFRAME}], PR[{PR_UTOOL}] are overwritten "
                f"and PAYLOAD[{o.tool_number}] selects that schedule")
        teach = f"replace the PR[{PR_UFRAME}] values with it"
    else:
        data = (f"CELL DATA LEFT ALONE: this program selects UFRAME {o.base_number} and "
                f"UTOOL {o.tool_number} and writes no frame, register or payload: enter "
                "the values of the UFRAME/UTOOL remarks below there and select the payload "
                "schedule before running")
        teach = "enter it in the UFRAME remarks"
    out = [*program.maker_note("FANUC"), data, *program.hook_notes("fanuc_tp"),
           f"SPEED REGISTER R[{o.speed_register}]: set before each move whose speed is not a "
           "whole mm/sec (export option speed_register)"]
    pl = program.payload
    if pl is not None:
        com = (np.linalg.inv(program.robot.description.convention.flange)
               @ np.append(pl.com, 1.0))[:3] * 100.0
        inertia = "UNKNOWN (0; identify it)" if pl.inertia is None else \
            " ".join(f"{number(x / KGFCMS2, 3)}" for x in pl.inertia) + " kgf cm s^2"
        out.append(f"PAYLOAD{'[' + str(o.tool_number) + ']' if o.cell_data else ''} "
                   f"(payload screen): {number(pl.mass, 1)} kg"
                   f"{' ASSUMED' if payload_assumed(pl) else ''}, "
                   f"centre X {number(com[0], 2)} Y {number(com[1], 2)} Z {number(com[2], 2)} "
                   f"cm (faceplate), inertia {inertia}")
    n_cr = len(cr)
    out += ["UFRAME = the plate: origin on the first weld point, +X along the seam, +Y on "
            f"the plate. To use a frame taught on the plate (3-point), {teach} and run "
            "rfsw-plan check on this file",
            f"Termination: CR (corner region, mm) at {n_cr} points inside the plunge, dwell, "
            "weld and retract, FINE at the phase ends; CRy keeps the corner path within y mm of "
            "the point (half the segment at most): it needs the Advanced Constant Path "
            "option (without it replace CRn by FINE)"]
    return out


def hook_lines(program: Program, hook: str) -> tuple[str, ...]:
    """The default text of ``hook`` (remarks): for a force-controlled plan the force-control
    hooks carry the set force and the ramp (no public FANUC source gives the TP instruction
    of the Force Sensor option for a constant axial force along a path, so the hook says so)."""
    f, ramp = program.force_ramp()
    if f > 0 and hook == "force_on":
        return (f"FORCE CONTROL ON at contact: axial set force {f:.0f} N along tool +Z, "
                f"ramp 0 to {f:.0f} N over the plunge ({ramp:.2f} s), held through dwell "
                "and weld. No public FANUC source gives the Force Sensor TP instruction: "
                "write your cell's force schedule call here",)
    if f > 0 and hook == "force_off":
        return ("FORCE CONTROL OFF: the weld has ended, pin still in, retract follows. "
                "Write your cell's force schedule end here",)
    return DEFAULT_HOOKS[hook]


def _mn(program: Program) -> tuple[list[str], list[str]]:
    """The ``/MN`` lines: (header, frames and payload; the motions with their hooks). Every
    remark is ASCII and within :data:`REMARK_LEN` characters (:func:`remarks`)."""
    cr, _ = corner_regions(program)
    head = [r for line in program.header.comments("", extra=_header_extra(program, cr))
            for r in remarks(line)]
    head += _frames(program)
    body: list[str] = []
    marks = program.phase_changes()
    reg = program.options.speed_register
    # the speed over the chord as written (/POS in 0.1 um), so a segment of a few um keeps the
    # plan's time as the controller computes it (length / speed)
    xyz = np.round(program.poses[:, :3, 3] * 1e3, 4)
    last = 0
    for i, m in enumerate(program.motions):
        if i in marks:
            body.append(f"! ---- phase: {marks[i]}")
        p = f"P[{m.point + 1}]"
        if m.kind == "hook":
            user = program.options.hooks.get(m.hook, "fanuc_tp")
            body.append(f"! hook {m.hook}")  # rfsw-plan check finds the hook by it
            body += list(user) if user is not None else \
                [r for t in hook_lines(program, m.hook) for r in remarks(t)]
        elif m.kind == "joint":
            body.append(f"J {p} {J_PERCENT}% FINE")
        elif m.kind == "wait":
            body.append(f"WAIT {max(m.duration, 0.01):.2f}(sec)")
        else:
            term = f"CR{cr[m.point]}" if m.point in cr else "FINE"
            body += remarks(speed_note(m, short=True)) if m.pin_speed is not None else []
            v = float(np.linalg.norm(xyz[m.point] - xyz[last])) * 1e-3 / m.duration \
                if m.duration > 0 else m.speed
            pre, speed = _speed(v, m.duration, reg)
            body += [*pre, f"L {p} {speed} {term}"]
        if m.kind in ("joint", "lin"):
            last = m.point
    return head, body


def sub_name(name: str, k: int) -> str:
    """Name of the k-th called program (1-based) of the TP program ``name``."""
    return controller_name(f"{name}_S{k}", max_len=FanucTpFormat.limits.name_length,
                           prefix="P", upper=True)


_POINT = re.compile(r"^[JL] P\[(\d+)\]")


def write_tp(program: Program, folder: str | Path, stamp: datetime | None = None,
             max_lines: int = MAX_LINES) -> list[Path]:
    """Write ``<NAME>.ls`` (and its called programs ``<NAME>_S<k>.ls`` when the motions do not
    fit in ``max_lines`` lines) atomically; returns their paths, the main program first
    (``stamp``: CREATE/MODIFIED time, default :data:`STAMP`)."""
    name = tp_name(program.header.name)
    head, body = _mn(program)
    if len(head) + len(body) <= max_lines:
        parts = [(name, head + body)]
    else:
        size = max_lines - 1  # each called program opens with one remark
        chunks = [body[i:i + size] for i in range(0, len(body), size)]
        subs = [sub_name(name, k + 1) for k in range(len(chunks))]
        main = [*head, f"! motions in {len(subs)} called programs (a TP program holds "
                       f"{max_lines} lines)", *(f"CALL {n}" for n in subs)]
        if len(main) > max_lines:
            raise InputError("format", "fanuc_tp", f"{len(main)} lines of calls, a TP "
                             f"program holds {max_lines}",
                             "a larger `export_spacing` or `path_tol`")
        parts = [(name, main), *((n, [f"! part {k + 1} of {name}, called by it", *c])
                                 for k, (n, c) in enumerate(zip(subs, chunks, strict=True)))]
    when = (stamp or STAMP).strftime("DATE %y-%m-%d  TIME %H:%M:%S")
    xyzwpr = np.array([frame_to_xyzwpr(p) for p in program.poses])
    xyzwpr[:, 3:] = unwrap_wpr(xyzwpr[:, 3:])  # along the whole program, across its parts
    configs = ["", *fanuc_configs(program.robot, program.samples.q[1:len(program.poses)])]
    return [write_text(Path(folder) / f"{n}.ls",
                       _listing(program, n, mn, when, xyzwpr, configs, len(parts) == 1))
            for n, mn in parts]


def _listing(program: Program, name: str, mn: list[str], when: str,
             xyzwpr: FloatArray, configs: list[str], whole: bool) -> str:
    """The text of one ``.ls`` file: ``/PROG`` ... ``/END`` with every point (``whole``: the
    program is not split) or the points its ``/MN`` moves to (``xyzwpr``: every point's X, Y,
    Z [mm], W, P, R [deg] in the plate frame; ``configs``: every point's CONFIG, "" for the
    first, a joint point)."""
    lines = [f"/PROG  {name}", "/ATTR", "OWNER\t\t= MNEDITOR;",
             f"COMMENT\t\t= \"{program.header.plan_id[:16]}\";", "PROG_SIZE\t= 0;"]
    lines += [f"CREATE\t\t= {when};", f"MODIFIED\t= {when};", "FILE_NAME\t= ;",
              "VERSION\t\t= 0;", f"LINE_COUNT\t= {len(mn)};", "MEMORY_SIZE\t= 0;",
              "PROTECT\t\t= READ_WRITE;",
              "TCD:  STACK_SIZE\t= 0,", "      TASK_PRIORITY\t= 50,", "      TIME_SLICE\t= 0,",
              "      BUSY_LAMP_OFF\t= 0,", "      ABORT_REQUEST\t= 0,",
              "      PAUSE_REQUEST\t= 0;", "DEFAULT_GROUP\t= 1,*,*,*,*;",
              "CONTROL_CODE\t= 00000000 00000000;", "/MN"]
    for n, text in enumerate(mn, start=1):
        lines.append(f"{n:4d}:{'  ' if text[0] not in 'JL' else ''}{text} ;")
    lines.append("/POS")
    if whole:  # one program: every point of the plan, as always
        used = list(range(1, len(xyzwpr) + 1))
    else:  # one of a split program's files: the points its /MN moves to
        used = sorted({int(m.group(1)) for t in mn if (m := _POINT.match(t)) is not None})
    lines += [line for k in used
              for line in _position(program, k - 1, xyzwpr[k - 1], configs[k - 1])]
    lines.append("/END")
    return "\n".join(lines) + "\n"


def _position(program: Program, k: int, v: FloatArray, config: str) -> list[str]:
    """The ``/POS`` entry of point ``k`` (0-based): joint values for the first, else Cartesian
    ``v`` (X, Y, Z [mm], W, P, R [deg]) in the plate frame with its CONFIG (``config``, as
    :func:`~rfsw_plan.export.config.fanuc_config` writes it)."""
    o = program.options
    frame = f"\tUF : {o.base_number}, UT : {o.tool_number},"
    if k == 0:
        q0 = np.degrees(program.samples.q[0])
        return ["P[1]{", "   GP1:", frame,
                "\t" + ",\t".join(f"J{j + 1}= {number(q0[j], 6):>12} deg" for j in range(3))
                + ",",
                "\t" + ",\t".join(f"J{j + 1}= {number(q0[j], 6):>12} deg" for j in range(3, 6)),
                "};"]
    return [f"P[{k + 1}]{{", "   GP1:",
            f"{frame}\t\tCONFIG : '{config}',",
            f"\tX = {number(v[0], 4):>10}  mm,\tY = {number(v[1], 4):>10}  mm,"
            f"\tZ = {number(v[2], 4):>10}  mm,",
            f"\tW = {number(v[3], 5):>10} deg,\tP = {number(v[4], 5):>10} deg,"
            f"\tR = {number(v[5], 5):>10} deg",
            "};"]


# --------------------------------------------------------------------------------------------
# Reading

_NUM = r"[-+0-9.Ee]+"
_POS = re.compile(rf"P\[(\d+)\]\{{\s*GP1:\s*UF\s*:\s*(\d+),\s*UT\s*:\s*(\d+),\s*CONFIG\s*:\s*"
                  rf"'([^']*)',\s*X\s*=\s*({_NUM})\s*mm,\s*Y\s*=\s*({_NUM})\s*mm,\s*Z\s*=\s*"
                  rf"({_NUM})\s*mm,\s*W\s*=\s*({_NUM})\s*deg,\s*P\s*=\s*({_NUM})\s*deg,\s*R\s*="
                  rf"\s*({_NUM})\s*deg\s*\}};", re.S)
_JPOS = re.compile(r"P\[(\d+)\]\{\s*GP1:\s*UF\s*:\s*(\d+),\s*UT\s*:\s*(\d+),\s*"
                   + r",\s*".join(rf"J{j}\s*=\s*({_NUM})\s*deg" for j in range(1, 7))
                   + r"\s*\};", re.S)
_MOT = re.compile(r"^\s*\d+:([JL])\s+P\[(\d+)\]\s+(\S+)\s+(FINE|CNT\d+|CR\d+)\s*;\s*$")
_WAIT = re.compile(rf"^\s*\d+:\s*WAIT\s+({_NUM})\(sec\)\s*;\s*$")
_PR = re.compile(rf"^\s*\d+:\s*PR\[(\d+),(\d)\]=({_NUM})\s*;\s*$")
_CALL = re.compile(r"^\s*\d+:\s*CALL\s+(\w+)\s*;\s*$")
_REG = re.compile(rf"^\s*\d+:\s*R\[(\d+)\]=({_NUM})\s*;\s*$")
_SET = re.compile(r"^\s*\d+:\s*(UFRAME|UTOOL)\[(\d+)\]=PR\[(\d+)\]\s*;\s*$")


def _speed_of(text: str, regs: dict[int, float] | None = None) -> tuple[float, float]:
    """``3mm/sec`` -> (0.003 m/s, 0); ``R[20]mm/sec`` -> the register's value (``regs``: the
    values the program assigned so far); ``1250msec`` or ``1.25sec`` -> (0, 1.25 s); ``10%``
    -> (0, 0)."""
    r = re.match(r"^R\[(\d+)\]mm/sec$", text)
    if r is not None:
        return (regs or {}).get(int(r.group(1)), 0.0) * 1e-3, 0.0
    if text.endswith("mm/sec"):
        return float(text[:-6]) * 1e-3, 0.0
    if text.endswith("msec"):
        return 0.0, float(text[:-4]) * 1e-3
    if text.endswith("sec"):
        return 0.0, float(text[:-3])
    return 0.0, 0.0


def read_tp(path: str | Path) -> ReadProgram:
    """Re-read a ``.ls``: frames from the ``PR[i,j]`` lines, every motion and wait, following
    ``CALL`` into the called programs beside it (``<NAME>.ls`` in the same folder).

    Checks in every file the section order ``/PROG``, ``/ATTR``, ``/MN``, ``/POS``, ``/END``,
    the line numbering of ``/MN`` and that every moved-to ``P[n]`` is defined in its ``/POS``.
    """
    p = Path(path)
    text, mn = _read_ls(p)
    frames = _tp_frames(p, mn)
    files = [p]
    motions = _tp_motions(p, text, mn, files)
    return ReadProgram(frames["UTOOL"], frames["UFRAME"], motions, tuple(files))


def _read_ls(p: Path) -> tuple[str, list[str]]:
    """The text of a ``.ls`` file and its ``/MN`` lines, with the sections and the line
    numbering checked."""
    if not p.is_file():
        raise InputError(p, "", "missing", "a TP program written by rfsw-plan export")
    text = read_program_text(p)
    heads = [line.split()[0] for line in text.splitlines() if line.startswith("/")]
    if heads != ["/PROG", "/ATTR", "/MN", "/POS", "/END"]:
        raise InputError(p, "sections", f"got {heads}", "/PROG /ATTR /MN /POS /END in order")
    mn = text.split("/MN", 1)[1].split("/POS", 1)[0].strip().splitlines()
    for n, line in enumerate(mn, start=1):
        m = _NUMBERED.match(line)
        if m is None or m.group(1) != str(n):
            raise InputError(p, f"/MN line {n}", f"got {line.strip()[:40]!r}", f"'{n:4d}: ... ;'")
    return text, mn


_NUMBERED = re.compile(r"^\s*(\d+):.*;\s*$")  # an /MN line: its number (one pattern for all)
_REMARK = re.compile(rf"^\s*\d+:\s*!\s*(UFRAME|UTOOL)\[(\d+)\]\s+([XYZWPR])\s+({_NUM})\s*;\s*$")


def _tp_frames(p: Path, mn: list[str]) -> dict[str, FloatArray]:
    """UFRAME and UTOOL from the ``PR[i,j]=v`` and ``UFRAME[n]=PR[i]`` lines (``--cell-data``)
    or from the ``! UFRAME[n] X .. Y .. Z ..`` / ``W .. P .. R ..`` remarks."""
    regs: dict[int, FloatArray] = {}
    frames: dict[str, FloatArray] = {}
    remarks: dict[str, FloatArray] = {}
    for line in mn:
        if (r := _PR.match(line)) is not None:
            regs.setdefault(int(r.group(1)), np.zeros(6))[int(r.group(2)) - 1] = \
                float(r.group(3))
        elif (s := _SET.match(line)) is not None:
            if int(s.group(3)) not in regs:
                raise InputError(p, s.group(0).strip()[:40], "register not set",
                                 "PR[i,1..6] lines before it")
            frames[s.group(1)] = xyzwpr_to_frame(regs[int(s.group(3))])
        elif (m := _REMARK.match(line)) is not None:
            v = remarks.setdefault(m.group(1), np.full(6, np.nan))
            v["XYZWPR".index(m.group(3))] = float(m.group(4))
    for what, v in remarks.items():
        if what not in frames and np.all(np.isfinite(v)):
            frames[what] = xyzwpr_to_frame(v)
    if set(frames) != {"UFRAME", "UTOOL"}:
        raise InputError(p, "UFRAME/UTOOL", "not both stated",
                         "the '! UFRAME[n] X ..' ... '! UFRAME[n] R ..' remarks (or the "
                         "frames set through PR[] with `cell_data`)")
    return frames


def _tp_motions(p: Path, text: str, mn: list[str], files: list[Path],
                regs: dict[int, float] | None = None) -> list[ReadPoint]:
    """Every motion and wait of /MN with its /POS target, a called program's in its place
    (``files``: the files read so far; a program calling itself again is refused)."""
    cart = {int(m.group(1)): m.groups() for m in _POS.finditer(text)}
    joint = {int(m.group(1)): m.groups() for m in _JPOS.finditer(text)}
    motions: list[ReadPoint] = []
    regs = {} if regs is None else regs
    for line in mn:
        if (r := _REG.match(line)) is not None:
            regs[int(r.group(1))] = float(r.group(2))
            continue
        if (c := _CALL.match(line)) is not None:
            sub = p.with_name(f"{c.group(1)}.ls")
            if sub in files:
                raise InputError(p, c.group(0).strip()[:40], "calls a program already read",
                                 "each called program once")
            files.append(sub)
            sub_text, sub_mn = _read_ls(sub)
            motions += _tp_motions(sub, sub_text, sub_mn, files, regs)
            continue
        if (w := _WAIT.match(line)) is not None:
            motions.append(ReadPoint("WAIT", kind="wait", duration=float(w.group(1))))
            continue
        m = _MOT.match(line)
        if not m:
            continue
        k = int(m.group(2))
        speed, duration = _speed_of(m.group(3), regs)
        if k in joint:
            motions.append(ReadPoint(f"P[{k}]", q=np.radians([float(x) for x in joint[k][3:9]]),
                                     kind="joint"))
        elif k in cart:
            g = cart[k]
            motions.append(ReadPoint(f"P[{k}]", xyzwpr_to_frame([float(x) for x in g[4:10]]),
                                     g[3], speed=speed, duration=duration,
                                     kind="joint" if m.group(1) == "J" else "lin"))
        else:
            raise InputError(p, f"P[{k}]", "not defined in /POS", "a /POS entry per point")
    return motions
