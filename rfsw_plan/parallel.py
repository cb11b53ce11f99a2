"""Independent jobs shared with forked processes on the machine's cores.

:func:`fork_map` runs ``task(0) ... task(n - 1)`` and returns the results in order. This
process and ``p - 1`` forked workers each take the next job not yet taken, in the order the
caller gives (the longest first balances the cores), until none is left. The workers inherit
``task`` and everything it reads through ``fork`` (nothing is pickled on the way in); their
results come back pickled. Each job is the same computation wherever it runs, so the results
do not depend on the split, and one job is never split.

A failed job does not stop the others. Once every job has run, the first failed job by index
is run again here and its exception raised as itself (an exception with several arguments
does not always survive the pipe): which error a caller sees does not depend on which process
ran which job, or on the order they were started in.

Where a process cannot be forked (no ``fork`` on the platform, a daemonic process, no
process to spare) or there is one core or one job, the jobs run here, one after the other.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

T = TypeVar("T")

#: The task the forked workers run, its start order, the shared count of jobs taken, the
#: calling process and its ``on_done`` (set for the length of one :func:`fork_map`).
_SHARED: list[tuple[Callable[[int], Any], list[int], Any, int, Any]] = []


def cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform says)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1


def can_fork() -> bool:
    """Whether this process can fork workers (a POSIX ``fork`` start method and a process
    that is not a daemon: a daemonic process may not have children)."""
    import multiprocessing

    return ("fork" in multiprocessing.get_all_start_methods()
            and not multiprocessing.current_process().daemon)


def fork_map(task: Callable[[int], T], n: int, processes: int | None = None,
             order: Sequence[int] | None = None,
             on_done: Callable[[int], object] | None = None) -> list[T]:
    """``[task(0), ..., task(n - 1)]``, the jobs shared with forked workers (module
    docstring).

    Args:
        task: One job by its index; its result must pickle.
        n: The number of jobs.
        processes: Processes in all, this one included (default: :func:`cores`).
        order: The order the workers start the jobs in, a permutation of ``range(n)``
            (default: by index; in one process they run by index). It changes neither the
            results nor which failure is raised.
        on_done: Called in this process with a job's index once it has run: at once for
            the jobs run here, once the workers are done for theirs (a progress bar).
    """
    start = list(range(n)) if order is None else [int(i) for i in order]
    if sorted(start) != list(range(n)):
        raise ValueError(f"order must be a permutation of range({n}), got {start}")
    p = min(cores() if processes is None else processes, n)
    if p <= 1 or not can_fork():
        return _here(task, n, on_done)
    import multiprocessing

    ctx = multiprocessing.get_context("fork")
    _SHARED.append((task, start, ctx.Value("i", 0), os.getpid(), on_done))
    try:
        with ctx.Pool(p - 1, worker_signals) as pool:
            pending = [pool.apply_async(_drain) for _ in range(p - 1)]
            done = _drain()
            for r in pending:
                theirs = r.get()
                done.update(theirs)
                if on_done is not None:
                    for i in theirs:
                        on_done(i)
            pool.close()
            pool.join()
    except OSError:  # no process to spare
        return _here(task, n, on_done)
    finally:
        _SHARED.clear()
    return _in_order(task, done, n)


def _here(task: Callable[[int], T], n: int, on_done: Callable[[int], object] | None
          ) -> list[T]:
    """Every job in this process, by index (one process gains nothing from another order):
    the first failure is the first failed job by index, raised at once."""
    out: list[T] = []
    for i in range(n):
        out.append(task(i))
        if on_done is not None:
            on_done(i)
    return out


def _run(task: Callable[[int], Any], i: int) -> tuple[bool, Any]:
    """Job ``i``: (True, its result) or (False, the exception it raised)."""
    try:
        return True, task(i)
    except Exception as exc:  # raised by _in_order, in index order
        return False, exc


def _in_order(task: Callable[[int], T], done: dict[int, tuple[bool, Any]], n: int) -> list[T]:
    """The results by index. The first failed job (by index) raises: its exception if it ran
    here, else it is run again here (a worker's exception does not come back)."""
    for i in range(n):
        ok, value = done[i]
        if not ok:
            if isinstance(value, Exception):
                raise value
            task(i)  # raises as itself
            raise RuntimeError(f"job {i} failed in a worker but not here")  # pragma: no cover
    return [done[i][1] for i in range(n)]


def _drain() -> dict[int, tuple[bool, Any]]:
    """Take the next job not yet taken until none is left (in this process or a worker);
    the jobs run and their outcomes by index."""
    task, start, taken, caller, on_done = _SHARED[-1]
    worker = os.getpid() != caller
    if worker:  # the caller's progress bar is not a worker's to draw
        from rfsw_plan.progress import set_enabled

        set_enabled(False)
    done: dict[int, tuple[bool, Any]] = {}
    while True:
        with taken.get_lock():
            k = taken.value
            taken.value = k + 1
        if k >= len(start):
            return done
        ok, value = _run(task, start[k])
        done[start[k]] = (ok, None if worker and not ok else value)
        if not worker and on_done is not None:
            on_done(start[k])


def worker_signals() -> None:
    """A worker leaves Ctrl-C to the calling process (which stops the pool) and dies quietly
    on SIGTERM (the CLI's own handler, inherited through fork, would print a traceback)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
