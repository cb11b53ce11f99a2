"""Entry point of ``rfsw-plan``: discovers subcommands and maps errors to one line."""

from __future__ import annotations

import argparse
import ast
import contextlib
import functools
import importlib
import logging
import os
import pkgutil
import re
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any, NoReturn

from rfsw_plan.exceptions import RfswError


@functools.cache
def _command_specs() -> tuple[tuple[str, str, str], ...]:
    """``(NAME, HELP, module)`` of every command module, sorted by module name.

    NAME and HELP are read from the module's source (string literals) without importing it, so
    ``rfsw-plan --help`` imports no command and none of the heavy libraries; a module whose
    NAME or HELP is not a literal is imported to read them. Read once per process (the
    installed command modules do not change while it runs): a program or a test that calls
    :func:`main` many times parses the 16 sources once, not 22 ms of CPU at every call."""
    import rfsw_plan.cli.commands as pkg

    specs = []
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        modname = f"{pkg.__name__}.{info.name}"
        found = _literal_names(Path(pkg.__path__[0]) / f"{info.name}.py")
        if "NAME" not in found or "HELP" not in found:
            mod = importlib.import_module(modname)
            found = {"NAME": mod.NAME, "HELP": mod.HELP}
        specs.append((found["NAME"], found["HELP"], modname))
    return tuple(specs)


def _literal_names(path: Path) -> dict[str, str]:
    """Top-level ``NAME = "..."`` and ``HELP = "..."`` string literals of a module file.

    Only the part before the first top-level ``def``, ``class`` or decorator is parsed when
    both are assigned there and nowhere after it (every command module names itself at its
    top): the same literals, without parsing every command's whole source at each start."""
    try:
        source = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return {}
    first = re.search(r"^(?:def |class |async def |@)", source, re.M)
    if first is not None:
        head, rest = source[:first.start()], source[first.start():]
        if (not re.search(r"^(?:NAME|HELP)\b", rest, re.M)
                and all(re.search(rf"^{n}\b", head, re.M) for n in ("NAME", "HELP"))):
            found = _literals_in(head)
            if len(found) == 2:
                return found
    return _literals_in(source)


def _literals_in(source: str) -> dict[str, str]:
    """The top-level ``NAME`` and ``HELP`` string literals of a module's source."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return {}
    out = {}
    for node in tree.body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and isinstance(node.targets[0], ast.Name)
                and node.targets[0].id in ("NAME", "HELP")
                and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str)):
            out[node.targets[0].id] = node.value.value
    return out


class OneLineArgumentParser(argparse.ArgumentParser):
    """Argument parser whose errors are one line (no usage block) with exit code 2.

    Values that start with a minus sign and a digit, such as ``--q-deg -96.2,3.9,...``, are
    taken as values, not as unknown options.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        # No prefix matching: ``--spacing 2`` is an unknown option, never ``--spacing-mm 2``.
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?\d[\d.,eE+-]*( ?%)?$")

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see --help)\n")

    def format_help(self) -> str:
        """The help text; an epilog given as a function (one that needs a heavy import, such as
        the list of effects) is computed only here, when the help is asked for."""
        if callable(self.epilog):
            self.epilog = self.epilog()
        return super().format_help()


def build_parser(only: str | None = None, lazy: bool = False
                 ) -> tuple[argparse.ArgumentParser, dict[str, ModuleType]]:
    """The top-level parser and the subcommand modules by name.

    Args:
        only: With ``lazy``: the one subcommand whose module is imported and whose arguments
            are registered (the one on the command line).
        lazy: Import only that module; every other subcommand is listed by NAME and HELP.
    """
    parser = OneLineArgumentParser(
        prog="rfsw-plan",
        description="Offline planning of robotic friction stir welding around the robot's "
        "own elasticity.",
    )
    _add_global_options(parser, False)
    from rfsw_plan import __version__

    parser.add_argument("--version", action="version", version=f"rfsw-plan {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    commands: dict[str, ModuleType] = {}
    for name, help_, modname in _command_specs():
        p = sub.add_parser(name, help=help_, description=help_)
        # The same options after the subcommand (``rfsw-plan plan P -q``); SUPPRESS keeps the
        # value set before the subcommand when they are not repeated after it.
        _add_global_options(p, argparse.SUPPRESS)
        if name in EFFECT_COMMANDS:
            p.add_argument("--effects", action="append", default=[], metavar="FILE.py",
                           help="load user-defined effects from a Python file (repeatable); "
                           "installed entry points of group rfsw_plan.effects load anyway")
        if not lazy or name == only:
            mod = importlib.import_module(modname)
            mod.register(p)
            commands[name] = mod
    return parser, commands


#: Commands that build an elastostatic model and so accept ``--effects FILE.py``.
EFFECT_COMMANDS = frozenset({"validate", "identify", "validate-weld", "plan", "predict"})


def _load_effects(args: argparse.Namespace) -> None:
    """Load the user's effect files and the installed effect entry points (one-line errors)."""
    if args.command not in EFFECT_COMMANDS:
        return
    from rfsw_plan.elastostatics.plugins import load_effect_file, load_entry_points

    load_entry_points()
    for path in getattr(args, "effects", []):
        load_effect_file(path)


def _add_global_options(parser: argparse.ArgumentParser, default: Any) -> None:
    """``-v/--verbose`` and ``-q/--quiet``, accepted before and after the subcommand."""
    parser.add_argument("-v", "--verbose", action="store_true", default=default,
                        help="log progress to stderr")
    parser.add_argument("-q", "--quiet", action="store_true", default=default,
                        help="no progress bars (they are shown only on a terminal anyway)")


def _command_word(argv: Sequence[str]) -> str | None:
    """The subcommand on a command line: the first word that is not an option (the top-level
    options take no value)."""
    return next((a for a in argv if not a.startswith("-")), None)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the process exit code (0 ok, 2 bad input, 3 infeasible, 130
    interrupted). Ctrl-C at any point, start-up (parser, lazy imports) included, ends with
    one line and exit 130, never a traceback. The SIGTERM handler in place before the call is
    restored after it."""
    return _run(argv, after=None)


def console() -> NoReturn:
    """The ``rfsw-plan`` script: :func:`main`, then exit with its code. Once the command has
    finished, SIGTERM is ignored: a termination that arrives while the interpreter shuts down
    (a second or so after a plan) does not turn a finished run into a killed one (exit -15);
    the process ends with the command's own code.

    The objects left at the end are moved out of the garbage collector's reach first
    (``gc.freeze``): the interpreter's last collection then does not walk the whole heap of a
    plan (its models, CasADi functions and arrays; about 0.2 s after ``plan`` on a busy
    machine, 0.05-0.09 s with it). Everything still ends as before: the exit handlers run,
    the modules are torn down, the streams are flushed."""
    code = _run(None, after=signal.SIG_IGN)
    import gc

    gc.freeze()
    sys.exit(code)


def _run(argv: Sequence[str] | None, after: Any) -> int:
    """:func:`main` with the SIGTERM handler to leave in place afterwards (None: the previous)."""
    # SIGTERM unwinds like Ctrl-C, so atomic writers remove their temporaries (a file is
    # either the complete new one or not there).
    from rfsw_plan import files

    previous: Any = None
    previous_int: Any = None
    with contextlib.suppress(ValueError):  # not in the main thread: keep the default
        previous = signal.signal(signal.SIGTERM, _terminated)
        # Ctrl-C is noted too: CasADi catches the KeyboardInterrupt inside IPOPT's callbacks
        # and returns a normal-looking solve, so the raise alone would be lost.
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            previous_int = signal.signal(signal.SIGINT, _interrupted)
    files.clear_interrupt()
    files.forget_created_dirs()
    hook = sys.unraisablehook
    sys.unraisablehook = _interrupt_in_a_callback(hook)
    try:
        code = _main(argv)
        if code != 130:
            files.check_interrupt()  # a library swallowed the interruption: still exit 130
        else:
            files.remove_created_dirs()
        return code
    except KeyboardInterrupt:
        with contextlib.suppress(Exception):
            files.remove_created_dirs()  # an interrupted run leaves no new empty folder
            print("rfsw-plan: interrupted", file=sys.stderr)
        return 130
    finally:
        files.clear_interrupt()
        sys.unraisablehook = hook
        if previous is not None:
            signal.signal(signal.SIGTERM, previous if after is None else after)
        if previous_int is not None:
            signal.signal(signal.SIGINT, previous_int)


def _interrupt_in_a_callback(hook: Any) -> Any:
    """An unraisable-exception hook: a Ctrl-C or SIGTERM that lands in a callback Python
    cannot raise from (a weakref callback, a finaliser) is noted, not printed as an ignored
    traceback; the next writer (or the end of the command) ends the run with exit 130."""

    def unraisable(info: Any) -> None:
        if isinstance(info.exc_value, KeyboardInterrupt):
            from rfsw_plan import files

            files.note_interrupt()
            return
        hook(info)

    return unraisable


def _terminated(signum: int, frame: Any) -> NoReturn:
    # A second SIGTERM while unwinding (a supervisor that repeats it) must not interrupt the
    # clean-up of the first: ignored until main() restores the previous handler.
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    from rfsw_plan import files

    files.note_interrupt()  # if a library swallows the KeyboardInterrupt, the writers re-raise
    raise KeyboardInterrupt


def _interrupted(signum: int, frame: Any) -> NoReturn:
    # Ctrl-C: Python's own KeyboardInterrupt, noted first so that a library that swallows it
    # (CasADi inside IPOPT) cannot turn the interruption into a finished run.
    from rfsw_plan import files

    files.note_interrupt()
    raise KeyboardInterrupt


#: Options that name a file or folder to write: an empty value is a slip, never "here".
_PATH_OPTIONS = ("output", "save_robot", "save_truth")


def _refuse_empty_paths(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    for name in _PATH_OPTIONS:
        if getattr(args, name, None) is not None and not str(getattr(args, name)).strip():
            parser.error(f"argument --{name.replace('_', '-')}: an empty path; give a file or "
                         "folder, or leave the option out for the default")


def _main(argv: Sequence[str] | None = None) -> int:
    """The CLI without the signal handling. The parsed namespace also carries ``argv`` (the
    words given, for reports that print the next command) and ``started``
    (``time.perf_counter()`` at the start, for wall times)."""
    started = time.perf_counter()
    words = list(sys.argv[1:] if argv is None else argv)
    parser, commands = build_parser(only=_command_word(words), lazy=True)
    try:
        if any(w == "--" or w.endswith("=--") for w in words):
            # No command takes it; argparse would hand the option an empty list.
            parser.error("'--' is not an argument of rfsw-plan")
        args = parser.parse_args(words)
        _refuse_empty_paths(parser, args)
    except SystemExit as exc:  # --help (0) or a usage error (2), already printed
        return exc.code if isinstance(exc.code, int) else 2
    args.argv = words
    args.started = started
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    logging.getLogger("toppra").setLevel(logging.WARNING)  # its INFO is per grid point
    from rfsw_plan import progress

    progress.set_enabled(not args.quiet)
    try:
        _load_effects(args)
        return int(commands[args.command].run(args) or 0)
    except RfswError as exc:
        from rfsw_plan.cli.params import as_flag_error

        print(f"rfsw-plan {args.command}: error: {as_flag_error(exc)}", file=sys.stderr)
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
    console()
