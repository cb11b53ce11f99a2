"""ABB RAPID module (``.mod``) of a :class:`~rfsw_plan.export.program.Program`.

Format (ABB RAPID instructions, functions and data types reference): a ``MODULE ... ENDMODULE``
with ``PERS tooldata`` ([robhold, [[x, y, z], [q1, q2, q3, q4]], [mass, [cog], [aom], ix, iy,
iz]]), ``PERS wobjdata`` ([robhold, ufprog, ufmec, [[x, y, z], [q1..q4]] user frame,
[[0, 0, 0], [1, 0, 0, 0]] object frame]), ``CONST robtarget pN := [[x, y, z], [q1, q2, q3, q4],
[cf1, cf4, cf6, cfx], [9E+09 x 6]]`` with the quaternion w first (q1 = w), ``CONST speeddata``
and ``CONST zonedata`` (``fine`` for exact stops), ``PROC main()`` with ``MoveJ``, ``MoveL``
and ``WaitTime``. ``MoveL`` is never given ``\\Conc`` while the pin is in the material (the next
instruction must not start before the robot is on its path); the file starts with a ``%%%``
header as RobotStudio writes it.

The tool payload is a placeholder (mass 1 kg at the TCP) to be replaced by the real spindle's
load data; configuration data follow :mod:`rfsw_plan.export.config`.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from rfsw_plan.exceptions import InputError
from rfsw_plan.export.config import abb_confdata
from rfsw_plan.export.program import Program, controller_name, phase_comments
from rfsw_plan.export.readback import ReadPoint
from rfsw_plan.files import write_text
from rfsw_plan.numfmt import canonical_quaternion, fixed

FloatArray = NDArray[np.float64]

#: Joint-move speed to the approach point.
MOVEJ_SPEED = "v100"
#: Spindle placeholders (comments) before the plunge and at the retract.
SPINDLE_START = ("SPINDLE START placeholder: e.g. SetDO doSpindle, 1;",
                 "WaitDI diSpindleAtSpeed, 1;")
SPINDLE_STOP = ("SPINDLE STOP placeholder: e.g. SetDO doSpindle, 0;",)


def quat_wxyz(R: FloatArray) -> FloatArray:
    """Rotation matrix -> unit quaternion (w, x, y, z), w >= 0 (its first component that is not
    float noise positive: :func:`rfsw_plan.numfmt.canonical_quaternion`)."""
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.asarray(canonical_quaternion([w, x, y, z]))


def _pose(T: FloatArray) -> str:
    p = T[:3, 3] * 1e3
    q = quat_wxyz(T[:3, :3])
    return (f"[[{fixed(p[0], 4)},{fixed(p[1], 4)},{fixed(p[2], 4)}],"
            f"[{fixed(q[0], 9)},{fixed(q[1], 9)},{fixed(q[2], 9)},{fixed(q[3], 9)}]]")


def rapid_name(name: str) -> str:
    """A valid RAPID identifier (letters, digits, underscore; max 32; starts with a letter)."""
    return controller_name(name, max_len=32, prefix="m")


def write_rapid(program: Program, folder: str | Path) -> list[Path]:
    """Write ``<name>.mod`` atomically; returns its path."""
    name = rapid_name(program.header.name)
    robot = program.robot
    out = ["%%%", "  VERSION:1", "  LANGUAGE:ENGLISH", "%%%", "", f"MODULE {name}"]
    out += program.header.comments("  ! ")
    out += [f"  PERS tooldata tFSW := [TRUE,{_pose(program.tool)},"
            "[1,[0,0,1],[1,0,0,0],0,0,0]];  ! load data: placeholder, enter the spindle's",
            f"  PERS wobjdata wSeam := [FALSE,TRUE,\"\",{_pose(program.work)},"
            "[[0,0,0],[1,0,0,0]]];"]
    speeds: dict[float, str] = {}
    zones: dict[float, str] = {}
    for m in program.motions:
        if m.kind == "lin":
            v = round(m.speed * 1e3, 4)
            speeds.setdefault(v, f"vS{len(speeds) + 1}")
            if m.blend > 0:
                z = round(m.blend * 1e3, 4)
                zones.setdefault(z, f"zB{len(zones) + 1}")
    for v, nm in speeds.items():
        out.append(f"  CONST speeddata {nm} := [{fixed(max(v, 1e-4), 4)},30,5000,1000];  ! mm/s")
    for z, nm in zones.items():
        out.append(f"  CONST zonedata {nm} := [FALSE,{fixed(z, 4)},{fixed(1.5 * z, 4)},"
                   f"{fixed(1.5 * z, 4)},{fixed(0.15 * z, 4)},{fixed(1.5 * z, 4)},"
                   f"{fixed(0.15 * z, 4)}];  ! mm")
    for k, (pose, q) in enumerate(zip(program.poses, program.samples.q, strict=True)):
        cf = abb_confdata(robot, q)
        out.append(f"  CONST robtarget p{k + 1} := {_pose(pose)[:-1]},"
                   f"[{cf[0]},{cf[1]},{cf[2]},{cf[3]}],"
                   "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];")
    out.append("")
    out.append("  PROC main()")
    marks = program.phase_changes()
    for i, m in enumerate(program.motions):
        if i in marks:
            out += phase_comments(marks[i], "    !", SPINDLE_START, SPINDLE_STOP)
        p = f"p{m.point + 1}"
        if m.kind == "ptp":
            out.append(f"    MoveJ {p},{MOVEJ_SPEED},fine,tFSW\\WObj:=wSeam;")
        elif m.kind == "wait":
            out.append(f"    WaitTime\\InPos,{fixed(m.duration, 3)};")
        else:
            vname = speeds[round(m.speed * 1e3, 4)]
            zname = zones[round(m.blend * 1e3, 4)] if m.blend > 0 else "fine"
            out.append(f"    MoveL {p},{vname},{zname},tFSW\\WObj:=wSeam;")
    out += ["  ENDPROC", "ENDMODULE"]
    return [write_text(Path(folder) / f"{name}.mod", "\n".join(out) + "\n")]


_NUM = r"[-+0-9.Ee]+"
_POSE = rf"\[\[({_NUM}),({_NUM}),({_NUM})\],\[({_NUM}),({_NUM}),({_NUM}),({_NUM})\]\]"
_TOOL = re.compile(rf"PERS\s+tooldata\s+\w+\s*:=\s*\[TRUE,{_POSE}")
_WOBJ = re.compile(rf"PERS\s+wobjdata\s+\w+\s*:=\s*\[FALSE,TRUE,\"\",{_POSE}")
_ROBT = re.compile(rf"CONST\s+robtarget\s+(\w+)\s*:=\s*\[\[({_NUM}),({_NUM}),({_NUM})\],"
                   rf"\[({_NUM}),({_NUM}),({_NUM}),({_NUM})\],\[(-?\d+),(-?\d+),(-?\d+),(\d+)\]")
_MOVE = re.compile(r"^\s*Move[JL]\s+(\w+),")


def _frame(vals: tuple[str, ...]) -> FloatArray:
    x, y, z, w, qx, qy, qz = (float(v) for v in vals)
    n = math.sqrt(w * w + qx * qx + qy * qy + qz * qz)
    if abs(n - 1.0) > 1e-6:
        raise InputError("rapid", "quaternion", f"norm {n:.9f}", "a unit quaternion")
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([qx, qy, qz, w]).as_matrix()
    T[:3, 3] = np.array([x, y, z]) * 1e-3
    return T


def read_rapid(path: str | Path) -> tuple[FloatArray, FloatArray, list[ReadPoint]]:
    """Re-read a written ``.mod``: (tool (4, 4), work object (4, 4) [m], moved-to points)."""
    p = Path(path)
    text = p.read_text()
    t, w = _TOOL.search(text), _WOBJ.search(text)
    if t is None or w is None:
        raise InputError(p, "tooldata/wobjdata", "missing", "both declared")
    targets = {m.group(1): m.groups() for m in _ROBT.finditer(text)}
    points: list[ReadPoint] = []
    for line in text.splitlines():
        m = _MOVE.match(line)
        if not m:
            continue
        g = targets.get(m.group(1))
        if g is None:
            raise InputError(p, m.group(1), "not declared", "a robtarget per moved-to point")
        points.append(ReadPoint(g[0], _frame(g[1:8]), {"cf": tuple(int(x) for x in g[8:12])}))
    return _frame(t.groups()), _frame(w.groups()), points
