"""Entry point of ``rfsw-plan``: discovers subcommands and maps errors to one line."""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import pkgutil
import re
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import Any, NoReturn

from rfsw_plan.exceptions import RfswError


def _command_modules() -> list[ModuleType]:
    import rfsw_plan.cli.commands as pkg

    mods = []
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        mods.append(importlib.import_module(f"{pkg.__name__}.{info.name}"))
    return mods


class OneLineArgumentParser(argparse.ArgumentParser):
    """Argument parser whose errors are one line (no usage block) with exit code 2.

    Values that start with a minus sign and a digit, such as ``--q-deg -96.2,3.9,...``, are
    taken as values, not as unknown options.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?\d[\d.,eE+-]*$")

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see --help)\n")


def build_parser() -> tuple[argparse.ArgumentParser, dict[str, ModuleType]]:
    """The top-level parser and the subcommand modules by name."""
    parser = OneLineArgumentParser(
        prog="rfsw-plan",
        description="Offline planning of robotic friction stir welding around the robot's "
        "own elasticity.",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress to stderr")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress bars (they are shown only on a terminal anyway)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    commands: dict[str, ModuleType] = {}
    for mod in _command_modules():
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=mod.HELP)
        mod.register(p)
        commands[mod.NAME] = mod
    return parser, commands


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the process exit code (0 ok, 2 bad input, 3 infeasible)."""
    parser, commands = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2), already printed
        return exc.code if isinstance(exc.code, int) else 2
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    logging.getLogger("toppra").setLevel(logging.WARNING)  # its INFO is per grid point
    from rfsw_plan import progress

    progress.set_enabled(not args.quiet)
    try:
        return int(commands[args.command].run(args) or 0)
    except RfswError as exc:
        print(f"rfsw-plan {args.command}: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except BrokenPipeError:
        # Output piped into a reader that closed early (``| head``): no traceback; silence
        # the interpreter's own flush of stdout at exit (Python docs, "Note on SIGPIPE").
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except KeyboardInterrupt:
        print("rfsw-plan: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
