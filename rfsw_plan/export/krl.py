"""KUKA KRL program (``.src`` + ``.dat``) of a :class:`~rfsw_plan.export.program.Program`.

Format conventions followed (KUKA System Software 8.x operating and programming manuals for
system integrators, expert programming chapters): ``&ACCESS``/``&REL`` attribute lines,
``DEF name( ) ... END`` in the ``.src`` and ``DEFDAT name PUBLIC ... ENDDAT`` in the ``.dat``
holding the points as ``DECL E6POS XPn={X .., Y .., Z .., A .., B .., C .., S .., T .., E1 ..
E6 ..}`` (mm, deg; orientation A, B, C about z, y', x'': R = Rz(A) Ry(B) Rx(C));
``$TOOL``/``$BASE`` as ``FRAME`` aggregates; ``$VEL.CP`` in m/s, ``$APO.CDIS`` in mm with
``C_DIS`` approximation; ``$VEL_AXIS``/``$ACC_AXIS`` in % for the PTP; ``WAIT SEC``; comments
after ``;``; identifiers of at most 24 characters.

``$TOOL`` is the TCP in KUKA's FLANGE frame (x out of the flange) and ``$BASE`` the seam work
object in ROBROOT; points are in ``$BASE``. S and T follow :mod:`rfsw_plan.export.config`.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.export.config import kuka_status_turn
from rfsw_plan.export.program import Program, controller_name, phase_comments
from rfsw_plan.export.readback import ReadPoint
from rfsw_plan.files import write_text
from rfsw_plan.numfmt import angle, fixed

FloatArray = NDArray[np.float64]

#: PTP axis speed and acceleration for the move to the approach point [%].
PTP_PERCENT = 10
#: Spindle placeholders (comments) before the plunge and at the retract.
SPINDLE_START = ("SPINDLE START (placeholder): switch the spindle on and wait until it",
                 "runs at the process speed before the plunge, e.g. $OUT[1] = TRUE",
                 "WAIT FOR $IN[1]")
SPINDLE_STOP = ("SPINDLE STOP (placeholder): after the pin has left the material,",
                "e.g. $OUT[1] = FALSE")


def frame_to_xyzabc(T: FloatArray) -> tuple[float, ...]:
    """4x4 pose [m] -> (X, Y, Z [mm], A, B, C [deg]) with R = Rz(A) Ry(B) Rx(C)."""
    R = T[:3, :3]
    B = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    A = math.atan2(R[1, 0], R[0, 0])
    C = math.atan2(R[2, 1], R[2, 2])
    return (*(T[:3, 3] * 1e3), math.degrees(A), math.degrees(B), math.degrees(C))


def xyzabc_to_frame(v: tuple[float, ...] | list[float]) -> FloatArray:
    """Inverse of :func:`frame_to_xyzabc`."""
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


def _num(x: float, digits: int) -> str:
    """Fixed-point text without a negative zero (:func:`rfsw_plan.numfmt.fixed`)."""
    return fixed(x, digits)


def _frame(v: tuple[float, ...]) -> str:
    return "{" + ", ".join(f"{k} {_num(x, 6) if k in 'XYZ' else angle(x, 6)}"
                          for k, x in zip("XYZABC", v, strict=True)) + "}"


def krl_name(name: str) -> str:
    """A valid KRL module name (letters, digits, underscore; max 24; starts with a letter)."""
    return controller_name(name, max_len=24, prefix="P")


def write_krl(program: Program, folder: str | Path) -> list[Path]:
    """Write ``<name>.src`` and ``<name>.dat`` atomically; returns both paths."""
    name = krl_name(program.header.name)
    folder = Path(folder)
    robot = program.robot
    dat = [f"&ACCESS RVP\n&REL 1\nDEFDAT {name} PUBLIC"]
    dat += program.header.comments("; ")
    for k, (pose, q) in enumerate(zip(program.poses, program.samples.q, strict=True)):
        s, t = kuka_status_turn(robot, q)
        v = frame_to_xyzabc(pose)
        dat.append(f"DECL E6POS XP{k + 1}={{X {_num(v[0], 4)},Y {_num(v[1], 4)},"
                   f"Z {_num(v[2], 4)},A {angle(v[3], 5)},B {angle(v[4], 5)},"
                   f"C {angle(v[5], 5)},S {s},T {t},"
                   "E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}")
    dat.append("ENDDAT")

    src = [f"&ACCESS RVP\n&REL 1\nDEF {name}( )", "  DECL INT I"]
    src += program.header.comments("  ; ")
    src += [f"  $TOOL = {_frame(frame_to_xyzabc(program.tool))}  ; TCP in FLANGE",
            f"  $BASE = {_frame(frame_to_xyzabc(program.work))}  ; seam work object in ROBROOT",
            "  FOR I = 1 TO 6",
            f"    $VEL_AXIS[I] = {PTP_PERCENT}",
            f"    $ACC_AXIS[I] = {PTP_PERCENT}",
            "  ENDFOR",
            "  $ACC.CP = 0.5",
            "  $ADVANCE = 3"]
    marks = program.phase_changes()
    vel: float | None = None
    cdis: float | None = None
    for i, m in enumerate(program.motions):
        if i in marks:
            src += phase_comments(marks[i], "  ;", SPINDLE_START, SPINDLE_STOP)
        p = f"XP{m.point + 1}"
        if m.kind == "ptp":
            src.append(f"  PTP {p}  ; approach point, joint move")
        elif m.kind == "wait":
            src.append(f"  WAIT SEC {fixed(m.duration, 3)}  ; hold {p} ({m.phase})")
        else:
            speed = round(float(m.speed), 7)
            if speed != vel:
                src.append(f"  $VEL.CP = {fixed(max(speed, 1e-7), 7)}  ; m/s")
                vel = speed
            if m.blend > 0:
                d = round(m.blend * 1e3, 4)
                if d != cdis:
                    src.append(f"  $APO.CDIS = {fixed(d, 4)}  ; mm")
                    cdis = d
                src.append(f"  LIN {p} C_DIS")
            else:
                src.append(f"  LIN {p}")
    src.append("END")
    src_path = write_text(folder / f"{name}.src", "\n".join(src) + "\n")
    dat_path = write_text(folder / f"{name}.dat", "\n".join(dat) + "\n")
    return [src_path, dat_path]


_E6POS = re.compile(r"DECL\s+E6POS\s+(\w+)\s*=\s*\{([^}]*)\}", re.I)
_FRAME = re.compile(r"\$(TOOL|BASE)\s*=\s*\{([^}]*)\}", re.I)
_MOVE = re.compile(r"^\s*(PTP|LIN)\s+(\w+)(\s+C_DIS)?\s*(;.*)?$", re.I)


def _agg(body: str, where: str) -> dict[str, float]:
    out: dict[str, float] = {}
    for item in body.split(","):
        parts = item.split()
        if len(parts) != 2:
            raise InputError(where, item.strip(), "malformed aggregate component", "'X 1.0'")
        out[parts[0].upper()] = float(parts[1])
    return out


def read_krl(src: str | Path) -> tuple[FloatArray, FloatArray, list[ReadPoint]]:
    """Re-read a written ``.src`` (and its ``.dat`` beside it).

    Returns:
        ``(tool, base, points)``: $TOOL (4, 4) and $BASE (4, 4) [m], and the moved-to points in
        program order with their pose in $BASE [m] and the S/T configuration.
    """
    src = Path(src)
    dat = src.with_suffix(".dat")
    text = src.read_text()
    frames = {m.group(1).upper(): _agg(m.group(2), str(src)) for m in _FRAME.finditer(text)}
    if set(frames) != {"TOOL", "BASE"}:
        raise InputError(src, "$TOOL/$BASE", "missing", "both frames set in the program")
    tool, base = (xyzabc_to_frame([frames[f][k] for k in "XYZABC"]) for f in ("TOOL", "BASE"))
    decl = {m.group(1).upper(): _agg(m.group(2), str(dat))
            for m in _E6POS.finditer(dat.read_text())}
    points: list[ReadPoint] = []
    for line in text.splitlines():
        m = _MOVE.match(line)
        if not m:
            continue
        name = m.group(2).upper()
        if name not in decl:
            raise InputError(dat, name, "not declared", "a DECL E6POS for every moved-to point")
        a = decl[name]
        pose = xyzabc_to_frame([a[k] for k in "XYZABC"])
        points.append(ReadPoint(name, pose, {"S": int(a["S"]), "T": int(a["T"])}))
    return tool, base, points
