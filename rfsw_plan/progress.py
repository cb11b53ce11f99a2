"""Progress bars on stderr for steps that can take more than about two seconds.

One switch for the whole tool: bars are shown only when stderr is a terminal and the CLI was
not given ``--quiet`` (:func:`set_enabled`). They never write to stdout, so ``--json`` output
stays clean. The library itself stays silent unless the caller enables bars.

Example::

    from rfsw_plan.progress import progress

    for candidate in progress(candidates, desc="diagnosis", unit="candidate"):
        ...

    with Stages("validate-weld", ("reading", "diagnosis", "report")) as stages:
        ...                   # reading
        stages.start("diagnosis")
        ...
"""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator, Sequence
from typing import Any, TypeVar

__all__ = ["Bar", "Stages", "enabled", "progress", "set_enabled"]

T = TypeVar("T")

_enabled: bool = False


def set_enabled(on: bool) -> None:
    """Turn bars on (only takes effect when stderr is a terminal) or off."""
    global _enabled
    _enabled = bool(on)


def enabled() -> bool:
    """True when bars are switched on and stderr is a terminal."""
    return _enabled and sys.stderr.isatty()


def progress(items: Iterable[T], desc: str, total: int | None = None,
             unit: str = "it") -> Iterator[T]:
    """Iterate ``items`` with a progress bar on stderr when bars are enabled."""
    if not enabled():
        yield from items
        return
    from tqdm import tqdm  # lazy: only when a bar is actually drawn

    yield from tqdm(items, desc=desc, total=total, unit=unit, file=sys.stderr, leave=False,
                    dynamic_ncols=True)


class Bar:
    """A manually advanced bar (``with Bar(total, desc) as bar: bar.update(1)``).

    A no-op when bars are disabled, so callers need no branches.
    """

    def __init__(self, total: int | None, desc: str, unit: str = "it") -> None:
        self._bar: Any = None
        if enabled():
            from tqdm import tqdm

            self._bar = tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False,
                             dynamic_ncols=True)

    def update(self, n: int = 1) -> None:
        if self._bar is not None:
            self._bar.update(n)

    def set_description(self, desc: str) -> None:
        if self._bar is not None:
            self._bar.set_description(desc)

    def __enter__(self) -> Bar:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.close()


class Stages:
    """A bar over the named stages of one command; its label names the running stage.

    For commands whose steps are few and long (reading, diagnosis, plots): the user sees what
    runs now and how many steps are left. A bar of an inner loop (e.g. the diagnosis
    candidates) is drawn below it. A no-op when bars are disabled.

    Args:
        command: The label's prefix (the command's name, e.g. ``"validate-weld"``).
        names: The stages in order; the first one starts at once.
    """

    def __init__(self, command: str, names: Sequence[str]) -> None:
        if not names:
            raise ValueError("Stages needs at least one stage")
        self._command = command
        self._names = list(names)
        self._k = 0
        self._bar = Bar(len(self._names), f"{command}: {self._names[0]}", unit="step")

    def start(self, name: str) -> None:
        """The running stage is done; stage ``name`` (a later one of ``names``) starts."""
        k = self._names.index(name, self._k + 1)  # ValueError for an unknown or past stage
        self._bar.update(k - self._k)
        self._k = k
        self._bar.set_description(f"{self._command}: {name}")

    def __enter__(self) -> Stages:
        return self

    def __exit__(self, *exc: object) -> None:
        self._bar.__exit__(*exc)
