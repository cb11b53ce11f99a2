"""``rfsw-plan predict``: TCP deflection of a robot at one pose under one wrench.

Uses :class:`~rfsw_plan.elastostatics.model.ElastostaticModel`, so the effects stored in the
robot file (e.g. tilting compliance) apply on top of joint compliance (seed 000 eq. 11).
"""

from __future__ import annotations

import argparse

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError, NotWithinLimitsError
from rfsw_plan.files import strict_json
from rfsw_plan.robot.kinematics import load_robot

NAME = "predict"
HELP = "predict the TCP deflection [mm, mrad] at one pose under one wrench"


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", required=True, metavar="NAME|PATH",
                        help="bundled robot name (see 'rfsw-plan robots') or robot TOML file")
    parser.add_argument("--q-deg", required=True, metavar="Q1,...,Qn",
                        help="controller joint values [deg] as on the pendant (KUKA A1..A6, FANUC "
                             "J1..J6; the robot file's [controller] axes), comma separated")
    parser.add_argument("--wrench", required=True, metavar="FX,FY,FZ[,MX,MY,MZ]",
                        help="wrench the environment applies to the tool at the TCP, robot "
                        "base frame [N, N m]; moments default to 0")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def parse_numbers(text: str, option: str, counts: tuple[int, ...], what: str) -> FloatArray:
    """Comma-separated finite numbers with one of the allowed counts.

    Raises:
        InputError: Non-numeric or non-finite entry, or a wrong count; names the option.
    """
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


def _is_float(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def run(args: argparse.Namespace) -> int:
    robot = load_robot(args.robot)
    n = robot.nq
    q = np.radians(parse_numbers(args.q_deg, "--q-deg", (n,), f"{n} joint values for "
                                 f"robot {robot.name}"))
    w = parse_numbers(args.wrench, "--wrench", (3, 6), "fx,fy,fz or fx,fy,fz,mx,my,mz")
    wrench = np.concatenate([w, np.zeros(6 - w.size)])
    d = robot.description
    for j in range(n):
        if not d.lower[j] <= q[j] <= d.upper[j]:
            raise NotWithinLimitsError(j, float(np.degrees(q[j])), float(np.degrees(d.lower[j])),
                                       float(np.degrees(d.upper[j])))
    model = ElastostaticModel(robot)
    dX = model.deflection(q, wrench)
    trans_mm = dX[:3] * 1e3
    rot_mrad = dX[3:] * 1e3
    if args.json:
        print(strict_json({
            "robot": robot.name,
            "q_deg": [float(v) for v in np.degrees(q)],
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
