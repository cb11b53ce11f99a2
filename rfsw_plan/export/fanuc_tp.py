"""FANUC TP program in ASCII form (``.ls``) of a :class:`~rfsw_plan.export.program.Program`.

Format conventions followed (FANUC R-30iB HandlingTool operator's manual, program structure
and the ASCII ``.ls`` listing that ``ASCII Upload`` / ``MAKETP`` accept): the sections
``/PROG name``, ``/ATTR`` (``OWNER``, ``COMMENT``, ``PROG_SIZE``, ``CREATE``, ``MODIFIED``,
``FILE_NAME``, ``VERSION``, ``LINE_COUNT``, ``MEMORY_SIZE``, ``PROTECT``, ``TCD``,
``DEFAULT_GROUP``, ``CONTROL_CODE``), ``/MN`` with numbered lines ``   n:  instruction ;``,
``/POS`` with ``P[n]{ GP1: UF : u, UT : t, CONFIG : 'N U T, 0, 0, 0', X = .. mm, Y, Z, W = ..
deg, P, R };`` and ``/END``; motion lines ``J P[n] v% FINE``, ``L P[n] v mm/sec FINE|CNTc`` or
``L P[n] t sec FINE`` (motion time, for speeds that are not whole mm/sec), ``WAIT t(sec)``,
remarks ``! text``, ``UFRAME_NUM``/``UTOOL_NUM``; program names of at most 8 upper-case
characters in the ``/PROG`` line are not required here (R-30iB allows 36).

W, P, R (R = Rz(R) Ry(P) Rx(W), deg) are unwrapped along the program: each angle is moved by
whole turns to be within 180 deg of the previous point's, so no motion sees a +-180 jump.
UF and UT are frame numbers; their values (the seam work object in the world frame and the
TCP in the faceplate frame) are in the header remarks, to be entered on the pendant.
"""

from __future__ import annotations

import math
import re
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.export.config import fanuc_config
from rfsw_plan.export.program import Program, controller_name, phase_comments
from rfsw_plan.export.readback import ReadPoint
from rfsw_plan.files import write_text
from rfsw_plan.numfmt import angle, fixed

FloatArray = NDArray[np.float64]

#: User frame and tool frame numbers the program uses.
UFRAME = 1
UTOOL = 1
#: Joint speed of the move to the approach point [%].
J_PERCENT = 10
#: Spindle placeholders (remarks) before the plunge and at the retract.
SPINDLE_START = ("SPINDLE START placeholder:", " e.g. DO[1]=ON and WAIT DI[1]=ON")
SPINDLE_STOP = ("SPINDLE STOP placeholder:", " e.g. DO[1]=OFF")


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
    out = np.array(wpr, dtype=float)
    for k in range(1, len(out)):
        out[k] -= 360.0 * np.round((out[k] - out[k - 1]) / 360.0)
    return out


def tp_name(name: str) -> str:
    """A valid TP program name (upper-case letters, digits, underscore; starts with a letter)."""
    return controller_name(name, max_len=36, prefix="P", upper=True)


def _speed(speed: float, duration: float) -> str:
    """``v mm/sec`` when the speed is a whole mm/s (within 0.1 %), else the motion time."""
    v = speed * 1e3
    if v >= 1.0 and abs(v - round(v)) <= 1e-3 * v and round(v) <= 2000:
        return f"{round(v)}mm/sec"
    return f"{fixed(duration, 2)}sec"


def write_tp(program: Program, folder: str | Path, stamp: datetime | None = None) -> list[Path]:
    """Write ``<name>.ls`` atomically; returns its path (``stamp``: CREATE/MODIFIED time,
    default now)."""
    name = tp_name(program.header.name)
    robot = program.robot
    xyzwpr = np.array([frame_to_xyzwpr(p) for p in program.poses])
    xyzwpr[:, 3:] = unwrap_wpr(xyzwpr[:, 3:])
    uf = frame_to_xyzwpr(program.work)
    ut = frame_to_xyzwpr(program.tool)

    mn = program.header.comments("! ", max_len=60)
    mn += [f"! UFRAME {UFRAME} = seam work object in world:",
           "!  " + " ".join(f"{k}={_num(x, 3) if k in 'XYZ' else angle(x, 3)}"
                           for k, x in zip("XYZWPR", uf, strict=True)),
           f"! UTOOL {UTOOL} = TCP in faceplate:",
           "!  " + " ".join(f"{k}={_num(x, 3) if k in 'XYZ' else angle(x, 3)}"
                           for k, x in zip("XYZWPR", ut, strict=True)),
           f"UFRAME_NUM={UFRAME}", f"UTOOL_NUM={UTOOL}"]
    marks = program.phase_changes()
    for i, m in enumerate(program.motions):
        if i in marks:
            mn += phase_comments(marks[i], "!", SPINDLE_START, SPINDLE_STOP)
        p = f"P[{m.point + 1}]"
        if m.kind == "ptp":
            mn.append(f"J {p} {J_PERCENT}% FINE")
        elif m.kind == "wait":
            mn.append(f"WAIT {fixed(m.duration, 2)}(sec)")
        else:
            term = "FINE"
            if m.blend > 0:
                seg = [x for x in _adjacent(program, i)]
                cap = 0.4 * min(seg) if seg else m.blend
                term = f"CNT{max(1, min(100, round(100 * m.blend / cap)))}"
            mn.append(f"L {p} {_speed(m.speed, m.duration)} {term}")

    lines = [f"/PROG  {name}", "/ATTR", "OWNER\t\t= MNEDITOR;",
             f"COMMENT\t\t= \"{program.header.plan_id[:16]}\";", "PROG_SIZE\t= 0;"]
    when = (stamp or datetime.now(UTC)).strftime("DATE %y-%m-%d  TIME %H:%M:%S")
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
    for k, (v, q) in enumerate(zip(xyzwpr, program.samples.q, strict=True)):
        lines += [f"P[{k + 1}]{{", "   GP1:",
                  f"\tUF : {UFRAME}, UT : {UTOOL},\t\tCONFIG : '{fanuc_config(robot, q)}',",
                  f"\tX = {_num(v[0], 4):>10}  mm,\tY = {_num(v[1], 4):>10}  mm,"
                  f"\tZ = {_num(v[2], 4):>10}  mm,",
                  f"\tW = {_num(v[3], 5):>10} deg,\tP = {_num(v[4], 5):>10} deg,"
                  f"\tR = {_num(v[5], 5):>10} deg",
                  "};"]
    lines.append("/END")
    return [write_text(Path(folder) / f"{name}.ls", "\n".join(lines) + "\n")]


def _num(x: float, digits: int) -> str:
    """Fixed-point text without a negative zero (:func:`rfsw_plan.numfmt.fixed`)."""
    return fixed(x, digits)


def _adjacent(program: Program, i: int) -> list[float]:
    """Lengths [m] of the segments before and after motion i's target."""
    m = program.motions[i]
    P = program.poses[:, :3, 3]
    out = []
    if m.point > 0:
        out.append(float(np.linalg.norm(P[m.point] - P[m.point - 1])))
    if m.point + 1 < len(P):
        out.append(float(np.linalg.norm(P[m.point + 1] - P[m.point])))
    return out


_POS = re.compile(r"P\[(\d+)\]\{\s*GP1:\s*UF\s*:\s*(\d+),\s*UT\s*:\s*(\d+),\s*CONFIG\s*:\s*"
                  r"'([^']*)',\s*X\s*=\s*(\S+)\s*mm,\s*Y\s*=\s*(\S+)\s*mm,\s*Z\s*=\s*(\S+)\s*mm,"
                  r"\s*W\s*=\s*(\S+)\s*deg,\s*P\s*=\s*(\S+)\s*deg,\s*R\s*=\s*(\S+)\s*deg\s*\};",
                  re.S)
_MOT = re.compile(r"^\s*\d+:([JL])\s+P\[(\d+)\]\s+(\S+)\s+(FINE|CNT\d+)\s*;\s*$")
_REMARK_FRAME = re.compile(r"!\s+X=(\S+) Y=(\S+) Z=(\S+) W=(\S+) P=(\S+) R=(\S+) ;")


def read_tp(path: str | Path) -> tuple[FloatArray, FloatArray, list[ReadPoint]]:
    """Re-read a written ``.ls``: (UTOOL (4, 4), UFRAME (4, 4) [m], points in program order).

    Checks the section order ``/PROG``, ``/ATTR``, ``/MN``, ``/POS``, ``/END``, the line
    numbering of ``/MN`` and that every moved-to ``P[n]`` is defined in ``/POS``.
    """
    p = Path(path)
    text = p.read_text()
    heads = [line.split()[0] for line in text.splitlines() if line.startswith("/")]
    if heads != ["/PROG", "/ATTR", "/MN", "/POS", "/END"]:
        raise InputError(p, "sections", f"got {heads}", "/PROG /ATTR /MN /POS /END in order")
    mn = text.split("/MN", 1)[1].split("/POS", 1)[0].strip().splitlines()
    for n, line in enumerate(mn, start=1):
        if not re.match(rf"^\s*{n}:.*;\s*$", line):
            raise InputError(p, f"/MN line {n}", f"got {line!r}", f"'{n:4d}: ... ;'")
    frames = [m.groups() for m in _REMARK_FRAME.finditer(text)]
    if len(frames) < 2:
        raise InputError(p, "UFRAME/UTOOL", "values missing", "the header remarks")
    uf, ut = (xyzwpr_to_frame([float(x) for x in f]) for f in frames[:2])
    pos = {int(m.group(1)): m.groups() for m in _POS.finditer(text)}
    points: list[ReadPoint] = []
    for line in mn:
        m = _MOT.match(line)
        if not m:
            continue
        k = int(m.group(2))
        if k not in pos:
            raise InputError(p, f"P[{k}]", "not defined in /POS", "a /POS entry per point")
        g = pos[k]
        pose = xyzwpr_to_frame([float(x) for x in g[4:10]])
        points.append(ReadPoint(f"P[{k}]", pose, {"CONFIG": g[3], "UF": int(g[1]),
                                                  "UT": int(g[2])}))
    return ut, uf, points
