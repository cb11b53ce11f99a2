"""Independent jobs shared with forked processes on the machine's cores.

:func:`fork_map` runs ``task(0) ... task(n - 1)`` and returns the results in order: the jobs
are dealt out (every p-th) to ``p - 1`` forked workers and this process, which takes the
first share itself. The workers inherit ``task`` and everything it reads through ``fork``
(nothing is pickled on the way in); their results come back pickled. Each job is the same
computation wherever it runs, so the results do not depend on the split, and one job is
never split.

Where a process cannot be forked (no ``fork`` on the platform, a daemonic process, no
process to spare) or there is one core or one job, the jobs run here, one after the other. A
job that fails in a worker is run again here, so its exception is raised as itself (an
exception with several arguments does not always survive the pipe).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar("T")

#: The task the forked workers run (set for the length of one :func:`fork_map`).
_TASK: list[Callable[[int], Any]] = []


def cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform says)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1


def can_fork() -> bool:
    """Whether this process can fork workers (a POSIX ``fork`` start method and a process
    that is not a daemon: a daemonic process may not have children)."""
    import multiprocessing

    return ("fork" in multiprocessing.get_all_start_methods()
            and not multiprocessing.current_process().daemon)


def fork_map(task: Callable[[int], T], n: int, processes: int | None = None) -> list[T]:
    """``[task(0), ..., task(n - 1)]``, the jobs shared with forked workers (module
    docstring).

    Args:
        task: One job by its index; its result must pickle.
        n: The number of jobs.
        processes: Processes in all, this one included (default: :func:`cores`).
    """
    p = min(cores() if processes is None else processes, n)
    if p <= 1 or not can_fork():
        return [task(i) for i in range(n)]
    import multiprocessing

    _TASK.append(task)
    try:
        with multiprocessing.get_context("fork").Pool(p - 1, worker_signals) as pool:
            pending = {i: pool.apply_async(_job, (i,)) for i in range(n) if i % p}
            mine = {i: task(i) for i in range(0, n, p)}
            theirs = {i: r.get() for i, r in pending.items()}
            pool.close()
            pool.join()
    except OSError:  # no process to spare
        return [task(i) for i in range(n)]
    finally:
        _TASK.clear()
    out: list[T] = []
    for i in range(n):
        if i in mine:
            out.append(mine[i])
            continue
        ok, value = theirs[i]
        out.append(value if ok else task(i))  # a failed job raises here, as itself
    return out


def _job(i: int) -> tuple[bool, Any]:
    """Worker: job ``i`` of the inherited task, (True, its result) or (False, None)."""
    from rfsw_plan.progress import set_enabled

    set_enabled(False)
    try:
        return True, _TASK[-1](i)
    except Exception:  # raised again in the parent, where it is the caller's
        return False, None


def worker_signals() -> None:
    """A worker leaves Ctrl-C to the calling process (which stops the pool) and dies quietly
    on SIGTERM (the CLI's own handler, inherited through fork, would print a traceback)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
