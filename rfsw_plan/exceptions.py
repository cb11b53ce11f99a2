"""One exception hierarchy for rfsw_plan.

Every runtime failure the user can cause (bad file, unknown name, infeasible plan) raises a
subclass of :class:`RfswError`. The CLI maps any ``RfswError`` to one line on stderr and a
non-zero exit code; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path


class RfswError(Exception):
    """Root of all errors raised on purpose by rfsw_plan."""

    exit_code: int = 2


class InputError(RfswError):
    """A file, option or value supplied by the user is malformed.

    Attributes:
        source: File name or option the bad value came from.
        where: Row, column, key or field inside ``source`` (may be empty).
        expected: What a valid value looks like.
    """

    def __init__(self, source: str | Path, where: str, problem: str, expected: str = "") -> None:
        self.source = str(source)
        self.where = where
        self.problem = problem
        self.expected = expected
        loc = f"{self.source}: {where}: " if where else f"{self.source}: "
        msg = loc + problem
        if expected:
            msg += f" (expected {expected})"
        super().__init__(msg)


class UnknownNameError(RfswError):
    """A name (robot, effect, strategy, frame) that does not exist.

    The message lists the valid alternatives.
    """

    def __init__(self, kind: str, name: str, known: Iterable[str]) -> None:
        self.kind = kind
        self.name = name
        self.known = sorted(known)
        super().__init__(f"unknown {kind} '{name}'; known: {', '.join(self.known)}")


class OutputPathError(RfswError):
    """An output path that cannot take the files (a file, under a file, read-only, locked).

    Attributes:
        option: The option that named the path (``-o``, ``--save-robot``...).
        path: The offending path.
    """

    def __init__(self, option: str, path: str | Path, problem: str) -> None:
        self.option = option
        self.path = str(path)
        super().__init__(f"{option} {self.path}: {problem}")


class IdentificationError(RfswError):
    """The data cannot identify what was asked (too few samples, no measured axis...)."""


class UnreachableError(RfswError):
    """A target pose the robot cannot reach."""


class InfeasibleError(RfswError):
    """A plan or time parameterisation that cannot satisfy its constraints.

    Attributes:
        waypoint: Index of the offending waypoint (0-based), if any.
        constraint: Name of the binding constraint.
        margin: Signed margin at the offending waypoint [m] (negative = violated).
    """

    exit_code = 3

    def __init__(
        self,
        message: str,
        waypoint: int | None = None,
        constraint: str = "",
        margin: float | None = None,
    ) -> None:
        self.waypoint = waypoint
        self.constraint = constraint
        self.margin = margin
        super().__init__(message)
