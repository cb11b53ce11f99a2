"""``rfsw-plan robots``: list the bundled robot descriptions."""

from __future__ import annotations

import argparse

NAME = "robots"
HELP = "list the bundled robots with their source and joint stiffness"


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from rfsw_plan.files import strict_json
    from rfsw_plan.robot.description import bundled_robot_names, load_robot_description

    descriptions = [load_robot_description(name) for name in bundled_robot_names()]
    if args.json:
        rows = [
            {
                "name": d.name,
                "title": d.title,
                "joints": d.n_joints,
                "stiffness_Nm_per_rad": [float(k) for k in d.stiffness],
                "effects": [e.name for e in d.effects],
                "file": str(d.path),
            }
            for d in descriptions
        ]
        print(strict_json({"robots": rows}), end="")
        return 0
    for d in descriptions:
        k = ", ".join(f"{v:.3g}" for v in np.asarray(d.stiffness, dtype=float))
        effects = [e.name for e in d.effects]
        extra = f"; effects: {', '.join(effects)}" if effects else ""
        print(f"{d.name:<20} {d.title}")
        print(f"{'':<20} k = [{k}] N m/rad{extra}")
    return 0
