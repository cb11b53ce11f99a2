"""``rfsw-plan predict``: TCP deflection of a robot at one pose under one wrench.

Uses :class:`~rfsw_plan.elastostatics.model.ElastostaticModel`, so the effects stored in the
robot file (e.g. tilting compliance) apply on top of joint compliance (seed 000 eq. 11).
"""

from __future__ import annotations

import argparse
import math
import re
from typing import TYPE_CHECKING

from rfsw_plan.cli.numbers import MAX_FORCE_N, MAX_MOMENT_NM, wrench
from rfsw_plan.exceptions import InputError

if TYPE_CHECKING:  # the parser answers before NumPy or Pinocchio are imported
    from rfsw_plan.elastostatics.effects.base import FloatArray
    from rfsw_plan.robot.kinematics import Robot

NAME = "predict"
HELP = "predict the TCP deflection [mm, mrad] at one pose under one wrench"

#: Units a ``--q`` value may carry, and their factor to SI (rad for revolute, m for prismatic).
ANGLE_UNITS = {"deg": math.pi / 180.0, "rad": 1.0}
LENGTH_UNITS = {"mm": 1e-3, "m": 1.0}
_VALUE = re.compile(r"^\s*([^a-zA-Z\s]+?)\s*([a-zA-Z]*)\s*$")


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", required=True, metavar="NAME|PATH",
                        help="bundled robot name (see 'rfsw-plan robots') or robot TOML file")
    q = parser.add_mutually_exclusive_group(required=True)
    q.add_argument("--q-deg", metavar="Q1,...,Qn",
                   help="controller joint values as on the pendant (KUKA A1..A6, FANUC J1..J6; "
                   "the robot file's [controller] axes), comma separated: degrees for a "
                   "revolute joint, millimetres for a prismatic one (never degrees)")
    q.add_argument("--q", metavar="Q1,...,Qn",
                   help="joint values with their units, e.g. 150mm,30deg,0.5rad,... (a value "
                   "without a unit: deg for a revolute joint, mm for a prismatic one)")
    parser.add_argument("--wrench", required=True, metavar="FX,FY,FZ[,MX,MY,MZ]", type=wrench,
                        help="wrench the environment applies to the tool at the TCP, robot "
                        f"base frame [N, N m]; moments default to 0; |F| <= {MAX_FORCE_N:g} N, "
                        f"|M| <= {MAX_MOMENT_NM:g} N m")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def parse_numbers(text: str, option: str, counts: tuple[int, ...], what: str) -> FloatArray:
    """Comma-separated finite numbers with one of the allowed counts.

    Raises:
        InputError: Non-numeric or non-finite entry, or a wrong count; names the option.
    """
    import numpy as np

    parts = [s.strip() for s in text.split(",")]
    try:
        values = np.array([float(s) for s in parts])
    except ValueError:
        bad = next(s for s in parts if not _is_float(s))
        raise InputError(option, "", f"'{bad}' is not a number", what) from None
    if values.size not in counts:
        raise InputError(option, "", f"got {values.size} values", what)
    if not np.all(np.isfinite(values)):
        raise InputError(option, "", "contains NaN or infinity", what)
    return values


def joint_values(robot: Robot, text: str, option: str) -> FloatArray:
    """Joint values [rad or m], shape (n,), from ``--q-deg`` (deg, prismatic in mm) or ``--q``
    (a unit per value; a bare value in deg or mm by the joint's type).

    Raises:
        InputError: A wrong count, a non-number, an angle unit on a prismatic joint or a length
            unit on a revolute one, a value outside the joint's limits (in its own unit).
    """
    import numpy as np

    n = robot.nq
    prismatic = [bool(p) for p in robot.prismatic]
    kinds = ", ".join(f"q{j + 1} {'mm' if p else 'deg'}" for j, p in enumerate(prismatic))
    what = f"{n} joint values for robot {robot.name} ({kinds})"
    if option == "--q-deg":
        raw = [float(v) for v in parse_numbers(text, option, (n,), what)]
        units = ["mm" if p else "deg" for p in prismatic]
    else:
        raw, units = _with_units(text, option, prismatic, what)
    q = np.empty(n)
    for j, (v, unit) in enumerate(zip(raw, units, strict=True)):
        q[j] = _joint_value(robot, j, v, unit, option)
    return q


def _with_units(text: str, option: str, prismatic: list[bool], what: str
                ) -> tuple[list[float], list[str]]:
    """``--q`` values and their units (a bare value: deg, or mm for a prismatic joint)."""
    parts = [s.strip() for s in text.split(",")]
    if len(parts) != len(prismatic):
        raise InputError(option, "", f"got {len(parts)} values", what)
    raw, units = [], []
    for j, part in enumerate(parts):
        m = _VALUE.match(part)
        if m is None or not _is_float(m.group(1)) or not math.isfinite(float(m.group(1))):
            raise InputError(option, f"joint {j + 1}", f"'{part}' is not a finite number with "
                             "an optional unit", "e.g. 30deg, 0.5rad, 150mm, 0.15m")
        raw.append(float(m.group(1)))
        units.append(m.group(2) or ("mm" if prismatic[j] else "deg"))
    return raw, units


def _joint_value(robot: Robot, j: int, v: float, unit: str, option: str) -> float:
    """Joint ``j``'s value in SI (rad, or m for a prismatic joint), within its limits."""
    prismatic = bool(robot.prismatic[j])
    table = LENGTH_UNITS if prismatic else ANGLE_UNITS
    kind = "prismatic" if prismatic else "revolute"
    if unit not in table:
        raise InputError(option, f"joint {j + 1}", f"unit '{unit}' on a {kind} joint",
                         f"{'a length' if prismatic else 'an angle'} in {' or '.join(table)}")
    q = v * table[unit]
    d = robot.description
    if not d.lower[j] <= q <= d.upper[j]:
        scale, shown = (1e3, "mm") if prismatic else (180.0 / math.pi, "deg")
        raise InputError(option, f"joint {j + 1}",
                         f"at {q * scale:.6g} {shown} is outside its limits "
                         f"[{d.lower[j] * scale:.6g}, {d.upper[j] * scale:.6g}] {shown}",
                         "a value within the robot's joint limits")
    return q


def _is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.files import strict_json
    from rfsw_plan.robot.kinematics import load_robot

    wrench = np.array(args.wrench)  # 6 values, range-checked by the parser
    robot = load_robot(args.robot)
    q = joint_values(robot, args.q if args.q is not None else args.q_deg,
                     "--q" if args.q is not None else "--q-deg")
    model = ElastostaticModel(robot)
    dX = model.deflection(q, wrench)
    trans_mm = dX[:3] * 1e3
    rot_mrad = dX[3:] * 1e3
    if args.json:
        print(strict_json({
            "robot": robot.name,
            # Per joint: q_deg for a revolute joint, q_mm for a prismatic one (null otherwise).
            "q_deg": [None if p else float(np.degrees(v))
                      for v, p in zip(q, robot.prismatic, strict=True)],
            **({"q_mm": [float(v) * 1e3 if p else None
                         for v, p in zip(q, robot.prismatic, strict=True)]}
               if robot.prismatic.any() else {}),
            "wrench_N_Nm": [float(v) for v in wrench],
            "effects": model.labels,
            "translation_mm": [float(v) for v in trans_mm],
            "rotation_mrad": [float(v) for v in rot_mrad],
        }, indent=None), end="")
        return 0
    print(f"robot {robot.name}; effects: {', '.join(model.labels)}")
    print("TCP deflection in the base frame:")
    print("  translation [mm]:   " + "  ".join(f"{v:+10.4f}" for v in trans_mm)
          + f"   |d| = {np.linalg.norm(trans_mm):.4f} mm")
    print("  rotation    [mrad]: " + "  ".join(f"{v:+10.4f}" for v in rot_mrad))
    return 0
