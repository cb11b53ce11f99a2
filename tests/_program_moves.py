"""The moves and waits of a written KRL, TP or RAPID program, read from the file's own text
(the positions and speeds it states), independently of the export's objects and readers: a
move's duration is its written length over its written speed (mm / (mm/s)), a wait's its
written time. Used by ``tests/test_export_cycle.py`` (every move at least the controller's
interpolation cycle) and to measure the bundled programs."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Move:
    """One instruction: ``lin`` (a linear move, from the previous Cartesian point) or ``wait``.

    Attributes:
        kind: ``lin`` or ``wait``.
        duration: Written length / written speed, or the written wait [s].
        label: The target's name (``XP22``, ``P[22]``, ``p22``), or the point a wait holds.
        line: 1-based line of the instruction in its file.
    """

    kind: str
    duration: float
    label: str
    line: int


_NUM = r"[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?"


def _length(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    return math.dist(a, b)


def krl_moves(src: Path) -> list[Move]:
    """Moves of a ``.src`` (positions from its ``.dat``: ``DECL E6POS XPn={X ..,Y ..,Z ..``,
    speeds ``$VEL.CP`` [m/s], waits ``WAIT SEC``). The first move after a joint target
    (``PTP``: its Cartesian point is not written) is not measured."""
    dat = src.with_suffix(".dat").read_text(encoding="utf-8")
    pos = {m[0]: (float(m[1]), float(m[2]), float(m[3])) for m in re.findall(
        rf"DECL E6POS (XP\d+)={{X ({_NUM}),Y ({_NUM}),Z ({_NUM})", dat)}
    out: list[Move] = []
    vel, last = 0.0, None
    for k, line in enumerate(src.read_text(encoding="utf-8").splitlines(), 1):
        code = line.split(";", 1)[0].strip()
        if m := re.fullmatch(rf"\$VEL\.CP = ({_NUM})", code):
            vel = float(m[1]) * 1e3
        elif m := re.fullmatch(r"PTP (XP\d+)", code):
            last = pos.get(m[1])
        elif m := re.fullmatch(r"LIN (XP\d+)(?: C_DIS)?", code):
            p = pos[m[1]]
            if last is not None:
                out.append(Move("lin", _length(last, p) / vel, m[1], k))
            last = p
        elif m := re.fullmatch(rf"WAIT SEC ({_NUM})", code):
            out.append(Move("wait", float(m[1]), line.split("hold ", 1)[-1], k))
    return out


def tp_moves(ls: Path) -> list[Move]:
    """Moves of a ``.ls`` (positions from its ``/POS`` section, speeds ``R[n]=v`` then
    ``L P[k] R[n]mm/sec`` or ``L P[k] v mm/sec``, waits ``WAIT t(sec)``). The first move after
    a ``J`` move is not measured."""
    text = ls.read_text(encoding="utf-8")
    pos = {f"P[{m[0]}]": (float(m[1]), float(m[2]), float(m[3])) for m in re.findall(
        rf"P\[(\d+)\]\{{[^}}]*?X = +({_NUM}) +mm,\s*Y = +({_NUM}) +mm,\s*Z = +({_NUM}) +mm",
        text)}
    out: list[Move] = []
    reg: dict[str, float] = {}
    last = None
    for k, line in enumerate(text.splitlines(), 1):
        code = re.sub(r"^\s*\d+:\s*", "", line).rstrip(" ;")
        if m := re.fullmatch(rf"(R\[\d+\])=({_NUM})", code):
            reg[m[1]] = float(m[2])
        elif m := re.match(r"J (P\[\d+\])", code):
            last = pos.get(m[1])
        elif m := re.match(rf"L (P\[\d+\]) (?:(R\[\d+\])|({_NUM}))mm/sec", code):
            p = pos[m[1]]
            v = reg[m[2]] if m[2] else float(m[3])
            if last is not None:
                out.append(Move("lin", _length(last, p) / v, m[1], k))
            last = p
        elif m := re.fullmatch(rf"WAIT ({_NUM})\(sec\)", code):
            out.append(Move("wait", float(m[1]), "", k))
    return out


def rapid_moves(mod: Path) -> list[Move]:
    """Moves of a ``.mod`` (positions ``robtarget pN := [[x,y,z],..``, speeds ``\\V:=v``
    [mm/s], waits ``WaitTime``). The first move after a ``MoveAbsJ`` is not measured."""
    text = mod.read_text(encoding="utf-8")
    pos = {m[0]: (float(m[1]), float(m[2]), float(m[3])) for m in re.findall(
        rf"robtarget (\w+) := \[\[({_NUM}),({_NUM}),({_NUM})\]", text)}
    out: list[Move] = []
    last = None
    for k, line in enumerate(text.splitlines(), 1):
        code = line.split("!", 1)[0].strip()
        if code.startswith("MoveAbsJ"):
            last = None
        elif m := re.match(rf"MoveL (\w+),v\d+\\V:=({_NUM}),", code):
            p = pos[m[1]]
            if last is not None:
                out.append(Move("lin", _length(last, p) / float(m[2]), m[1], k))
            last = p
        elif m := re.fullmatch(rf"WaitTime(?:\\InPos)?,({_NUM});", code):
            out.append(Move("wait", float(m[1]), "", k))
    return out


#: Main-file suffix -> reader.
READERS = {".src": krl_moves, ".ls": tp_moves, ".mod": rapid_moves}


def program_moves(path: Path) -> list[Move]:
    """The moves of a KRL, TP or RAPID main file (by its suffix)."""
    return READERS[path.suffix.lower()](path)
