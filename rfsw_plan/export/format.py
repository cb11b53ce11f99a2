"""The contract of a controller format, and the registry every format joins by being defined.

A format is one class in one module (``export/krl.py``, ``export/fanuc_tp.py``,
``export/rapid.py``, ``export/stream.py``) derived from :class:`ControllerFormat`. It says:

* how it **writes** a vendor-neutral :class:`~rfsw_plan.export.program.Program`
  (:meth:`ControllerFormat.write`);
* how it **reads** a file of its own language back (:meth:`ControllerFormat.read`), as the
  points a controller would move to, so the round trip, ``rfsw-plan check`` and a programmer's
  touched-up file all go through the same reader;
* how it **encodes the posture** of a joint vector (:meth:`ControllerFormat.posture`: KUKA S/T,
  FANUC CONFIG, ABB confdata), which the round trip uses to pick the inverse kinematics branch;
* its **limits** (:class:`FormatLimits`): name length, lines per program before it is split;
* the **path bound** of its rounding at the points (:meth:`ControllerFormat.path_deviation`,
  default the vendor-neutral blend model; FANUC ``CR`` has its own), checked at export.

Defining a subclass with a ``name`` registers it in :data:`FORMATS` (``__init_subclass__``); the
CLI's ``--format`` choices, ``export``'s dispatch and the tests' format matrix all read that
registry, so a new format is one module and nothing else (``docs/dev/writing-a-format.md``).
"""

from __future__ import annotations

import abc
import importlib
from collections.abc import Hashable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.kinematics import Robot

if TYPE_CHECKING:
    from rfsw_plan.export.program import Program, Samples

FloatArray = NDArray[np.float64]

#: name -> format class, every class defined so far (:func:`formats` discovers the package's).
FORMATS: dict[str, type[ControllerFormat]] = {}
#: The modules of this package that hold no format (every other module is imported by
#: :func:`formats`, so a new format is a new module and nothing else).
SUPPORT_MODULES = frozenset({"api", "check", "config", "format", "program", "readback"})


@dataclass(frozen=True)
class FormatLimits:
    """What a controller accepts.

    Attributes:
        name_length: Longest program or module name [characters].
        max_lines: Lines of one program file above which the motion part is split into
            called sub-programs (the vendor's practical limit), or 0 for no limit.
    """

    name_length: int = 32
    max_lines: int = 0


@dataclass(frozen=True)
class ReadPoint:
    """One motion re-read from a program file.

    Attributes:
        name: The point's name in the program (``XP3``, ``P[3]``, ``p3``).
        pose: TCP pose in the program's work object frame [m], (4, 4); for a joint target
            None.
        config: The posture the program states for a Cartesian point (the format's
            :meth:`ControllerFormat.posture` value), or None.
        q: Joint values of a joint target (controller axes) [rad], (n,), or None.
        speed: Programmed TCP speed of a linear move [m/s] (0: not stated).
        duration: Programmed duration of a move or wait [s] (0: not stated).
        kind: ``joint``, ``lin`` or ``wait`` (a wait holds the previous point).
    """

    name: str
    pose: FloatArray | None = None
    config: Hashable | None = None
    q: FloatArray | None = None
    speed: float = 0.0
    duration: float = 0.0
    kind: str = "lin"


@dataclass(frozen=True)
class ReadProgram:
    """A program file re-read by its format.

    Attributes:
        tool: TCP in the controller's flange frame [m], (4, 4).
        work: Work object (base, user frame, wobjdata) in the controller's base frame [m],
            (4, 4).
        motions: Every motion and wait, in program order (sub-programs followed).
        files: The files read.
    """

    tool: FloatArray
    work: FloatArray
    motions: list[ReadPoint]
    files: tuple[Path, ...] = field(default=())

    @property
    def points(self) -> list[ReadPoint]:
        """The moved-to points (no waits), in program order."""
        return [m for m in self.motions if m.kind != "wait"]


#: The last programs bounded by the default :meth:`ControllerFormat.path_deviation` and their
#: bounds (by identity: a program is frozen).
_BOUNDS: list[tuple[Program, FloatArray]] = []


class ControllerFormat(abc.ABC):
    """One controller language (see the module docstring).

    Class attributes:
        name: The ``--format`` value.
        description: One line for ``--help`` and the docs.
        suffix: Suffix of the main file (``.src``).
        maker: The robot maker whose controllers run the language (``KUKA``, ``FANUC``,
            ``ABB``), or ``""`` for a vendor-neutral file: a robot description of another
            maker gets a warning line in the program header.
        limits: The controller's limits.
        order: Where the format stands in :func:`formats` (lowest first, then by name): the
            order of ``--format``'s default and of the written files.
        cycle: The controller's interpolation cycle [s]: no move or wait of a program is
            shorter (a shorter one cannot run as written; the controller slows down or
            stops), 0 for a format without moves (the stream). The export builds the
            vendor-neutral program once per cycle (``build_program(min_move=cycle)``), so a
            format's file does not depend on which other formats are written with it.
        runs_rows: The file's rows are the run itself, one joint target per controller cycle
            sent as it is (the stream for a real-time interface): ``check`` judges the rows
            at their own clock, with no path, posture or base between them, and reports the
            joint velocity, acceleration and jerk (no motion planner of the controller's
            enforces them).
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    suffix: ClassVar[str] = ""
    maker: ClassVar[str] = ""
    limits: ClassVar[FormatLimits] = FormatLimits()
    order: ClassVar[int] = 100
    cycle: ClassVar[float] = 0.0
    runs_rows: ClassVar[bool] = False

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        # ABCMeta fills __abstractmethods__ only after this hook: look at the methods
        abstract = [m for m in ("write", "read", "posture")
                    if getattr(getattr(cls, m, None), "__isabstractmethod__", False)]
        if cls.name and not abstract:
            FORMATS[cls.name] = cls

    @abc.abstractmethod
    def write(self, program: Program, folder: Path) -> list[Path]:
        """Write the program into ``folder`` (each file atomically); returns the files, the
        main file (the one :meth:`read` takes) first."""

    @abc.abstractmethod
    def read(self, path: Path) -> ReadProgram:
        """Re-read a file of this format (written by :meth:`write` or edited by a programmer).

        Raises:
            InputError: One line naming the file, line and what was expected.
        """

    @abc.abstractmethod
    def posture(self, robot: Robot, q: FloatArray) -> Hashable:
        """The posture a Cartesian point states for controller joint values q [rad], (n,)."""

    def postures(self, robot: Robot, Q: FloatArray) -> list[Hashable]:
        """:meth:`posture` of every row of Q [rad], (m, n) (a format overrides it where the
        rows share one pass of the forward kinematics)."""
        return [self.posture(robot, q) for q in Q]

    def matches(self, robot: Robot, point: ReadPoint, q: FloatArray) -> bool:
        """Does ``q`` have the posture ``point`` states? (Joint values at a boundary, where a
        sign or quadrant changes, match either side:
        :func:`~rfsw_plan.export.config.configs_near`.)"""
        from rfsw_plan.export.config import configs_near

        if point.config == self.posture(robot, q):  # the usual case: no boundary to nudge
            return True
        return point.config in configs_near(self.posture, robot, q)

    def path_deviation(self, program: Program) -> FloatArray:
        """Bound of every verified sample's distance to the path the controller runs with
        this format's rounding at the points [m], (N,) (default: the vendor-neutral blend
        model, :func:`rfsw_plan.export.program.path_deviation`); export refuses a program
        whose bound exceeds the path tolerance. Formats of one program (KRL and RAPID share
        their cycle's) bound it once in a process."""
        from rfsw_plan.export.program import path_deviation

        for src, bound in _BOUNDS:
            if src is program:
                return bound.copy()
        bound = path_deviation(program)
        _BOUNDS[:] = [*_BOUNDS[-3:], (program, bound)]
        return bound.copy()

    def expected(self, program: Program) -> Samples:
        """The plan samples the re-read points must reproduce, in order (default: the
        samples of the program's moved-to points)."""
        return program.samples.subset(program.moved_points())

    def file_name(self, program: Program) -> str:
        """The main file's name."""
        return program.header.name + self.suffix

    def header_text(self, path: Path, lines: int = 80) -> str:
        """The text of the program's first ``lines`` lines as one string, comment markers
        (``;``, ``!``, a TP line number and its ``;`` end) taken off and the lines joined by
        a space: what ``check`` reads the header's ``plan id`` and level from. A format
        whose comments cut a long word over two lines overrides it and joins them again."""
        import re

        strip = re.compile(r"^\s*(?:\d+:)?\s*[;!]?\s*|\s*;\s*$")
        with Path(path).open(encoding="utf-8", errors="replace") as fh:
            return " ".join(strip.sub("", line) for _, line in zip(range(lines), fh,
                                                                    strict=False))


def formats() -> dict[str, type[ControllerFormat]]:
    """The registry (name -> class, by :attr:`ControllerFormat.order` then name), with every
    format module of this package imported: each module that is not one of
    :data:`SUPPORT_MODULES` (found with :mod:`pkgutil`, not listed)."""
    import pkgutil

    import rfsw_plan.export as package

    for mod in pkgutil.iter_modules(package.__path__):
        if not mod.name.startswith("_") and mod.name not in SUPPORT_MODULES:
            importlib.import_module(f"{package.__name__}.{mod.name}")
    return dict(sorted(FORMATS.items(), key=lambda kv: (kv[1].order, kv[0])))


def format_names() -> tuple[str, ...]:
    """The registered format names (``--format`` choices)."""
    return tuple(formats())


def get_format(name: str, option: str = "format") -> ControllerFormat:
    """An instance of the format called ``name``.

    Raises:
        InputError: Unknown name (lists the known ones).
    """
    reg = formats()
    if name not in reg:
        raise InputError(option, name, "unknown format", ", ".join(reg))
    return reg[name]()


def parse_formats(text: str, option: str = "formats") -> list[str]:
    """Comma-separated format list -> names (one-line error naming the bad one)."""
    names = [f.strip() for f in text.split(",") if f.strip()]
    reg = formats()
    bad = [f for f in names if f not in reg]
    if bad or not names:
        raise InputError(option, bad[0] if bad else "", "unknown format" if bad else "empty",
                         ", ".join(reg))
    return list(dict.fromkeys(names))


def format_for_file(path: str | Path) -> ControllerFormat:
    """The format whose main-file suffix ``path`` ends with (``.src``, ``.ls``, ``.mod``).

    Raises:
        InputError: No registered format writes that suffix.
    """
    name = Path(path).name.lower()
    for cls in formats().values():
        if cls.suffix and name.endswith(cls.suffix.lower()):
            return cls()
    known = ", ".join(f"{c.suffix} ({n})" for n, c in formats().items() if c.suffix)
    raise InputError(path, "", f"unknown program suffix '{Path(path).suffix}'", known)
