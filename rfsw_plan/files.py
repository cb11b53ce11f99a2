"""Output files that never lie: atomic writes, strict JSON, checked and locked output folders.

Every file rfsw_plan writes goes through this module:

* :func:`write_text`, :func:`write_bytes` and :func:`atomic_path` write to a temporary file in
  the same folder and ``os.replace`` it onto the target, so a reader (or a killed process) only
  ever sees the old file or the complete new one, never a truncated one.
* :func:`strict_json` turns NaN and +-inf into ``null`` (numpy scalars and arrays included) and
  refuses anything ``json`` cannot represent, so every JSON output parses with strict parsers
  (JavaScript ``JSON.parse``, Python ``json`` with ``parse_constant`` rejecting NaN).
* :func:`prepare_output_dir` checks an output folder before any work is done (one-line
  :class:`~rfsw_plan.exceptions.OutputPathError`, exit 2) and :class:`OutputLock` refuses a
  second concurrent writer to the same folder.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import math
import os
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from rfsw_plan.exceptions import OutputPathError

__all__ = [
    "LOCK_NAME",
    "OutputLock",
    "atomic_path",
    "prepare_output_dir",
    "prepare_output_file",
    "sha256_file",
    "strict_json",
    "to_jsonable",
    "write_bytes",
    "write_json",
    "write_text",
]

LOCK_NAME = ".rfsw-plan.lock"


def to_jsonable(obj: Any) -> Any:
    """A copy of ``obj`` made only of JSON types; NaN and +-inf become ``None``.

    Handles dicts, lists, tuples, numpy arrays and scalars, ``Path`` and objects with a
    ``to_dict()`` method. Raises ``TypeError`` for anything else (a bug, not user input).
    """
    if obj is None or isinstance(obj, (bool, str)):
        return obj
    if isinstance(obj, int):
        return int(obj)
    if isinstance(obj, float):
        return obj + 0.0 if math.isfinite(obj) else None  # + 0.0: never -0.0
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    try:  # numpy without importing it here
        import numpy as np

        if isinstance(obj, np.ndarray):
            return to_jsonable(obj.tolist())
        if isinstance(obj, np.bool_):
            return bool(obj)
        if isinstance(obj, np.integer):
            return int(obj)
        if isinstance(obj, np.floating):
            return to_jsonable(float(obj))
    except ImportError:  # pragma: no cover
        pass
    to_dict = getattr(obj, "to_dict", None)
    if callable(to_dict):
        return to_jsonable(to_dict())
    raise TypeError(f"cannot write {type(obj).__name__} as JSON")


def strict_json(obj: Any, indent: int | None = 2) -> str:
    """``obj`` as strict JSON text (no NaN or Infinity tokens), ending with a newline."""
    return json.dumps(to_jsonable(obj), indent=indent, allow_nan=False) + "\n"


@contextlib.contextmanager
def atomic_path(target: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; on success it replaces ``target`` atomically.

    Use it for writers that want a path (``savefig``, ``np.savetxt``). On any exception the
    temporary file is removed and ``target`` is untouched.
    """
    target = Path(target)
    # The temporary keeps the target's suffix, so writers that infer the format from the name
    # (matplotlib's savefig) write the right format.
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".tmp{target.suffix}",
                               dir=target.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        with open(tmp_path, "rb+") as fh:  # flush to disk before the rename
            os.fsync(fh.fileno())
        os.chmod(tmp_path, 0o644)
        os.replace(tmp_path, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        raise


def write_bytes(target: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``target`` atomically; returns ``target`` as a Path."""
    target = Path(target)
    with atomic_path(target) as tmp:
        tmp.write_bytes(data)
    return target


def write_text(target: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``target`` atomically; returns ``target`` as a Path."""
    return write_bytes(target, text.encode("utf-8"))


def write_json(target: str | Path, obj: Any) -> Path:
    """Write ``obj`` as strict JSON to ``target`` atomically."""
    return write_text(target, strict_json(obj))


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def prepare_output_dir(path: str | Path, option: str = "-o") -> Path:
    """Create (if needed) and check an output folder before any work is done.

    Raises:
        OutputPathError: the path is an existing file, lies under a file, is on a read-only
            or pseudo file system (``/proc``, ``/sys``), or cannot be written. One line, exit 2.
    """
    p = Path(path)
    resolved = _check_not_pseudo(p, option)
    if p.exists() and not p.is_dir():
        raise OutputPathError(option, p, "is an existing file, not a folder")
    for parent in resolved.parents:
        if parent.exists():
            if not parent.is_dir():
                raise OutputPathError(option, p, f"lies under the file {parent}")
            break
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputPathError(option, p, f"cannot be created ({exc.strerror or exc})") from None
    try:
        fd, probe = tempfile.mkstemp(prefix=".rfsw-probe.", dir=p)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputPathError(option, p, f"is not writable ({exc.strerror or exc})") from None
    return p


def _check_not_pseudo(p: Path, option: str) -> Path:
    resolved = p.resolve()
    if resolved.parts[:2] in (("/", "proc"), ("/", "sys"), ("/", "dev")):
        raise OutputPathError(option, p, "is on a pseudo file system; choose a normal folder")
    return resolved


def prepare_output_file(path: str | Path, option: str = "-o") -> Path:
    """Check (and create the folder of) an output *file* before any work is done.

    An existing file is fine (it is replaced atomically when written); a folder, a path under
    a file, a pseudo file system or a folder that cannot be written is refused.

    Raises:
        OutputPathError: one line naming the option and the path, exit 2.
    """
    p = Path(path)
    _check_not_pseudo(p, option)
    if p.is_dir():
        raise OutputPathError(option, p, "is a folder; give a file name")
    if str(path).endswith(("/", os.sep)):
        raise OutputPathError(option, p, "ends with a path separator; give a file name")
    parent = p.parent if str(p.parent) else Path(".")
    try:
        prepare_output_dir(parent, option)
    except OutputPathError as exc:
        raise OutputPathError(option, p, str(exc).split(": ", 1)[-1].replace(
            "is an existing file, not a folder", f"lies under the file {parent}")) from None
    if p.exists() and not os.access(p, os.W_OK):
        raise OutputPathError(option, p, "exists and is read-only")
    return p


class OutputLock:
    """An exclusive lock on an output folder, so two writers never mix their files.

    Usage::

        with OutputLock(out_dir):
            ...write files...

    Raises:
        OutputPathError: another rfsw-plan process holds the folder (one line, exit 2).
    """

    def __init__(self, folder: str | Path, option: str = "-o") -> None:
        self.folder = Path(folder)
        self.option = option
        self._fd: int | None = None

    def __enter__(self) -> OutputLock:
        import fcntl

        path = self.folder / LOCK_NAME
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise OutputPathError(self.option, self.folder,
                                  f"cannot be locked ({exc.strerror or exc})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                raise OutputPathError(
                    self.option, self.folder,
                    "is being written by another rfsw-plan process; wait for it or choose "
                    "another folder") from None
            raise OutputPathError(self.option, self.folder,
                                  f"cannot be locked ({exc.strerror or exc})") from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._fd = fd
        return self

    def __exit__(self, *exc: object) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing releases the flock; the file itself stays (harmless)
            self._fd = None
