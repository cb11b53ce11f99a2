"""``rfsw_plan.parallel.fork_map``: the jobs' results in order whatever the split, a failed
job raised as itself, and the jobs run here where no worker can be forked."""

from __future__ import annotations

import os

import pytest

from rfsw_plan import parallel
from rfsw_plan.exceptions import InputError


def test_results_come_back_in_order_from_the_workers() -> None:
    pids = parallel.fork_map(lambda i: (i, i * i, os.getpid()), 7, processes=3)
    assert [(i, sq) for i, sq, _ in pids] == [(i, i * i) for i in range(7)]
    here = {pid for i, _, pid in pids if i % 3 == 0}
    assert here == {os.getpid()}  # this process takes every third job, the first one too
    if parallel.can_fork():
        assert all(pid != os.getpid() for i, _, pid in pids if i % 3)


def test_a_failed_job_is_raised_as_itself() -> None:
    def task(i: int) -> int:
        if i == 3:
            raise InputError("jobs.csv", "row 4", "not a number", "a number")
        return i

    with pytest.raises(InputError) as exc:  # job 3 runs in a worker: raised again here
        parallel.fork_map(task, 5, processes=2)
    assert "row 4" in str(exc.value)


def test_one_process_runs_every_job_here(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(parallel, "cores", lambda: 1)
    assert {pid for pid in parallel.fork_map(lambda i: os.getpid(), 4)} == {os.getpid()}
    monkeypatch.setattr(parallel, "can_fork", lambda: False)
    assert parallel.fork_map(lambda i: os.getpid(), 4, processes=4) == [os.getpid()] * 4
