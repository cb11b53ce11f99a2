"""ABB RAPID module (``.mod``) of a :class:`~rfsw_plan.export.program.Program`.

Format (ABB RAPID instructions, functions and data types reference; IRC5): a ``MODULE ...
ENDMODULE`` without the ``%%%`` header of S4 files (RobotWare 5/6 load a module that starts
with ``MODULE``; ``rapidchecker`` parses the file exactly as written). Its data are
module-local (``LOCAL``), so loading it never clashes with the controller's other modules, and
its procedure is named after the program with ``_run`` (not ``main``, which the controller's
main module owns, and not the module's own name):

* ``LOCAL PERS tooldata`` ([robhold, [[x, y, z], [q1, q2, q3, q4]], [mass, [cog], [aom], ix,
  iy, iz]]): the TCP in tool0 and the spindle's load (mass [kg], centre of gravity in tool0
  [mm], inertia [kg m^2]) from the robot file;
* ``LOCAL PERS wobjdata`` ([robhold, ufprog, ufmec, user frame, object frame]): the plate;
* ``LOCAL CONST jointtarget`` of the first point, reached with ``MoveAbsJ`` (no posture flag
  can send it another way), ``ConfJ\\On`` and ``ConfL\\Off`` (linear moves continue from
  there; a configuration check on every LIN would stop on the wrist's turn numbers);
* ``LOCAL CONST robtarget pN`` ([[x, y, z], [q1..q4], [cf1, cf4, cf6, cfx], [9E+09 x 6]],
  quaternion w first);
* ``MoveL p, v100\\V:=speed, zone, tool\\WObj:=wobj``: the ``\\V`` argument sets the TCP speed
  [mm/s] of each move, so no speeddata are declared; ``LOCAL CONST zonedata`` only for the
  distinct blend sizes (rounded down to 1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6 or 8 per decade: a
  smaller zone keeps the bound); ``fine`` for exact stops; ``WaitTime\\InPos``.

A procedure longer than :data:`MAX_LINES` lines calls sub-procedures of the same module.
Configuration data follow :mod:`rfsw_plan.export.config` (ABB cfx = 4 rear + 2 lower arm +
flip, the RoboDK IRC5 post-processor's encoding).
"""

from __future__ import annotations

import math
import re
from collections.abc import Hashable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.export.config import abb_confdata, abb_confdatas
from rfsw_plan.export.format import ControllerFormat, FormatLimits, ReadPoint, ReadProgram
from rfsw_plan.export.krl import chunks
from rfsw_plan.export.program import Program, controller_name, number, speed_note
from rfsw_plan.files import read_program_text, write_text
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: Joint-move speed to the approach point.
MOVEJ_SPEED = "v100"
#: ABB's path interpolation cycle [s], ASSUMED: no public source found gives the IRC5 /
#: OmniCore path planner's cycle (the only public ABB figure found is EGM's 4 ms, 250 Hz,
#: position update: abb-motion-program-exec docs, "EGM Support"), so the program is held to
#: KUKA's 12 ms IPO (:data:`rfsw_plan.export.krl.IPO_CYCLE`), the longer of the two. No move
#: or WaitTime of a program is shorter (:attr:`ControllerFormat.cycle`).
PATH_CYCLE = 0.012
#: Lines of the procedure above which the motions move into sub-procedures.
MAX_LINES = 5000
#: Default hook comments.
DEFAULT_HOOKS = {
    "home_start": ("HOME: move to the cell's home position first (not known to rfsw-plan),",
                   "e.g. MoveAbsJ jHome,v100,fine,tFSW;"),
    "home_end": ("HOME: back to the cell's home position here,",
                 "e.g. MoveAbsJ jHome,v100,fine,tFSW;"),
    "spindle_start": ("SPINDLE START: spindle on and wait at speed, e.g. SetDO doSpindle, 1;",
                      "WaitDI diSpindleAtSpeed, 1;"),
    "force_on": ("FORCE CONTROL: none (the plan is verified in position control)",),
    "force_off": ("FORCE CONTROL: none (position control)",),
    "spindle_stop": ("SPINDLE STOP: the pin has left the material, e.g. SetDO doSpindle, 0;",),
}


#: A quaternion component smaller than this is not used to choose the sign of q (of q and -q,
#: the same rotation): far above rounding noise (a tool pointing straight down has w = 0, and
#: its -1e-13 or +1e-13 must not flip the whole quaternion), far below what is written (1e-9).
SIGN_TOL = 1e-6


def quat_wxyz(R: FloatArray) -> FloatArray:
    """Rotation matrix -> unit quaternion (w, x, y, z), the first component (in that order)
    larger than :data:`SIGN_TOL` in size positive (w >= 0 unless w is about 0)."""
    return quats_wxyz(np.asarray(R)[None])[0]


def quats_wxyz(R: FloatArray) -> FloatArray:
    """:func:`quat_wxyz` of every rotation matrix of R, (m, 3, 3) -> (m, 4) (one SciPy call;
    each matrix converted as alone)."""
    from rfsw_plan.robot.rotation import Rotation

    out = np.roll(Rotation.from_matrix(R).as_quat(), 1, axis=1)  # x, y, z, w -> w, x, y, z
    for q in out:
        if q[np.flatnonzero(np.abs(q) > SIGN_TOL)[0]] < 0:
            q *= -1.0
    return out


def _pose(T: FloatArray, q: FloatArray | None = None) -> str:
    """``[[x, y, z], [qw, qx, qy, qz]]`` of a pose [m] in mm (``q``: its :func:`quat_wxyz`,
    when known)."""
    p = T[:3, 3] * 1e3
    q = quat_wxyz(T[:3, :3]) if q is None else q
    return (f"[[{number(p[0], 4)},{number(p[1], 4)},{number(p[2], 4)}],"
            f"[{','.join(number(x, 9) for x in q)}]]")


def rapid_name(name: str) -> str:
    """A valid RAPID identifier (letters, digits, underscore; max 32; starts with a letter)."""
    return controller_name(name, max_len=32, prefix="m")


def proc_name(name: str) -> str:
    """The procedure of the module ``rapid_name(name)``: ``<name>_run`` (a module and its
    routine never share a name)."""
    return rapid_name(f"{name}_run")


#: Zone sizes per decade (a blend is rounded down to one of them, so few zonedata are needed).
ZONE_STEPS = (1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0)


def zone_mm(blend: float) -> float:
    """Blend distance [m] -> zone radius [mm], rounded down to :data:`ZONE_STEPS` (a smaller
    zone keeps the blend bound)."""
    z = blend * 1e3
    if z <= 0:
        return 0.0
    e = math.floor(math.log10(z))
    m = z / 10.0 ** e
    step = max(x for x in ZONE_STEPS if x <= m + 1e-9)
    return float(f"{step * 10.0 ** e:.6g}")


class RapidFormat(ControllerFormat):
    """ABB RAPID module (``.mod``), IRC5."""

    name = "rapid"
    order = 30
    description = "ABB RAPID module (.mod, IRC5)"
    suffix = ".mod"
    maker = "ABB"
    limits = FormatLimits(name_length=32, max_lines=MAX_LINES)
    cycle = PATH_CYCLE

    def file_name(self, program: Program) -> str:
        return rapid_name(program.header.name) + ".mod"

    def posture(self, robot: Robot, q: FloatArray) -> Hashable:
        return abb_confdata(robot, q)

    def postures(self, robot: Robot, Q: FloatArray) -> list[Hashable]:
        return list(abb_confdatas(robot, Q))

    def write(self, program: Program, folder: Path) -> list[Path]:
        return write_rapid(program, folder)

    def read(self, path: Path) -> ReadProgram:
        return read_rapid(path)


def _tooldata(program: Program) -> str:
    pl = program.payload
    if pl is None:
        load = "[1,[0,0,1],[1,0,0,0],0,0,0]"
        note = "  ! PAYLOAD UNKNOWN: enter the spindle's load data"
    else:
        conv = program.robot.description.convention
        cog = (np.linalg.inv(conv.flange) @ np.append(pl.com, 1.0))[:3] * 1e3
        inertia = pl.inertia if pl.inertia is not None else np.zeros(3)
        load = (f"[{number(pl.mass, 3)},[{','.join(number(x, 3) for x in cog)}],[1,0,0,0],"
                f"{','.join(number(x, 4) for x in inertia)}]")
        note = "" if pl.inertia is not None else "  ! inertia not known: 0, identify it"
    return f"  LOCAL PERS tooldata tFSW := [TRUE,{_pose(program.tool)},{load}];{note}"


def _header_extra(program: Program) -> list[str]:
    return [*program.maker_note("ABB"), *program.hook_notes("rapid"),
            "tFSW and wPlate are this module's own (LOCAL) data",
            "wPlate = the plate: origin on the first weld point, +X along the seam, +Y on "
            "the plate. To use a work object taught on the plate, enter its user frame in "
            "wPlate and run rfsw-plan check on this file"]


def hook_lines(program: Program, hook: str) -> tuple[str, ...]:
    """The default comment of ``hook``: for a force-controlled plan the force-control hooks
    carry the set force, the ramp and the Force Control option's instructions (``FCAct``,
    ``FCRefForce``, ``FCRefStart``, ``FCDeact``: ABB Application manual Force Control; they
    stay comments, so the module loads on a controller without the option)."""
    f, ramp = program.force_ramp()
    rate = f / ramp if ramp > 0 else f
    if f > 0 and hook == "force_on":
        return (f"FORCE CONTROL ON at contact: axial set force {f:.0f} N along tool +Z, "
                f"ramped 0 -> {f:.0f} N",
                f"over the rest of the plunge ({ramp:.2f} s, {rate:.0f} N/s), held through "
                "the dwell and the weld (option Force Control), e.g.",
                f"FCAct tFSW; FCRefForce \\Fz:={f:.0f}; FCRefStart;")
    if f > 0 and hook == "force_off":
        return ("FORCE CONTROL OFF: the weld has ended, the pin is still in, the retract "
                "follows, e.g. FCRefStop; FCDeact;",)
    return DEFAULT_HOOKS[hook]


def _motion_lines(program: Program, span: range, zones: dict[float, str]) -> list[str]:
    out: list[str] = []
    marks = program.phase_changes()
    for i in span:
        m = program.motions[i]
        if i in marks:
            out.append(f"    ! ---- phase: {marks[i]}")
        p = f"p{m.point + 1}"
        if m.kind == "hook":
            out += program.options.hooks.render(m.hook, "rapid", hook_lines(program, m.hook),
                                                "    ", "!")
        elif m.kind == "joint":
            out.append(f"    MoveAbsJ jStart,{MOVEJ_SPEED},fine,tFSW\\WObj:=wPlate;")
        elif m.kind == "wait":
            out.append(f"    WaitTime\\InPos,{m.duration:.3f};")
        else:
            if m.pin_speed is not None:
                out.append(f"    ! {speed_note(m)}")
            z = zone_mm(m.blend)
            zname = zones[z] if z > 0 else "fine"
            out.append(f"    MoveL {p},v100\\V:={max(m.speed * 1e3, 1e-4):.4f},{zname},"
                       "tFSW\\WObj:=wPlate;")
    return out


def write_rapid(program: Program, folder: str | Path, max_lines: int = MAX_LINES) -> list[Path]:
    """Write ``<name>.mod`` atomically; returns its path."""
    name = rapid_name(program.header.name)
    robot = program.robot
    out = [f"MODULE {name}"]
    out += program.header.comments("  ! ", extra=_header_extra(program))
    out += [_tooldata(program),
            f"  LOCAL PERS wobjdata wPlate := [FALSE,TRUE,\"\",{_pose(program.work)},"
            "[[0,0,0],[1,0,0,0]]];"]
    zones: dict[float, str] = {}
    for m in program.motions:
        z = zone_mm(m.blend) if m.kind == "lin" else 0.0
        if z > 0:
            zones.setdefault(z, f"zB{len(zones) + 1}")
    for z, nm in zones.items():
        out.append(f"  LOCAL CONST zonedata {nm} := [FALSE,{z:g},{z:g},{z:g},{z:g},{z:g},"
                   f"{z:g}];  ! mm")
    q0 = np.degrees(program.samples.q[0])
    out.append("  LOCAL CONST jointtarget jStart := [["
               + ",".join(number(x, 6) for x in q0) + "],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];")
    confs = abb_confdatas(robot, program.samples.q[1:len(program.poses)])
    quats = quats_wxyz(program.poses[:, :3, :3])
    for k in range(1, len(program.poses)):
        cf = confs[k - 1]
        out.append(f"  LOCAL CONST robtarget p{k + 1} := "
                   f"{_pose(program.poses[k], quats[k])[:-1]},"
                   f"[{cf[0]},{cf[1]},{cf[2]},{cf[3]}],"
                   "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];")
    body = _motion_lines(program, range(len(program.motions)), zones)
    proc = proc_name(program.header.name)
    head = ["", f"  PROC {proc}()", "    ConfJ\\On;", "    ConfL\\Off;"]
    if len(out) + len(body) > max_lines:
        subs: list[str] = []
        for c, span in enumerate(chunks(program.motions, max(max_lines // 2, 10))):
            sub = f"{proc[:26]}_s{c + 1}"
            head.append(f"    {sub};")
            subs += ["", f"  LOCAL PROC {sub}()", *_motion_lines(program, span, zones),
                     "  ENDPROC"]
        out += [*head, "  ENDPROC", *subs, "ENDMODULE"]
    else:
        out += [*head, *body, "  ENDPROC", "ENDMODULE"]
    return [write_text(Path(folder) / f"{name}.mod", "\n".join(out) + "\n")]


# --------------------------------------------------------------------------------------------
# Reading

_NUM = r"[-+0-9.Ee]+"
_POSE = rf"\[\[({_NUM}),({_NUM}),({_NUM})\],\[({_NUM}),({_NUM}),({_NUM}),({_NUM})\]\]"
_TOOL = re.compile(rf"PERS\s+tooldata\s+\w+\s*:=\s*\[TRUE,{_POSE}")
_WOBJ = re.compile(rf"PERS\s+wobjdata\s+\w+\s*:=\s*\[FALSE,TRUE,\"\",{_POSE}")
_ROBT = re.compile(rf"CONST\s+robtarget\s+(\w+)\s*:=\s*\[\[({_NUM}),({_NUM}),({_NUM})\],"
                   rf"\[({_NUM}),({_NUM}),({_NUM}),({_NUM})\],\[(-?\d+),(-?\d+),(-?\d+),(\d+)\]")
_JT = re.compile(rf"CONST\s+jointtarget\s+(\w+)\s*:=\s*\[\[((?:{_NUM},){{5}}{_NUM})\]")
_MOVE = re.compile(rf"^\s*(MoveL|MoveJ|MoveAbsJ)\s+(\w+),\w+(?:\\V:=({_NUM}))?,")
_WAIT = re.compile(rf"^\s*WaitTime(?:\\InPos)?\s*,\s*({_NUM})\s*;")
_PROC = re.compile(r"^\s*(?:LOCAL\s+)?PROC\s+(\w+)\s*\(\s*\)")
_CALL = re.compile(r"^\s*(\w+)\s*;\s*$")


def _frame(vals: tuple[str, ...], where: str) -> FloatArray:
    from rfsw_plan.robot.rotation import Rotation

    x, y, z, w, qx, qy, qz = (float(v) for v in vals)
    n = math.sqrt(w * w + qx * qx + qy * qy + qz * qz)
    if abs(n - 1.0) > 1e-6:
        raise InputError(where, "quaternion", f"norm {n:.9f}", "a unit quaternion")
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat([qx, qy, qz, w]).as_matrix()
    T[:3, 3] = np.array([x, y, z]) * 1e-3
    return T


def read_rapid(path: str | Path) -> ReadProgram:
    """Re-read a ``.mod``: tool, work object and every motion and wait (sub-procedures
    followed)."""
    p = Path(path)
    text = read_program_text(p)
    t, w = _TOOL.search(text), _WOBJ.search(text)
    if t is None or w is None:
        raise InputError(p, "tooldata/wobjdata", "missing", "both declared")
    targets = {m.group(1): m.groups() for m in _ROBT.finditer(text)}
    joints = {m.group(1): np.radians([float(x) for x in m.group(2).split(",")])
              for m in _JT.finditer(text)}
    procs: dict[str, list[str]] = {}
    current: list[str] | None = None
    for line in text.splitlines():
        if (pm := _PROC.match(line)) is not None:
            current = procs.setdefault(pm.group(1), [])
        elif line.strip() == "ENDPROC":
            current = None
        elif current is not None:
            current.append(line)
    if not procs:
        raise InputError(p, "PROC", "no procedure", "PROC name() ... ENDPROC")
    motions: list[ReadPoint] = []
    _read_proc(p, next(iter(procs)), procs, targets, joints, motions)
    return ReadProgram(_frame(t.groups(), str(p)), _frame(w.groups(), str(p)), motions, (p,))


def _read_proc(p: Path, name: str, procs: dict[str, list[str]], targets: dict[str, tuple],
               joints: dict[str, FloatArray], out: list[ReadPoint]) -> None:
    for line in procs[name]:
        code = line.split("!", 1)[0]
        if (c := _CALL.match(code)) is not None and c.group(1) in procs:
            _read_proc(p, c.group(1), procs, targets, joints, out)
        elif (wt := _WAIT.match(code)) is not None:
            out.append(ReadPoint("WaitTime", kind="wait", duration=float(wt.group(1))))
        elif (m := _MOVE.match(code)) is not None:
            tname = m.group(2)
            if m.group(1) == "MoveAbsJ":
                if tname not in joints:
                    raise InputError(p, tname, "not declared", "a jointtarget")
                out.append(ReadPoint(tname, q=joints[tname], kind="joint"))
                continue
            g = targets.get(tname)
            if g is None:
                raise InputError(p, tname, "not declared", "a robtarget per moved-to point")
            speed = float(m.group(3)) * 1e-3 if m.group(3) else 0.0
            out.append(ReadPoint(tname, _frame(g[1:8], str(p)), tuple(int(x) for x in g[8:12]),
                                 speed=speed, kind="lin" if m.group(1) == "MoveL" else "joint"))
