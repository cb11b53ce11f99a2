"""Backlash on campaigns generated outside the project (issue 34): gear play on joint 1 of
the ZK-500 under a lab's cable loads, and lost motion by approach direction on joint 1 of the
KR600 in an ISO 9283-style campaign, alone and with a second effect, are named and brought to
the noise floor; when the campaign shows one flank only, the report says what to add."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from _lab_campaign import lab_campaign

from rfsw_plan.cli.main import main

ARCMIN = np.radians(1.0 / 60.0)
NOISE_MM = 0.01


def _validate(robot: str, csv: Path, capsys: pytest.CaptureFixture[str]) -> dict:
    assert main(["validate", "--robot", robot, "--data", str(csv), "--json"]) == 0
    return json.loads(capsys.readouterr().out)




@pytest.mark.parametrize(("robot", "loaded", "columns"), [
    ("zk500", True, False),                 # gear play flips with the cable's torque on j1
    ("kuka_kr600_r2830", False, True),      # lost motion by approach (dir_qN columns)
])
def test_play_on_joint_1_is_named_and_reaches_the_floor(
    robot: str, loaded: bool, columns: bool, tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    camp = lab_campaign(robot, tmp_path / "lab.csv", play_joint=0, play_rad=2 * ARCMIN,
                        poses=25, loaded=loaded, approach_columns=columns, seed=3)
    assert camp.play_mm > 10 * NOISE_MM  # the play is visible
    js = _validate(robot, camp.path, capsys)
    dg = js["diagnosis"]
    assert js["verdict"] == "missing", js["message"]
    assert dg["named"] == ["lost_motion:j1"], dg["chain"]
    assert dg["chain"][-1]["heldout_rms_after_mm"] <= 1.5 * NOISE_MM
    top = js["candidates"][0]
    assert top["label"] == "lost_motion:j1"
    assert top["params"]["b"] == pytest.approx(2 * ARCMIN, rel=0.05)


def test_play_with_joint_offsets_is_named_with_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    offsets = (0.0, np.radians(0.02), np.radians(-0.03), 0.0, 0.0, 0.0)
    camp = lab_campaign("kuka_kr600_r2830", tmp_path / "lab.csv", play_joint=0,
                        play_rad=2 * ARCMIN, poses=25, loaded=False, approach_columns=True,
                        offsets_rad=offsets, seed=5)
    js = _validate("kuka_kr600_r2830", camp.path, capsys)
    dg = js["diagnosis"]
    assert js["verdict"] == "missing", js["message"]
    assert set(dg["named"]) == {"lost_motion:j1", "kinematic_offsets"}, dg["chain"]
    assert dg["chain"][-1]["heldout_rms_after_mm"] <= 1.5 * NOISE_MM


def test_one_flank_only_says_which_approach_to_add(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    camp = lab_campaign("kuka_kr600_r2830", tmp_path / "lab.csv", play_joint=0,
                        play_rad=2 * ARCMIN, poses=25, loaded=False, approach_columns=True,
                        from_below_only=True, seed=3)
    js = _validate("kuka_kr600_r2830", camp.path, capsys)
    dg = js["diagnosis"]
    assert "lost_motion:j1" not in dg["named"]
    reasons = {s["label"]: s["reason"] for s in dg["not_identifiable"]}
    assert "one side of its play" in reasons["lost_motion:j1"]
    tip = next(a for a in dg["advice"] if a.startswith("lost_motion:j1:"))
    assert "moving down" in tip
