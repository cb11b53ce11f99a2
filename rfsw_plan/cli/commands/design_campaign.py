"""``rfsw-plan design-campaign``: the poses to measure next, chosen by D-optimality."""

from __future__ import annotations

import argparse

from rfsw_plan.cli.numbers import count, number

NAME = "design-campaign"
HELP = "choose N poses (with load and approach) that make the model's effects identifiable"


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", required=True, help="bundled robot name or robot TOML file")
    parser.add_argument("--poses", type=count(1, 10_000), required=True,
                        help="number of poses N to measure")
    parser.add_argument("--effects", action="append", default=[], metavar="EFFECT[:jN]",
                        help="effect to make identifiable besides the robot file's own "
                             "(repeatable, or comma-separated)")
    parser.add_argument("--load-N", dest="load_n", type=number(0, 1e6, "N"),
                        default=2000.0, help="force to apply at a loaded pose [N] "
                                             "(default 2000; 0: an unloaded campaign)")
    parser.add_argument("--seed", type=count(0, 2**32 - 1), default=0,
                        help="seed of the candidate poses (default 0)")
    parser.add_argument("-o", "--output", required=True, metavar="FOLDER",
                        help="folder for design.csv and design.json")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.files import OutputLock, prepare_output_dir, strict_json
    from rfsw_plan.robot.kinematics import load_robot
    from rfsw_plan.validation.campaign.design import DesignRequest
    from rfsw_plan.validation.campaign.design import run as design

    effects = tuple(x.strip() for e in args.effects for x in e.split(",") if x.strip())
    request = DesignRequest(load_robot(args.robot), args.poses, effects, args.load_n,
                            args.seed)
    result = design(request)
    out = prepare_output_dir(args.output)
    with OutputLock(out):
        csv, js = result.write(out)
    if args.json:
        print(strict_json({**result.to_json(), "csv": str(csv), "json": str(js)}), end="")
        return 0
    print(result.text())
    print(f"wrote {csv} (teach these poses: controller axis values in degrees; apply the "
          f"force fx_N, fy_N, fz_N at the TCP; reach each pose as dir_qN says) and {js}")
    return 0
