"""Options shared by ``rfsw-plan map`` and ``rfsw-plan place`` (not a subcommand)."""

from __future__ import annotations

import argparse
from typing import Any

from rfsw_plan.cli.numbers import count, percent
from rfsw_plan.exceptions import InputError


def register_region(parser: argparse.ArgumentParser, shape: str) -> None:
    """The region, yaw, height, grid and waypoint options."""
    parser.add_argument("problem", help="bundled problem name (e.g. zk500_table6_seam) or file")
    parser.add_argument("-o", "--output", default=None,
                        help="output directory (default: out/<command>/<problem>)")
    parser.add_argument("--region", default=None, metavar="x0,x1,y0,y1[,z0,z1]",
                        help="where the seam anchor (its middle point) may go, robot base frame "
                        "[mm] (default: the reachable part of the workspace around the given "
                        "placement at the seam's height)")
    parser.add_argument("--yaw-range", default=None, metavar="a0,a1",
                        help="rotation of the part about the vertical relative to the given "
                        "placement [deg] (default: the full turn)")
    parser.add_argument("--robot-base-height", default=None, metavar="h0,h1",
                        help="change of the robot base height (pedestal) [mm]; the part sits "
                        "that much lower relative to the robot")
    parser.add_argument("--grid", default=shape, metavar="nx,ny,nyaw[,nz]",
                        help=f"grid points per axis (default {shape}; nz only with a height "
                        "range)")
    parser.add_argument("--waypoints", type=count(2, 10_000), default=50,
                        help="weld waypoints evaluated per placement (default 50)")
    parser.add_argument("--force-uncertainty", type=percent(), default=None, metavar="PERCENT",
                        help="requested relative force uncertainty: 20%%, '20 %%' or the "
                        "fraction 0.2 (default: the problem's)")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")


def request_from_args(args: argparse.Namespace) -> Any:
    """A :class:`~rfsw_plan.placement.session.MapRequest` from the options (mm, deg -> SI)."""
    from rfsw_plan.placement.geometry import parse_range
    from rfsw_plan.placement.session import MapRequest

    region = None
    if args.region is not None:
        region = tuple(v * 1e-3 for v in parse_range(args.region, "--region", (4, 6), "mm"))
    yaw = None
    if args.yaw_range is not None:
        a = parse_range(args.yaw_range, "--yaw-range", (2,), "deg")
        yaw = (a[0], a[1])
    height = None
    if args.robot_base_height is not None:
        h = parse_range(args.robot_base_height, "--robot-base-height", (2,), "mm")
        height = (h[0] * 1e-3, h[1] * 1e-3)
    parts = args.grid.split(",")
    try:
        n = [int(p) for p in parts]
    except ValueError:
        raise InputError("--grid", "", f"got '{args.grid}'", "nx,ny,nyaw[,nz] integers") from None
    if len(n) not in (3, 4) or min(n) < 1:
        raise InputError("--grid", "", f"got '{args.grid}'", "3 or 4 integers >= 1")
    shape = (n[0], n[1], n[2], n[3] if len(n) == 4 else 3)
    if args.waypoints < 2:
        raise InputError("--waypoints", "", f"got {args.waypoints}", ">= 2")
    if args.force_uncertainty is not None and not args.force_uncertainty >= 0:
        raise InputError("--force-uncertainty", "", f"got {args.force_uncertainty}", ">= 0")
    return MapRequest(region, yaw, height, shape, args.waypoints)
