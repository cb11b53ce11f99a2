"""The reliability campaign in the test suite (issue 25): a seeded, bounded sample of every
input kind in the default run (seconds each), a longer one under ``-m slow``. A future
traceback, hang, silent accept or null output is then a failing test, not a user's surprise.

The cases and the outcome rules are in ``tests/fuzz_campaign.py`` (also a script that prints the
acceptance table). ``plan folders -> export`` is sampled too, but its reader is the plan-folder
reader of the programs work; it is checked here only for hangs and crashes.
"""

from __future__ import annotations

import pytest
from fuzz_campaign import KINDS, campaign

#: Cases per kind in the default run (each kind takes a few seconds; the commands' imports are
#: paid once by the first case).
DEFAULT = {"output paths": 10, "CLI numbers": 16, "URDF": 12, "measurement CSV": 12,
           "force logs": 8, "weld tracks": 5, "column maps": 8}
MINE = tuple(DEFAULT)


@pytest.mark.parametrize("kind", MINE)
def test_campaign_sample(kind: str, tmp_path) -> None:
    report = campaign({kind: DEFAULT[kind]}, seed=2025, folder=tmp_path)
    assert not report.bad(), report.bad()


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_campaign_long(kind: str, tmp_path) -> None:
    report = campaign({kind: 120}, seed=7, folder=tmp_path)
    bad = report.bad()
    if kind == "plan folders -> export":  # tracebacks there belong to the strict reader
        bad = [b for b in bad if b[1] in ("hang", "crash")]
    assert not bad, bad
