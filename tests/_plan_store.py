"""A store of bundled plans shared by the pytest-xdist workers of one test session.

Under ``--dist loadfile`` each test file runs on one worker, and session fixtures live once per
worker: without a shared store every worker planned the same bundled problem again. The store
keeps each plan once on disk, keyed by the full input (the request, and a hash of the package's
source, the bundled problems and robots), under a file lock so that two workers never make the
same entry twice: the first one makes it, the others wait and read it.

Planning is deterministic and a result read back is the result planned
(``tests/test_plan_cache.py`` checks that the files written from a stored plan are the bytes of
a fresh plan's), so a stored entry stands for a fresh plan.

The store lives in the session's base temporary folder (the parent of each worker's, which
xdist shares between its workers); entries are never reused by a later session.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import shutil
from collections.abc import Callable, Iterator
from functools import cache
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: What a plan depends on besides its request: the package and its bundled data.
SOURCES = ("rfsw_plan", "problems", "robots")


@cache
def source_hash() -> str:
    """SHA-256 over the paths and bytes of every file under :data:`SOURCES` (caches skipped)."""
    h = hashlib.sha256()
    for top in SOURCES:
        for p in sorted((ROOT / top).rglob("*")):
            if p.is_file() and "__pycache__" not in p.parts:
                h.update(str(p.relative_to(ROOT)).encode() + b"\0")
                h.update(p.read_bytes() + b"\0")
    return h.hexdigest()


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """An exclusive lock on ``path`` (POSIX ``flock``; without it, no lock: at worst a
    plan is made twice, and the rename below keeps each entry whole)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    with open(path, "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


class PlanStore:
    """Entries are folders under ``root``, one per key, made once by :meth:`folder`."""

    def __init__(self, root: Path) -> None:
        self.root = root
        root.mkdir(parents=True, exist_ok=True)

    def folder(self, key: tuple[Any, ...], make: Callable[[Path], None]) -> Path:
        """The entry's folder: ``make(folder)`` fills it the first time ``key`` is asked for
        (in any worker); later calls return it as it is. Read it, never change it."""
        digest = hashlib.sha256(repr((source_hash(), key)).encode()).hexdigest()[:24]
        entry = self.root / digest
        with _locked(self.root / f"{digest}.lock"):
            if not entry.is_dir():
                tmp = self.root / f"{digest}.tmp"
                shutil.rmtree(tmp, ignore_errors=True)
                tmp.mkdir()
                make(tmp)
                tmp.rename(entry)
        return entry

    def result(self, key: tuple[Any, ...], make: Callable[[], Any]) -> Any:
        """``make()``'s return value, pickled once per key, read back from the store."""
        def write(folder: Path) -> None:
            (folder / "value.pickle").write_bytes(pickle.dumps(make()))

        return pickle.loads((self.folder(key, write) / "value.pickle").read_bytes())


def store_root(basetemp: Path) -> Path:
    """The session's store: beside the workers' folders under xdist, else in the base."""
    return (basetemp.parent if os.environ.get("PYTEST_XDIST_WORKER") else basetemp) / "plans"
