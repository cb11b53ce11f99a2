"""Lost motion at j1 on lab campaigns the workbench did not design (issue 40).

The campaigns come from tests/lab_campaigns.py (a lab's jack procedure, ISO 9283 poses, no
workbench code): 0.6 arcmin of gear play at j1, friction (300 N m) holding the output on the
flank the last load above it pushed it to, arriving at a pose the output lagging the motor.
What a lab varies from campaign to campaign is varied by the seed: zero-load readings between
the directions or not, the order of the directions, zero readings forgotten, the repeats on
arrival. The claim: ``validate`` says "missing lost_motion:j1" and the held-out RMS with it is
within FLOOR_RATIO x the noise floor, on 9 of 10 campaigns on the KR600 and on the ZK-500.

The campaign's first pose is reached with no motion before it in the file: until the first
load that turns j1, nothing tells the side of the play of its readings (a state of the
campaign, +-b/2). ``validate`` names those readings (one line, the JSON's
``indeterminate_readings``) and scores them against the model's stated spread +-b/2, never
against a side read from the held-out readings themselves; before it did, seeds 103, 104 and
107 on the ZK-500 stayed at 1.56-1.67 x the floor (7 of 10).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from lab_campaigns import lab_campaign

from rfsw_plan.cli.main import main
from rfsw_plan.validation.engine.diagnosis import FLOOR_RATIO

#: The campaigns' seeds (fixed).
SEEDS = range(100, 110)


def lab_variant(seed: int) -> dict[str, object]:
    """What the lab varies: zero-load readings between the directions or not, the order of
    the directions, a share of the zero readings forgotten, the repeats on arrival."""
    return {"zero_between": seed % 2 == 0, "shuffle": seed % 3 == 0,
            "skip_zero": 0.2 if seed % 4 == 0 else 0.0, "repeats": 2 + seed % 2}


def lost_motion_named(robot: str, seed: int, tmp_path: Path,
                      capsys: pytest.CaptureFixture[str]) -> tuple[bool, str]:
    """(right, log line): right when the verdict is "missing" with lost_motion:j1 named
    first and the held-out RMS within FLOOR_RATIO x the floor."""
    kw = lab_variant(seed)
    camp = lab_campaign(robot, tmp_path / f"lm_{robot}_{seed}.csv", ("lost_motion",),
                        seed=seed, **kw)  # type: ignore[arg-type]
    assert main(["validate", "--robot", robot, "--data", str(camp.path), "--no-report",
                 "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    dg = js["diagnosis"]
    effects = dg["named"] or dg["partly_explained"]
    right = (js["verdict"] == "missing" and effects[:1] == ["lost_motion:j1"]
             and dg["floor_ratio"] <= FLOOR_RATIO)
    # The readings of unknown side are the first pose's only, named with their reason.
    ind = dg["indeterminate"]
    assert dg["indeterminate_readings"] == sum(x["readings"] for x in ind)
    assert all(x["poses"] == ["P01"] and "side of the play unknown" in x["reason"]
               for x in ind), ind
    return right, (f"{robot} seed {seed} {kw}: {js['verdict']} {' + '.join(effects)} "
                   f"{dg['floor_ratio']:.2f} x floor {'ok' if right else 'WRONG'}")


@pytest.mark.parametrize(("robot", "seed"), [("zk500", 101), ("zk500", 102),
                                             ("kuka_kr600_r2830", 101)])
def test_lost_motion_at_j1_is_named_on_a_lab_campaign(
    robot: str, seed: int, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    right, line = lost_motion_named(robot, seed, tmp_path, capsys)
    assert right, line


@pytest.mark.slow
@pytest.mark.parametrize("robot", ["kuka_kr600_r2830", "zk500"])
def test_lost_motion_at_j1_nine_of_ten_lab_campaigns(
    robot: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    results = [lost_motion_named(robot, s, tmp_path, capsys) for s in SEEDS]
    with capsys.disabled():
        print("\n" + "\n".join(line for _, line in results))
    assert sum(r for r, _ in results) >= 9, [line for r, line in results if not r]


def test_readings_of_unknown_side_are_named_with_their_pose_and_advice(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Seed 103 on the ZK-500 (was 1.58 x the floor): the first pose's readings before the
    first load on j1 are named on one line with their count, pose and reason, and the advice
    says how the next campaign avoids them."""
    camp = lab_campaign("zk500", tmp_path / "lm.csv", ("lost_motion",), seed=103,
                        **lab_variant(103))  # type: ignore[arg-type]
    assert main(["validate", "--robot", "zk500", "--data", str(camp.path), "--no-report"]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("unknown state:"))
    assert " reading(s) at pose P01 " in line and "lost_motion:j1" in line
    assert "side of the play unknown before the first load on j1" in line
    assert "next campaign: lost_motion:j1: move j1 onto the first pose from a known side" in out
    assert "verdict: missing: lost_motion:j1" in out


def test_the_score_of_readings_of_unknown_side_picks_no_side(tmp_path: Path) -> None:
    """The first readings of seed 103 sit on the -b/2 flank of j1 (the generator's arrival
    lag). Moved to the +b/2 flank (b the fitted play, along j1's motion) they score the same:
    the held-out score measures them against the model's +-b/2 spread, at the tracker's noise
    either way (they are 0.17 mm off the middle of the play), and no side is read from them."""
    from dataclasses import replace

    from rfsw_plan.elastostatics.model import load_model
    from rfsw_plan.io.measurements import read_measurements
    from rfsw_plan.validation.engine.crossval import cross_validate, make_folds

    camp = lab_campaign("zk500", tmp_path / "lm.csv", ("lost_motion",), seed=103,
                        **lab_variant(103))  # type: ignore[arg-type]
    model = load_model("zk500").with_effect("lost_motion:j1")
    data = read_measurements(camp.path, 6)
    folds = make_folds(data, 5)
    cv = cross_validate(model, data, folds, model.batch_of(data))
    (ind,) = cv.indeterminate
    assert ind.label == "lost_motion:j1" and ind.poses == ("P01",) and ind.count >= 2
    b = float(cv.fit.model.effects[-1].params[0])
    lever = np.linalg.norm(model.batch_of(data).J[ind.rows, :3, 0], axis=1)
    assert np.all(lever * b / 2 > 0.1e-3)  # the middle of the play is 0.1 mm+ off
    moved = data.position.copy()
    moved[ind.rows] += model.batch_of(data).J[ind.rows, :3, 0] * b
    other = replace(data, position=moved)
    cv2 = cross_validate(model, other, folds, model.batch_of(other))
    for c in (cv, cv2):
        at = c.heldout_residual[ind.rows]
        assert np.sqrt(np.nanmean(at ** 2)) < 0.02e-3  # the tracker's noise is 0.01 mm
    assert cv2.heldout_rms == pytest.approx(cv.heldout_rms, rel=0.02)
