"""KUKA KRL program (``.src`` + ``.dat``) of a :class:`~rfsw_plan.export.program.Program`.

Format conventions followed (KUKA System Software 8.x operating and programming manuals for
system integrators, expert programming chapters; the structure of KUKA's own ``.src``
template and of common post-processors): ``&ACCESS``/``&REL`` attribute lines,
``DEF name( ) ... END`` in the ``.src`` with an ``INI`` fold calling ``BAS(#INITMOV, 0)``;
``DEFDAT name PUBLIC ... ENDDAT`` in the ``.dat`` holding the first point as ``DECL E6AXIS``
(a joint target: the first move cannot take another posture) and the others as ``DECL E6POS
XPn={X .., Y .., Z .., A .., B .., C .., S .., T .., E1 .. E6 ..}`` (mm, deg; R = Rz(A) Ry(B)
Rx(C), each angle unwrapped to follow the previous point's, so no ``+-180`` jumps);
``TOOL_DATA[t]``, ``LOAD_DATA[t]`` and ``BASE_DATA[b]`` assigned and selected with
``BAS(#TOOL, t)``/``BAS(#BASE, b)`` (KUKA's ``BAS.SRC``: it sets ``$TOOL``, ``$LOAD`` and
``$BASE``), ``$VEL.CP`` in m/s, ``$VEL.ORI1/2`` and ``$ACC.CP/ORI1/ORI2``, ``$APO.CDIS`` in mm
with ``C_DIS`` approximation; ``$VEL_AXIS``/``$ACC_AXIS`` in % for the PTP; ``WAIT SEC``;
comments after ``;``; identifiers of at most 24 characters. A program longer than
:data:`MAX_LINES` lines moves its motions into called sub-programs (``DEF`` ... ``END`` in the
same ``.src``, ``XPn`` in the shared ``.dat``).

``TOOL_DATA`` is the TCP in KUKA's FLANGE frame (x out of the flange), ``BASE_DATA`` the plate
frame in ROBROOT, ``LOAD_DATA`` the spindle's mass, centre of mass in FLANGE [mm] and inertia
[kg m^2]; points are in the base. S and T follow :mod:`rfsw_plan.export.config` (checked
against public sources in ``tests/data/vendor/posture_facts.csv``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Hashable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.export.config import kuka_status_turn, kuka_status_turns
from rfsw_plan.export.format import ControllerFormat, FormatLimits, ReadPoint, ReadProgram
from rfsw_plan.export.program import (
    Motion,
    Program,
    controller_name,
    number,
    payload_assumed,
    speed_note,
)
from rfsw_plan.files import read_program_text, write_text
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: PTP axis speed and acceleration for the move to the approach point [%].
PTP_PERCENT = 10
#: Orientation speed limits of LIN moves [deg/s] and accelerations [deg/s^2]: high enough
#: that the programmed CP speed, not the orientation, sets the pace.
VEL_ORI = (200, 200)
ACC_ORI = (100, 100)
#: KUKA's interpolation cycle (IPO) [s]: 12 ms on KR C4 (KSS 8), the cycle at which the
#: controller computes the path's set points; RSI's default IPO mode runs at it (public
#: source: industrialmonitordirect.com knowledge base, "KUKA Robot: Get Next Interpolation
#: Point During Motion" and "KUKA RSI Time Stamp Calculation": IPO 12 ms, IPO_FAST 4 ms).
#: No LIN or WAIT of a program is shorter (:attr:`ControllerFormat.cycle`).
IPO_CYCLE = 0.012
#: CP acceleration [m/s^2].
ACC_CP = 1.0
#: Lines of one .src above which the motions move into sub-programs (KRC4 practical limit).
MAX_LINES = 1400
#: Default hook comments (one line each).
DEFAULT_HOOKS = {
    "home_start": ("HOME: move to the cell's home position first (not known to rfsw-plan),",
                   "e.g. PTP XHOME; the joint move to XP1 follows"),
    "home_end": ("HOME: back to the cell's home position here, e.g. PTP XHOME",),
    "spindle_start": ("SPINDLE START: switch the spindle on and wait until it runs at the",
                      "process speed, e.g. $OUT[1] = TRUE and WAIT FOR $IN[1]"),
    "force_on": ("FORCE CONTROL: none (the plan is verified in position control)",),
    "force_off": ("FORCE CONTROL: none (position control)",),
    "spindle_stop": ("SPINDLE STOP: the pin has left the material (move above), e.g.",
                     "$OUT[1] = FALSE"),
}


def frame_to_xyzabc(T: FloatArray) -> tuple[float, ...]:
    """4x4 pose [m] -> (X, Y, Z [mm], A, B, C [deg]) with R = Rz(A) Ry(B) Rx(C)."""
    R = T[:3, :3]
    B = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    A = math.atan2(R[1, 0], R[0, 0])
    C = math.atan2(R[2, 1], R[2, 2])
    return (*(T[:3, 3] * 1e3), math.degrees(A), math.degrees(B), math.degrees(C))


def xyzabc_to_frame(v: tuple[float, ...] | list[float]) -> FloatArray:
    """Inverse of :func:`frame_to_xyzabc` (any number of turns in A, B, C)."""
    X, Y, Z, A, B, C = v
    a, b, c = (math.radians(x) for x in (A, B, C))
    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), \
        math.cos(c), math.sin(c)
    T = np.eye(4)
    T[:3, :3] = np.array([
        [ca * cb, ca * sb * sc - sa * cc, ca * sb * cc + sa * sc],
        [sa * cb, sa * sb * sc + ca * cc, sa * sb * cc - ca * sc],
        [-sb, cb * sc, cb * cc]])
    T[:3, 3] = np.array([X, Y, Z]) * 1e-3
    return T


def unwrap_angles(rows: FloatArray) -> FloatArray:
    """Angle rows [deg], (m, 3), each moved by whole turns to follow the previous row."""
    out = np.array(rows, dtype=float)
    for k in range(1, len(out)):
        out[k] -= 360.0 * np.round((out[k] - out[k - 1]) / 360.0)
    return out


def _frame(v: tuple[float, ...] | FloatArray) -> str:
    return "{" + ",".join(f"{k} {number(x, 6)}" for k, x in zip("XYZABC", v, strict=True)) + "}"


def krl_name(name: str) -> str:
    """A valid KRL module name (letters, digits, underscore; max 24; starts with a letter)."""
    return controller_name(name, max_len=24, prefix="P")


class KrlFormat(ControllerFormat):
    """KUKA KRL (KRC4, KSS 8): ``.src`` and ``.dat``."""

    name = "krl"
    order = 10
    description = "KUKA KRL (.src/.dat, KRC4)"
    suffix = ".src"
    maker = "KUKA"
    limits = FormatLimits(name_length=24, max_lines=MAX_LINES)
    cycle = IPO_CYCLE

    def file_name(self, program: Program) -> str:
        return krl_name(program.header.name) + ".src"

    def posture(self, robot: Robot, q: FloatArray) -> Hashable:
        return kuka_status_turn(robot, q)

    def postures(self, robot: Robot, Q: FloatArray) -> list[Hashable]:
        return list(kuka_status_turns(robot, Q))

    def write(self, program: Program, folder: Path) -> list[Path]:
        return write_krl(program, folder)

    def read(self, path: Path) -> ReadProgram:
        return read_krl(path)


def _header_extra(program: Program) -> list[str]:
    o = program.options
    if o.cell_data:
        data = (f"WRITES THE CELL'S DATA (export option cell_data): TOOL_DATA[{o.tool_number}], "
                f"LOAD_DATA[{o.tool_number}] and BASE_DATA[{o.base_number}] are overwritten "
                "below with the plan's values and stay so after the run")
        teach = "delete the BASE_DATA line, enter the taught values there instead"
    else:
        data = ("CELL DATA LEFT ALONE: $TOOL, $LOAD and $BASE are set below from this "
                "program's own values; no TOOL_DATA, LOAD_DATA or BASE_DATA is changed")
        teach = "enter the taught values in the $BASE line"
    return [
        *program.maker_note("KUKA"),
        data,
        *program.hook_notes("krl"),
        "BASE = the plate: origin on the first weld point, +X along the seam, +Y on the "
        f"plate, Z out of it. To use a base taught on the plate (3-point method), {teach} "
        "and run rfsw-plan check on this file: the pin depth then follows the taught plate",
    ]


def hook_lines(program: Program, hook: str) -> tuple[str, ...]:
    """The default comment of ``hook``: for a force-controlled plan the force-control hooks
    carry the set force and the ramp; no public KUKA source gives the KRL of the
    KUKA.ForceTorqueControl option for a constant axial force along a path, so they say so."""
    f, ramp = program.force_ramp()
    if f > 0 and hook == "force_on":
        return (f"FORCE CONTROL ON at contact (KUKA.ForceTorqueControl): axial set force "
                f"{f:.0f} N along the tool's +Z,",
                f"ramped 0 -> {f:.0f} N over the rest of the plunge ({ramp:.2f} s), held "
                "through the dwell and the weld.",
                "No public KUKA source gives the KRL call: write your cell's here")
    if f > 0 and hook == "force_off":
        return ("FORCE CONTROL OFF: the weld has ended, the pin is still in the plate and the "
                "retract follows;", "write your cell's force-control end here")
    return DEFAULT_HOOKS[hook]


def _load(program: Program) -> str:
    pl = program.payload
    if pl is None:
        return ""
    conv = program.robot.description.convention
    com = (np.linalg.inv(conv.flange) @ np.append(pl.com, 1.0))[:3] * 1e3
    inertia = pl.inertia if pl.inertia is not None else np.zeros(3)
    return (f"{{M {number(pl.mass, 3)},CM {_frame((*com, 0.0, 0.0, 0.0))},"
            f"J {{X {number(inertia[0], 4)},Y {number(inertia[1], 4)},"
            f"Z {number(inertia[2], 4)}}}}}")


def _init(program: Program) -> list[str]:
    o = program.options
    t, b = o.tool_number, o.base_number
    pl = program.payload
    load = _load(program)
    tool = _frame(frame_to_xyzabc(program.tool))
    base = _frame(frame_to_xyzabc(program.work))
    what = "" if pl is None else (
        f"spindle {number(pl.mass, 1)} kg{' ASSUMED' if payload_assumed(pl) else ''}, "
        + ("inertia UNKNOWN (0: set it by load identification)" if pl.inertia is None
           else "inertia known"))
    out = [";FOLD INI", "  BAS(#INITMOV, 0)", ";ENDFOLD (INI)"]
    if o.cell_data:
        out.append(f"  TOOL_DATA[{t}] = {tool}  ; TCP in FLANGE")
        out.append(f"  LOAD_DATA[{t}] = {load}  ; {what}" if pl is not None else
                   "  ; LOAD_DATA: PAYLOAD UNKNOWN, enter the spindle's load data")
        out += [f"  BASE_DATA[{b}] = {base}  ; plate in ROBROOT",
                f"  BAS(#TOOL, {t})", f"  BAS(#BASE, {b})"]
    else:
        out.append(f"  $TOOL = {tool}  ; TCP in FLANGE (this program's own)")
        out.append(f"  $LOAD = {load}  ; {what}" if pl is not None else
                   "  ; $LOAD: PAYLOAD UNKNOWN, enter the spindle's load data")
        out.append(f"  $BASE = {base}  ; plate in ROBROOT (this program's own)")
    out += ["  FOR I = 1 TO 6", f"    $VEL_AXIS[I] = {PTP_PERCENT}",
            f"    $ACC_AXIS[I] = {PTP_PERCENT}", "  ENDFOR",
            f"  $VEL.ORI1 = {VEL_ORI[0]}", f"  $VEL.ORI2 = {VEL_ORI[1]}",
            f"  $ACC.CP = {ACC_CP}", f"  $ACC.ORI1 = {ACC_ORI[0]}", f"  $ACC.ORI2 = {ACC_ORI[1]}",
            "  $APO.CDIS = 0.0", "  $ADVANCE = 3"]
    return out


def _motion_lines(program: Program, span: range, state: dict[str, float]) -> list[str]:
    """KRL lines of the motions in ``span``; ``state`` keeps the last $VEL.CP and $APO.CDIS."""
    out: list[str] = []
    marks = program.phase_changes()
    for i in span:
        m = program.motions[i]
        if i in marks:
            out.append(f"  ; ---- phase: {marks[i]}")
        p = f"XP{m.point + 1}"
        if m.kind == "hook":
            out += program.options.hooks.render(m.hook, "krl", hook_lines(program, m.hook),
                                                "  ", ";")
        elif m.kind == "joint":
            out.append(f"  PTP {p}  ; joint target (approach point)")
        elif m.kind == "wait":
            out.append(f"  WAIT SEC {m.duration:.3f}  ; hold {p} ({m.phase})")
        else:
            if m.pin_speed is not None:
                out.append(f"  ; {speed_note(m)}")
            speed = round(float(m.speed), 7)
            if speed != state.get("vel"):
                out.append(f"  $VEL.CP = {max(speed, 1e-7):.7f}  ; m/s")
                state["vel"] = speed
            if m.blend > 0:
                d = round(m.blend * 1e3, 4)
                if d != state.get("cdis"):
                    out.append(f"  $APO.CDIS = {d:.4f}  ; mm")
                    state["cdis"] = d
                out.append(f"  LIN {p} C_DIS")
            else:
                out.append(f"  LIN {p}")
    return out


def chunks(motions: tuple[Motion, ...], size: int) -> list[range]:
    """Index ranges of at most about ``size`` motions each, cut before a move (a hook or wait
    stays with the move before it)."""
    starts = [0]
    for i, m in enumerate(motions):
        if i - starts[-1] >= size and m.kind in ("lin", "joint"):
            starts.append(i)
    return [range(a, b) for a, b in zip(starts, [*starts[1:], len(motions)], strict=True)]


def write_krl(program: Program, folder: str | Path, max_lines: int = MAX_LINES) -> list[Path]:
    """Write ``<name>.src`` and ``<name>.dat`` atomically; returns both paths.

    Args:
        program: The program.
        folder: Output folder.
        max_lines: Lines of the ``.src`` above which the motions are split into called
            sub-programs of at most ``max_lines // 4`` motions (three lines each at most).
    """
    name = krl_name(program.header.name)
    folder = Path(folder)
    robot = program.robot
    dat = [f"&ACCESS RVP\n&REL 1\nDEFDAT {name} PUBLIC"]
    dat += program.header.comments("; ", extra=_header_extra(program))
    q0 = np.degrees(program.samples.q[0])
    dat.append("DECL E6AXIS XP1={" + ",".join(f"A{j + 1} {number(v, 6)}"
                                               for j, v in enumerate(q0))
               + ",E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}")
    v = np.array([frame_to_xyzabc(p) for p in program.poses])
    v[:, 3:] = unwrap_angles(v[:, 3:])
    st = kuka_status_turns(robot, program.samples.q[1:len(program.poses)])
    for k in range(1, len(program.poses)):
        s, t = st[k - 1]
        dat.append(f"DECL E6POS XP{k + 1}={{X {number(v[k, 0], 4)},Y {number(v[k, 1], 4)},"
                   f"Z {number(v[k, 2], 4)},A {number(v[k, 3], 5)},B {number(v[k, 4], 5)},"
                   f"C {number(v[k, 5], 5)},S {s},T {t},"
                   "E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}")
    dat.append("ENDDAT")

    src = [f"&ACCESS RVP\n&REL 1\nDEF {name}( )", "  DECL INT I"]
    src += program.header.comments("  ; ", extra=_header_extra(program))
    src += _init(program)
    state: dict[str, float] = {}
    body = _motion_lines(program, range(len(program.motions)), state)
    subs: list[list[str]] = []
    if len(src) + len(body) > max_lines:
        # a motion writes at most three lines ($VEL.CP, $APO.CDIS, LIN)
        for c, span in enumerate(chunks(program.motions, max(max_lines // 4, 10))):
            sub = f"{name[:20]}_S{c + 1}"
            src.append(f"  {sub}( )")
            # each sub-program restates speed and blend: it may be run after a block selection
            subs.append([f"DEF {sub}( )", *_motion_lines(program, span, {}), "END"])
    else:
        src += body
    src.append("END")
    for sub_lines in subs:
        src += ["", *sub_lines]
    src_path = write_text(folder / f"{name}.src", "\n".join(src) + "\n")
    dat_path = write_text(folder / f"{name}.dat", "\n".join(dat) + "\n")
    return [src_path, dat_path]


# --------------------------------------------------------------------------------------------
# Reading


_DECL = re.compile(r"DECL\s+(E6POS|E6AXIS)\s+(\w+)\s*=\s*\{([^}]*)\}", re.I)
_FRAME_SET = re.compile(r"^\s*(TOOL_DATA|BASE_DATA|\$TOOL|\$BASE)(?:\[\d+\])?\s*=\s*\{([^}]*)\}",
                        re.I | re.M)
_MOVE = re.compile(r"^\s*(PTP|LIN)\s+(\w+)(\s+C_DIS)?\s*(;.*)?$", re.I)
_VEL = re.compile(r"^\s*\$VEL\.CP\s*=\s*([-+0-9.Ee]+)", re.I)
_WAIT = re.compile(r"^\s*WAIT\s+SEC\s+([-+0-9.Ee]+)", re.I)
_CALL = re.compile(r"^\s*(\w+)\s*\(\s*\)\s*(;.*)?$")
_DEF = re.compile(r"^\s*DEF\s+(\w+)\s*\(\s*\)", re.I)


def _agg(body: str, where: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for item in body.split(","):
        parts = item.split()
        if len(parts) != 2:
            raise InputError(where, item.strip()[:40], "malformed aggregate component",
                             "'X 1.0'")
        try:
            out[parts[0].upper()] = float(parts[1])
        except ValueError:
            raise InputError(where, item.strip()[:40], "not a number", "'X 1.0'") from None
    return out


def _routines(text: str) -> dict[str, list[str]]:
    """DEF name -> its lines (the main routine first)."""
    out: dict[str, list[str]] = {}
    current: list[str] | None = None
    for line in text.splitlines():
        d = _DEF.match(line)
        if d:
            current = out.setdefault(d.group(1).upper(), [])
            continue
        if re.match(r"^\s*END\s*$", line, re.I):
            current = None
            continue
        if current is not None:
            current.append(line)
    return out


def read_krl(src: str | Path) -> ReadProgram:
    """Re-read a ``.src`` (and its ``.dat`` beside it), following called sub-programs.

    Raises:
        InputError: Missing frames or declarations, malformed aggregates (one line).
    """
    src = Path(src)
    dat = src.with_suffix(".dat")
    if not dat.is_file():
        raise InputError(dat, "", "missing beside the .src", "the program's .dat")
    text = read_program_text(src)
    frames = {m.group(1).upper().lstrip("$").replace("_DATA", ""): _agg(m.group(2), str(src))
              for m in _FRAME_SET.finditer(text)}
    if set(frames) != {"TOOL", "BASE"}:
        raise InputError(src, "$TOOL/$BASE", "not both assigned",
                         "the tool and base values in the program ($TOOL = {...}, $BASE = "
                         "{...}, or TOOL_DATA[n]/BASE_DATA[n] with `cell_data`)")
    tool, base = (xyzabc_to_frame([frames[f].get(k, 0.0) for k in "XYZABC"])
                  for f in ("TOOL", "BASE"))
    decl = {m.group(2).upper(): (m.group(1).upper(), _agg(m.group(3), str(dat)))
            for m in _DECL.finditer(read_program_text(dat))}
    routines = _routines(text)
    if not routines:
        raise InputError(src, "DEF", "no routine", "DEF name( ) ... END")
    motions: list[ReadPoint] = []
    _read_routine(src, next(iter(routines)), routines, decl, motions, {"vel": 0.0})
    return ReadProgram(tool, base, motions, (src, dat))


def _read_routine(src: Path, name: str, routines: dict[str, list[str]],
                  decl: dict[str, tuple[str, dict[str, float]]], out: list[ReadPoint],
                  state: dict[str, float]) -> None:
    for line in routines[name]:
        code = line.split(";", 1)[0]
        if (v := _VEL.match(code)) is not None:
            state["vel"] = float(v.group(1))
        elif (w := _WAIT.match(code)) is not None:
            out.append(ReadPoint("WAIT", kind="wait", duration=float(w.group(1))))
        elif (c := _CALL.match(code)) is not None and c.group(1).upper() in routines:
            _read_routine(src, c.group(1).upper(), routines, decl, out, state)
        elif (m := _MOVE.match(line)) is not None:
            out.append(_point(src, m.group(1).upper(), m.group(2).upper(), decl, state["vel"]))


def _point(src: Path, move: str, name: str, decl: dict[str, tuple[str, dict[str, float]]],
           vel: float) -> ReadPoint:
    if name not in decl:
        raise InputError(src.with_suffix(".dat"), name, "not declared",
                         "a DECL E6POS or E6AXIS for every moved-to point")
    kind, a = decl[name]
    if kind == "E6AXIS":
        q = np.radians([a.get(f"A{j + 1}", 0.0) for j in range(6)])
        return ReadPoint(name, q=q, kind="joint")
    pose = xyzabc_to_frame([a[k] for k in "XYZABC"])
    return ReadPoint(name, pose, (int(a["S"]), int(a["T"])), speed=vel,
                     kind="joint" if move == "PTP" else "lin")
