"""``rfsw-plan compare PROBLEM``: offline plan against real-time compensation on a virtual weld."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from rfsw_plan.cli.numbers import count, number
from rfsw_plan.exceptions import InputError

NAME = "compare"
HELP = "compare offline pre-compensation with seed 000/002 real-time compensation on a " \
    "virtual weld"

log = logging.getLogger(__name__)

_STRATEGIES = ("none", "realtime_seed000", "realtime_seed002", "offline", "hybrid")


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("problem", metavar="PROBLEM",
                        help="problem file or bundled stem (e.g. zk500_table6_seam)")
    parser.add_argument("-o", "--output", metavar="DIR", default=None,
                        help="output folder (default out/compare/<problem>)")
    parser.add_argument("--truth-effect", action="append", default=[],
                        metavar="NAME[=key=value,...]",
                        help="effect the truth robot has and the model lacks (repeatable), "
                        "e.g. tilting_compliance:j3 or payload_gravity=m=150 (SI values)")
    parser.add_argument("--truth-stiffness-scale", type=number(0.01, 100), default=1.0, metavar="X",
                        help="truth joint stiffness / model joint stiffness (default 1)")
    parser.add_argument("--strategies", nargs="+", default=list(_STRATEGIES), metavar="NAME",
                        help=f"strategies to run (default all: {', '.join(_STRATEGIES)})")
    parser.add_argument("--cycle-ms", type=number(0.1, 1000, "ms", why="a controller cycle"),
                        default=4.0, metavar="MS",
                        help="controller cycle [ms] (default 4, KUKA RSI)")
    parser.add_argument("--sensor-rate-hz", type=number(1, 1e5, "Hz"), default=1000.0,
                        metavar="HZ",
                        help="force sensor sample rate [Hz] (default 1000)")
    parser.add_argument("--sensor-delay-ms", type=number(0, 1000, "ms"), default=4.0, metavar="MS",
                        help="force sensor delay [ms] (default 4)")
    parser.add_argument("--sensor-noise-N", type=number(0, 1e4, "N"), default=30.0, metavar="N",
                        help="sensor noise std per force component [N] (default 30; moments "
                        "get 0.1 m times this)")
    parser.add_argument("--force-drift", type=number(0, 1), default=0.10, metavar="FRACTION",
                        help="slow process-force variation along the seam (default 0.10)")
    parser.add_argument("--seed", type=count(0, 2**32 - 1), default=0,
                        help="noise seed (default 0)")
    parser.add_argument("--seed000-average", type=number(0, 100, "%"), default=50.0,
                        metavar="PERCENT",
                        help="seed 000 averaging percentage (default 50)")
    parser.add_argument("--seed000-update-ms", type=number(0, 1e12, "ms"), default=250.0,
                        metavar="MS",
                        help="seed 000 model/average update period [ms] (default 250; 0 = "
                        "every controller cycle)")
    parser.add_argument("--maf-samples", type=count(1, 10**12), default=320, metavar="N",
                        help="seed 002 moving-average length in 0.5 ms steps (default 320)")
    parser.add_argument("--no-sensitivity", action="store_true",
                        help="skip the reruns with a softer truth, a hidden effect, 3x noise")
    parser.add_argument("--no-plot", action="store_true", help="do not write the PNG")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.process.problem import load_problem
    from rfsw_plan.realtime.compare import (
        CompareOptions,
        compare,
        format_table,
        parse_effect_arg,
    )
    from rfsw_plan.realtime.simulator import ProcessVariation, SensorModel

    if not args.cycle_ms > 0:
        raise InputError("--cycle-ms", "", f"controller cycle {args.cycle_ms:g} ms", "> 0 ms")
    if args.seed000_update_ms < 0:
        raise InputError("--seed000-update-ms", "", f"got {args.seed000_update_ms:g}",
                         ">= 0 (0 = every cycle)")
    effects = tuple(parse_effect_arg(e) for e in args.truth_effect)
    sensor = SensorModel(
        rate_hz=args.sensor_rate_hz, delay_s=args.sensor_delay_ms * 1e-3,
        noise_force_N=args.sensor_noise_N, noise_moment_Nm=0.1 * args.sensor_noise_N,
        seed=args.seed,
    )
    options = CompareOptions(
        strategies=tuple(args.strategies),
        cycle_s=args.cycle_ms * 1e-3,
        sensor=sensor,
        variation=ProcessVariation(amplitude=args.force_drift),
        truth_stiffness_scale=args.truth_stiffness_scale,
        truth_effects=effects,
        sensitivity=not args.no_sensitivity,
        seed000_average_percent=args.seed000_average,
        seed000_update_s=args.seed000_update_ms * 1e-3 if args.seed000_update_ms > 0 else None,
        seed002_maf_samples=args.maf_samples,
    )
    from rfsw_plan.files import OutputLock, prepare_output_dir, strict_json

    problem = load_problem(args.problem)
    out = prepare_output_dir(args.output if args.output else Path("out") / NAME / problem.name)
    result = compare(problem, options)
    with OutputLock(out):
        files = result.write(out, plot=not args.no_plot)
    data = {**result.to_dict(), "files": [str(f) for f in files]}
    if args.json:
        print(strict_json(data, indent=None), end="")
        return 0
    print(format_table(result))
    print(f"wrote {', '.join(f.name for f in files)} to {out}")
    return 0
