"""Adapter around CasADi's machinery: C compilation cache and IPOPT's BLAS threads.

The NLP (:mod:`rfsw_plan.planning.nlp`) states the problem; this module holds what is about
running CasADi on this machine:

* :func:`compile_functions`: CasADi functions compiled to one shared library with the system C
  compiler, cached on disk by a hash of their serialisation (``$RFSW_PLAN_CACHE``, default
  ``$XDG_CACHE_HOME/rfsw_plan``);
* :func:`compile_in_background`: the same library built by a detached compiler process, for
  the plans after this one;
* :func:`single_thread_blas`: run IPOPT's MUMPS on one OpenBLAS thread (CasADi's bundled
  OpenBLAS, not numpy's).
"""

from __future__ import annotations

import ctypes
import hashlib
import logging
import os
import shutil
import subprocess
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

import casadi as ca

log = logging.getLogger(__name__)


def cache_dir() -> Path:
    """Folder of the compiled libraries: ``$RFSW_PLAN_CACHE`` or ``~/.cache/rfsw_plan``
    (:func:`rfsw_plan.files.cache_dir`, shared with the fitted penetration laws)."""
    from rfsw_plan.files import cache_dir as shared

    return shared()


def library_path(fns: Sequence[ca.Function], prefix: str) -> Path:
    """Where :func:`compile_functions` keeps the library of ``fns``: ``<prefix>_<hash>.so`` in
    :func:`cache_dir`, the hash over CasADi's version and the functions' serialisation (a
    change of the functions, e.g. of a row or of the robot's constants, is a new library)."""
    h = hashlib.sha1(str(getattr(ca, "__version__", "")).encode())
    for f in fns:
        h.update(f.serialize().encode())
    return cache_dir() / f"{prefix}_{h.hexdigest()[:16]}.so"


def compile_functions(fns: Sequence[ca.Function], prefix: str, fd_index: int | None = None,
                      optimise: str = "-O1") -> list[ca.Function] | None:
    """Compile functions to one shared library, cached on disk, and load them.

    Args:
        fns: The functions (SX or MX, code-generable).
        prefix: File name prefix of the library (``<prefix>_<hash>.so``).
        fd_index: If given, ``fns[fd_index]`` is loaded once more, last in the returned
            list, with finite-difference derivatives enabled (for an ``nlpsol`` definition
            that asks for derivative functions it never evaluates).
        optimise: The compiler's optimisation flag (``-O0`` compiles about 4x faster, its
            code runs about 1.4x slower; neither reorders floating-point operations, so both
            give the virtual machine's numbers bit for bit).

    Returns:
        The loaded functions (same order, plus the finite-difference copy), or None if no C
        compiler is available or compilation fails (the caller keeps the virtual machine).
    """
    cc = _compiler()
    if cc is None:
        log.info("no C compiler; CasADi functions run in the virtual machine")
        return None
    so = library_path(fns, prefix)
    d = so.parent
    try:
        if not so.exists():
            d.mkdir(parents=True, exist_ok=True)
            t0 = time.perf_counter()
            with tempfile.TemporaryDirectory(dir=d) as tmp:
                src = _generate(fns, so, Path(tmp))
                out = Path(tmp) / so.name
                subprocess.run([cc, optimise, "-shared", "-fPIC", str(src), "-o", str(out)],
                               check=True, capture_output=True, timeout=600)
                os.replace(out, so)  # atomic: a concurrent process sees all or nothing
            log.info("compiled %s in %.1f s (%s)", prefix, time.perf_counter() - t0, so)
        loaded = [ca.external(f.name(), str(so)) for f in fns]
        if fd_index is not None:
            loaded.append(ca.external(fns[fd_index].name(), str(so), {"enable_fd": True}))
        return loaded
    except (OSError, subprocess.SubprocessError, RuntimeError) as exc:
        log.warning("compiling %s failed (%s); using the virtual machine", prefix, exc)
        return None


def _compiler() -> str | None:
    """The C compiler (``$CC``, else ``gcc``, else ``cc``), or None."""
    return shutil.which(os.environ.get("CC", "gcc")) or shutil.which("cc")


def _generate(fns: Sequence[ca.Function], so: Path, folder: Path) -> Path:
    """CasADi's C code of ``fns`` for the library ``so``, written into ``folder``."""
    cg = ca.CodeGenerator(f"{so.stem}.c")
    for f in fns:
        cg.add(f)
    cg.generate(str(folder) + os.sep)
    return folder / f"{so.stem}.c"


#: A build folder (``<library>.building``) older than this [s] is left from a build that was
#: stopped (a reboot, a killed session), and a failed build's mark (``<library>.failed``)
#: this old is tried again: neither stops another build any longer.
BUILD_STALE_S = 900.0

#: What the detached build runs (``sh -c``; $1 compiler, $2 flag, $3 source, $4 output, $5
#: library, $6 build folder): the compiler at the lowest priority, the library renamed into
#: place once complete (a reader sees all of it or nothing), else a ``.failed`` mark beside
#: it; the folder removed either way. The outer shell returns at once.
_BUILD = ('( if command -v nice >/dev/null 2>&1; then n="nice -n 19"; else n=""; fi; '
          'if $n "$1" "$2" -shared -fPIC "$3" -o "$4" && mv -f "$4" "$5"; '
          'then :; else : > "$5.failed"; fi; rm -rf "$6" ) </dev/null >/dev/null 2>&1 &')


def compile_in_background(fns: Sequence[ca.Function], prefix: str, optimise: str) -> bool:
    """Start building the library :func:`compile_functions` would build (``prefix``,
    ``optimise``) in a detached process, for the plans after this one; True if started.

    The C code is generated here, into ``<library>.building`` beside the library; the
    compiler runs there at the lowest priority (``nice``) in a session of its own (it outlives
    this process and a Ctrl-C of its terminal) and the library is renamed into place once
    complete. Nothing is started where the library is on disk, where another process is
    building it (its build folder exists) or a build failed (its ``.failed`` mark), each
    unless older than :data:`BUILD_STALE_S`, or without a compiler, a shell or a writable
    cache folder.
    """
    cc, sh = _compiler(), shutil.which("sh")
    so = library_path(fns, prefix)
    if cc is None or sh is None or so.exists():
        return False
    build = so.with_name(so.name + ".building")
    failed = so.with_name(so.name + ".failed")
    try:
        so.parent.mkdir(parents=True, exist_ok=True)
        for mark in (build, failed):
            with suppress(FileNotFoundError):
                if time.time() - mark.stat().st_mtime <= BUILD_STALE_S:
                    return False
                if mark.is_dir():
                    shutil.rmtree(mark)
                else:
                    mark.unlink()
        build.mkdir()  # FileExistsError: another process started one just now
    except OSError:
        return False
    try:
        src = _generate(fns, so, build)
        subprocess.run([sh, "-c", _BUILD, "rfsw-plan-compile", cc, optimise, str(src),
                        str(build / so.name), str(so), str(build)],
                       check=True, start_new_session=True, timeout=60)
    except (OSError, RuntimeError, subprocess.SubprocessError) as exc:
        shutil.rmtree(build, ignore_errors=True)
        log.info("could not start compiling %s in the background (%s)", so.name, exc)
        return False
    log.info("compiling %s in the background for the next plans", so.name)
    return True


_BLAS: list[Any] = []


def casadi_blas() -> Any:
    """CasADi's own OpenBLAS (MUMPS' BLAS inside IPOPT; not numpy's), or None."""
    if not _BLAS:
        lib = None
        path = Path(ca.__file__).parent / "libcasadi-tp-openblas.so.0"
        if path.exists():
            try:
                lib = ctypes.CDLL(str(path))
                lib.openblas_get_num_threads.restype = ctypes.c_int
                lib.openblas_set_num_threads.argtypes = [ctypes.c_int]
            except (OSError, AttributeError):
                lib = None
        _BLAS.append(lib)
    return _BLAS[0]


@contextmanager
def single_thread_blas() -> Iterator[None]:
    """Run IPOPT's MUMPS with single-threaded BLAS; the previous thread count is restored.

    MUMPS' fronts on the banded KKT matrix are small: a second OpenBLAS thread only spins
    (sched_yield) and takes the CPU from the callbacks (about 5-10 % of the solve time on two
    cores). Only CasADi's bundled OpenBLAS is touched, numpy's BLAS is a separate library.
    """
    lib = casadi_blas()
    if lib is None:
        yield
        return
    before = int(lib.openblas_get_num_threads())
    lib.openblas_set_num_threads(1)
    try:
        yield
    finally:
        lib.openblas_set_num_threads(before)
