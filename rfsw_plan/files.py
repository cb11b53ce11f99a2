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
import io
import json
import math
import os
import tempfile
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

from rfsw_plan.exceptions import OutputPathError

__all__ = [
    "LOCK_NAME",
    "OutputLock",
    "atomic_path",
    "cache_dir",
    "figures_in_memory",
    "prepare_output_dir",
    "prepare_output_file",
    "sha256_file",
    "strict_json",
    "to_jsonable",
    "write_bytes",
    "write_figure",
    "write_json",
    "write_text",
]

LOCK_NAME = ".rfsw-plan.lock"

#: Set by the CLI when SIGTERM or Ctrl-C arrived (:func:`note_interrupt`). Libraries may swallow
#: the KeyboardInterrupt the signal raises (CasADi's Python wrappers have bare ``except:``
#: clauses, and an interrupted IPOPT solve returns as a failed solve), so no file is given its
#: name after it: :func:`atomic_path` and :class:`OutputLock` raise it again.
_interrupted = False

#: Folders :func:`prepare_output_dir` created in this run (outermost first); an interrupted
#: command removes those left empty (:func:`remove_created_dirs`), so Ctrl-C writes nothing.
_created_dirs: list[Path] = []


def note_interrupt() -> None:
    """Record that the process was asked to stop (SIGTERM, Ctrl-C)."""
    global _interrupted
    _interrupted = True


def clear_interrupt() -> None:
    """Forget a recorded interruption (the CLI, when a run has ended)."""
    global _interrupted
    _interrupted = False


def check_interrupt() -> None:
    """Raise KeyboardInterrupt if the process was asked to stop and something swallowed it."""
    if _interrupted:
        raise KeyboardInterrupt


def created_this_run(path: str | Path) -> bool:
    """Whether :func:`prepare_output_dir` created the folder ``path`` in this run."""
    return Path(path) in _created_dirs


def forget_created_dirs() -> None:
    """Start a run: no folder is counted as created by it yet."""
    _created_dirs.clear()


def remove_created_dirs() -> None:
    """Remove the folders :func:`prepare_output_dir` created in this run that are empty
    (innermost first), then forget them: an interrupted command leaves no new empty folder."""
    for d in reversed(_created_dirs):
        with contextlib.suppress(OSError):
            d.rmdir()  # only if empty
    _created_dirs.clear()


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


#: Errors of the file system itself (full, read-only, quota, I/O): a one-line OutputPathError.
_FS_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EFBIG,
                        errno.EACCES, errno.EPERM, errno.ENAMETOOLONG, errno.EISDIR,
                        errno.ENOTDIR, errno.ELOOP})


def _anonymous_file(folder: Path) -> int | None:
    """An unnamed file in ``folder`` (Linux ``O_TMPFILE``), or None where that is not available.

    It has no name until :func:`_commit_file` links it: a process killed while writing it
    (SIGKILL included) leaves nothing behind, the kernel frees it.
    """
    flag = getattr(os, "O_TMPFILE", None)
    if flag is None or not os.path.isdir("/proc/self/fd"):
        return None
    try:
        return os.open(folder, flag | os.O_RDWR, 0o644)
    except OSError:  # a file system without O_TMPFILE support
        return None


def _commit_file(source: Path, target: Path, anonymous: bool) -> None:
    """Give the finished temporary ``source`` the name ``target`` in one step.

    An anonymous file is linked straight to ``target`` if that name is free (the file appears
    complete, no other name ever exists); otherwise it gets a temporary name that is renamed
    over ``target`` at once (``os.replace`` is atomic).
    """
    if not anonymous:
        os.replace(source, target)
        return
    try:
        _link(source, target)
        return
    except FileExistsError:
        pass
    named = target.parent / f".{target.name}.{os.getpid()}.{os.urandom(4).hex()}.tmp"
    _link(source, named)
    try:
        os.replace(named, target)
    except BaseException:
        with contextlib.suppress(OSError):
            named.unlink()
        raise


def _link(source: Path, target: Path) -> None:
    """``linkat(source, target, AT_SYMLINK_FOLLOW)``: the file behind ``/proc/self/fd/N`` gets
    the name ``target`` (a directory fd makes Python call ``linkat``, not ``link``, which would
    try to link the /proc entry itself)."""
    dfd = os.open(target.parent, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.link(source, target.name, src_dir_fd=dfd, dst_dir_fd=dfd, follow_symlinks=True)
    finally:
        os.close(dfd)


def _path_error(target: Path, exc: OSError) -> OutputPathError:
    why = exc.strerror or str(exc)
    if exc.errno == errno.EISDIR or (exc.errno in (errno.EEXIST, errno.ENOTEMPTY)
                                     and target.is_dir()):
        why = "is a folder; move it away or choose another output folder"
    return OutputPathError("output", target, f"cannot be written ({why})"
                           if "folder" not in why else why)


@contextlib.contextmanager
def atomic_path(target: str | Path) -> Iterator[Path]:
    """Yield a temporary path for ``target``; on success it becomes ``target`` in one step.

    Use it for writers that want a path (``csv.writer`` on an open file, ``np.savetxt``); a
    matplotlib figure goes through :func:`write_figure` (``savefig`` picks the format from a
    path's suffix, which the temporary has not). On Linux the temporary is an unnamed file
    (``O_TMPFILE``, reached as ``/proc/self/fd/N``): a process killed at any moment while
    writing, SIGKILL included, leaves no temporary file behind. Elsewhere it is a hidden file
    beside the target, which the next run into the folder removes. Either way a reader only
    ever sees the old file or the complete new one. On any exception the temporary is removed
    and ``target`` is untouched.

    Raises:
        OutputPathError: The target cannot be written: a folder of that name, a full or
            read-only file system, a name too long (one line, exit 2).
    """
    target = Path(target)
    check_interrupt()
    if target.parent == Path("/proc/self/fd"):  # already an outer atomic_path's temporary
        yield target
        return
    fd = _anonymous_file(target.parent)
    if fd is not None:
        tmp_path = Path(f"/proc/self/fd/{fd}")
    else:
        try:
            nfd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=f".tmp{target.suffix}",
                                        dir=target.parent)
        except OSError as exc:
            raise _path_error(target, exc) from None
        os.close(nfd)
        tmp_path = Path(tmp)
    try:
        yield tmp_path
        check_interrupt()  # never give a file its name after a stop request
        with open(tmp_path, "rb+") as fh:  # flush to disk before the name is given
            os.fsync(fh.fileno())
            os.fchmod(fh.fileno(), 0o644)
        _commit_file(tmp_path, target, fd is not None)
    except OSError as exc:
        if fd is None:
            with contextlib.suppress(OSError):
                tmp_path.unlink()
        if exc.errno in _FS_ERRNOS or isinstance(exc, IsADirectoryError):
            raise _path_error(target, exc) from None
        raise
    except BaseException:
        if fd is None:
            with contextlib.suppress(OSError):
                tmp_path.unlink()
        raise
    finally:
        if fd is not None:
            os.close(fd)


def cache_dir() -> Path:
    """Folder of the on-disk caches (CasADi's compiled libraries, fitted penetration laws):
    ``$RFSW_PLAN_CACHE``, else ``$XDG_CACHE_HOME/rfsw_plan``, else ``~/.cache/rfsw_plan``.
    A cache only saves time: every entry is keyed by a hash of all it depends on."""
    root = os.environ.get("RFSW_PLAN_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "rfsw_plan")
    return Path(root)


def write_bytes(target: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``target`` atomically; returns ``target`` as a Path."""
    target = Path(target)
    with atomic_path(target) as tmp:
        tmp.write_bytes(data)
    return target


def write_figure(target: str | Path, fig: Any, **savefig: Any) -> Path:
    """Draw a matplotlib figure into ``target`` atomically, in the format its suffix names.

    The image is rendered in memory (``fig.savefig`` to a buffer) and written by
    :func:`write_bytes`, so it gets the unnamed temporary of every other file: a process killed
    while plotting leaves nothing in the folder. ``savefig`` keywords (``dpi``...) are passed on.
    """
    target = Path(target)
    buf = io.BytesIO()
    fig.savefig(buf, format=target.suffix.lstrip(".").lower() or "png", **savefig)
    if _figures is not None:  # a drawing process: the caller's process writes them
        _figures[target] = buf.getvalue()
        return target
    return write_bytes(target, buf.getvalue())


#: The images :func:`write_figure` keeps in memory instead of writing (:func:`figures_in_memory`).
_figures: dict[Path, bytes] | None = None


@contextlib.contextmanager
def figures_in_memory() -> Iterator[dict[Path, bytes]]:
    """Inside the block :func:`write_figure` writes no file: it keeps each rendered image in
    the returned dict (target path -> bytes), for another process to write atomically (the
    plan's plots drawn beside the data files:
    :class:`rfsw_plan.planfiles.waypoints.PlotDrawing`)."""
    global _figures
    before, _figures = _figures, {}
    try:
        yield _figures
    finally:
        _figures = before


def read_program_text(path: str | Path) -> str:
    """The text of a controller program or stream file: UTF-8, as ``export`` writes it, else
    each byte as Latin-1.

    A program edited on a pendant or in an editor may come back with a remark in the
    controller's or the editor's 8-bit code page (an accented word). Its statements are ASCII,
    so only remarks and strings can hold such a byte, and Latin-1 reads every byte as one
    character: the statements read as written. A byte inside a statement still fails that
    statement's own parse, which names the line.
    """
    return program_text(Path(path).read_bytes())


def program_text(data: bytes) -> str:
    """:func:`read_program_text` of a file's bytes."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def write_text(target: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``target`` atomically; returns ``target`` as a Path."""
    return write_bytes(target, text.encode("utf-8"))


def without_wall_times(o: Any) -> Any:
    """``o`` without its wall times (every ``seconds`` key, at any depth): what a file holds,
    so that the same input writes the same bytes on any machine (the terminal prints them)."""
    if isinstance(o, dict):
        return {k: without_wall_times(v) for k, v in o.items() if k != "seconds"}
    if isinstance(o, list | tuple):
        return [without_wall_times(v) for v in o]
    return o


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
            or pseudo file system (``/proc``, ``/sys``), is a symbolic link loop, has a name
            too long, or cannot be written. One line, exit 2.
    """
    if not str(path).strip():
        raise OutputPathError(option, repr(str(path)), "is empty; give a folder")
    try:
        return _prepare_output_dir(Path(path), option)
    except OSError as exc:  # whatever the checks below did not foresee: still one line
        raise OutputPathError(option, path, f"cannot be used ({exc.strerror or exc})") from None


def _prepare_output_dir(p: Path, option: str) -> Path:
    resolved = _check_not_pseudo(p, option)
    if p.exists() and not p.is_dir():
        raise OutputPathError(option, p, "is an existing file, not a folder")
    for parent in resolved.parents:
        if parent.exists():
            if not parent.is_dir():
                raise OutputPathError(option, p, f"lies under the file {parent}")
            break
    new = [d for d in (*reversed(p.parents), p) if not d.exists()]
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputPathError(option, p, f"cannot be created ({exc.strerror or exc})") from None
    _created_dirs.extend(d for d in new if d not in _created_dirs)
    try:
        fd, probe = tempfile.mkstemp(prefix=".rfsw-probe.", dir=p)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputPathError(option, p, f"is not writable ({exc.strerror or exc})") from None
    return p


def _check_not_pseudo(p: Path, option: str) -> Path:
    try:
        resolved = p.resolve()
    except RuntimeError:  # Python < 3.13 reports a symbolic link loop so
        raise OutputPathError(option, p, "is a symbolic link loop") from None
    except OSError as exc:
        raise OutputPathError(option, p, f"cannot be resolved ({exc.strerror or exc})") from None
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
    if not str(path).strip():
        raise OutputPathError(option, repr(str(path)), "is empty; give a file name")
    try:
        return _prepare_output_file(path, option)
    except OSError as exc:
        raise OutputPathError(option, path, f"cannot be used ({exc.strerror or exc})") from None


def _prepare_output_file(path: str | Path, option: str) -> Path:
    p = Path(path)
    _check_not_pseudo(p, option)
    if len(p.name.encode()) > 255:
        raise OutputPathError(option, p.parent / (p.name[:40] + "..."),
                              f"a file name of {len(p.name.encode())} bytes is too long "
                              "(at most 255)")
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

    The lock is taken on the folder itself (``flock`` on its descriptor): no lock file is
    created, so nothing is left behind, not even after a SIGKILL (the kernel drops the lock
    with the process). A ``.rfsw-plan.lock`` left by an earlier version is removed.

    Usage::

        with OutputLock(out_dir):
            ...write files...

    Raises:
        OutputPathError: another rfsw-plan process holds the folder (one line, exit 2).
    """

    #: The locks this process holds, by resolved folder (see :meth:`held`).
    _held: dict[Path, OutputLock] = {}  # noqa: RUF012  (a registry, shared on purpose)

    def __init__(self, folder: str | Path, option: str = "-o") -> None:
        self.folder = Path(folder)
        self.option = option
        self._fd: int | None = None
        self._on_abort: list[Callable[[], None]] = []

    @classmethod
    def held(cls, folder: str | Path) -> OutputLock | None:
        """The lock this process holds on ``folder``, or None."""
        return cls._held.get(Path(folder).resolve())

    def on_abort(self, cleanup: Callable[[], None] | None) -> None:
        """Run ``cleanup`` if the locked block ends with an exception (Ctrl-C and SIGTERM
        included), before the lock is released; None forgets the registered cleanups (the
        writer has committed)."""
        if cleanup is None:
            self._on_abort.clear()
        else:
            self._on_abort.append(cleanup)

    def __enter__(self) -> OutputLock:
        import fcntl

        check_interrupt()
        try:
            fd = os.open(self.folder, os.O_RDONLY | os.O_DIRECTORY)
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
        self._fd = fd
        with contextlib.suppress(OSError):
            (self.folder / LOCK_NAME).unlink()  # an earlier version's lock file
        OutputLock._held[self.folder.resolve()] = self
        return self

    @classmethod
    def close_inherited(cls) -> None:
        """In a forked child: close the descriptors of the parent's locks (the parent keeps
        them; the child never writes the folder, and a child that outlives its parent does
        not keep the folder locked)."""
        for lock in cls._held.values():
            if lock._fd is not None:
                os.close(lock._fd)
                lock._fd = None
        cls._held.clear()

    def __exit__(self, exc_type: object, *exc: object) -> None:
        try:
            if exc_type is not None:
                for cleanup in reversed(self._on_abort):
                    with contextlib.suppress(Exception):
                        cleanup()
        finally:
            self._on_abort.clear()
            OutputLock._held.pop(self.folder.resolve(), None)
            if self._fd is not None:
                os.close(self._fd)  # closing releases the flock
                self._fd = None
