"""``rfsw_plan.parallel.fork_map``: the jobs' results in order whatever the split and the
start order, the first failed job by index raised as itself, and the jobs run here where no
worker can be forked."""

from __future__ import annotations

import os

import pytest

from rfsw_plan import parallel
from rfsw_plan.exceptions import InputError


def test_results_come_back_in_order_from_the_workers() -> None:
    pids = parallel.fork_map(lambda i: (i, i * i, os.getpid()), 7, processes=3)
    assert [(i, sq) for i, sq, _ in pids] == [(i, i * i) for i in range(7)]
    if parallel.can_fork():  # every job ran once, here or in one of the two workers
        assert len({pid for _, _, pid in pids} - {os.getpid()}) <= 2


@pytest.mark.parametrize("processes", [1, 2])
def test_the_start_order_changes_no_result(processes: int) -> None:
    order = [4, 0, 3, 1, 2]
    assert parallel.fork_map(lambda i: 10 * i, 5, processes, order) == [0, 10, 20, 30, 40]
    with pytest.raises(ValueError, match="permutation"):
        parallel.fork_map(lambda i: i, 3, processes, [0, 0, 1])


@pytest.mark.parametrize("processes", [1, 2])
def test_the_first_failed_job_by_index_is_raised_as_itself(processes: int) -> None:
    """Jobs 1 and 3 fail; job 3 is started first, but job 1's error is the one raised,
    wherever each ran (a worker's exception is raised again here)."""
    def task(i: int) -> int:
        if i in (1, 3):
            raise InputError("jobs.csv", f"row {i + 1}", "not a number", "a number")
        return i

    with pytest.raises(InputError) as exc:
        parallel.fork_map(task, 5, processes, order=[3, 4, 2, 1, 0])
    assert "row 2" in str(exc.value)


def test_one_process_runs_every_job_here(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(parallel, "cores", lambda: 1)
    assert {pid for pid in parallel.fork_map(lambda i: os.getpid(), 4)} == {os.getpid()}
    monkeypatch.setattr(parallel, "can_fork", lambda: False)
    assert parallel.fork_map(lambda i: os.getpid(), 4, processes=4) == [os.getpid()] * 4


def test_a_free_process_takes_the_next_job() -> None:
    """Job 0 waits until every other job is done: the other process takes them all (jobs are
    taken, not dealt out in advance; dealt out, job 2 would wait behind job 0 here)."""
    import multiprocessing
    import time

    if not parallel.can_fork():
        pytest.skip("no fork on this platform")
    finished = multiprocessing.get_context("fork").Value("i", 0)

    def task(i: int) -> int:
        if i == 0:
            deadline = time.monotonic() + 60
            while finished.value < 4 and time.monotonic() < deadline:
                time.sleep(0.01)
            return -1 if finished.value < 4 else os.getpid()
        with finished.get_lock():
            finished.value += 1
        return os.getpid()

    pids = parallel.fork_map(task, 5, processes=2)
    assert pids[0] != -1, "job 0 waited for jobs nobody took"
    assert len(set(pids[1:])) == 1 and pids[1] != pids[0]


@pytest.mark.parametrize("processes", [1, 2])
def test_on_done_hears_of_every_job_once_in_this_process(processes: int) -> None:
    heard: list[tuple[int, int]] = []
    parallel.fork_map(lambda i: i, 6, processes, on_done=lambda i: heard.append((i, os.getpid())))
    assert sorted(i for i, _ in heard) == list(range(6))
    assert {pid for _, pid in heard} == {os.getpid()}


def test_in_one_process_the_first_failure_stops_the_jobs() -> None:
    """Serially the jobs run by index and the first failure is raised at once: no job after
    it runs for nothing (export refusing a format's path does not write and judge the rest)."""
    ran: list[int] = []

    def task(i: int) -> int:
        ran.append(i)
        if i == 1:
            raise InputError("jobs.csv", "row 2", "not a number", "a number")
        return i

    with pytest.raises(InputError):
        parallel.fork_map(task, 5, processes=1, order=[4, 3, 2, 1, 0])
    assert ran == [0, 1]
