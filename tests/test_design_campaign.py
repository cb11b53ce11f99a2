"""``rfsw-plan design-campaign`` (issue 34): N poses chosen by D-optimality of the
identification Jacobian identify a hidden effect that random campaigns of the same size, drawn
from the same candidates, do not."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.elastostatics.effects.base import PoseBatch
from rfsw_plan.elastostatics.identification import identify
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.robot.kinematics import load_robot
from rfsw_plan.validation.campaign.design import DesignRequest, random_campaign

EFFECTS = ("payload_gravity", "joint_backlash:j1")
TRUTH = {"payload_gravity": [150.0, 0.0, 0.0, -37.5], "joint_backlash:j1": [2e-4]}
POSES = 6
NOISE_M = 3e-5


def _read_design(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(q [rad], wrench [N], approach or None) of a design CSV, read with the csv module."""
    with path.open() as fh:
        rows = list(csv.DictReader(fh))
    q = np.radians([[float(r[f"q{j}_deg"]) for j in range(1, 7)] for r in rows])
    w = np.array([[float(r[k]) for k in ("fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm")]
                  for r in rows])
    a = (np.array([[float(r[f"dir_q{j}"]) for j in range(1, 7)] for r in rows])
         if "dir_q1" in rows[0] else None)
    return q, w, a


def _identified(q: np.ndarray, w: np.ndarray, a: np.ndarray | None, seed: int) -> bool:
    """Measure the samples on a truth with the hidden effects (noise NOISE_M per axis),
    identify the model with them and say whether the backlash is identified: a standard error
    below 10 % of its size and the estimate within 3 standard errors of the truth."""
    robot = load_robot("zk500")
    truth = ElastostaticModel(robot)
    for label in EFFECTS:
        truth = truth.with_effect(label)
        truth.effects[-1].params = np.array(TRUTH[label])
    batch = PoseBatch.from_q(robot, q, a, force_noise=5.0)
    p = batch.T[:, :3, 3] + truth.deflection_batch(batch, w)[:, :3]
    p = p + np.random.default_rng(seed).normal(0.0, NOISE_M, p.shape)
    form = ElastostaticModel(robot)
    for label in EFFECTS:
        form = form.with_effect(label)
    fit = identify(form, MeasurementSet(q=q, wrench=w, position=p, approach=a))
    (b,) = [e for e in fit.estimates if e.effect == "joint_backlash:j1"]
    b0 = TRUTH["joint_backlash:j1"][0]
    return bool(b.identified and b.std_error < 0.1 * b0 and abs(b.value - b0) < 3 * b.std_error)


def test_a_designed_campaign_identifies_what_random_ones_of_its_size_do_not(
    tmp_path: Path, capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "design"
    assert main(["design-campaign", "--robot", "zk500", "--poses", str(POSES), "--effects",
                 ",".join(EFFECTS), "-o", str(out), "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["poses"] == POSES and js["condition_number"] < js["random_condition_number"]
    q, w, a = _read_design(out / "design.csv")
    assert q.shape == (POSES, 6)
    # The loads reverse joint 1's torque: backlash is seen from both sides.
    tau1 = np.array([load_robot("zk500").jacobian(qi)[:, 0] @ wi for qi, wi in zip(q, w,
                                                                                 strict=True)])
    assert (tau1 > 60).sum() >= 1 and (tau1 < -60).sum() >= 1
    designed = [_identified(q, w, a, seed) for seed in range(3)]
    request = DesignRequest(load_robot("zk500"), POSES, EFFECTS)
    randoms = []
    for seed in range(10):
        r = random_campaign(request, seed)
        wr = np.concatenate([r.force, np.zeros_like(r.force)], axis=1)
        randoms.append(_identified(r.q, wr, None, 0))
    print(f"designed: identified in {sum(designed)} of 3 noise draws; random campaigns of "
          f"{POSES} poses: {sum(randoms)} of 10")
    assert all(designed)
    assert sum(randoms) <= 3


def test_lost_motion_gets_approach_directions_both_ways(tmp_path: Path) -> None:
    # An unloaded (ISO 9283-style) campaign: the approach sets the side of joint 1's play.
    out = tmp_path / "d"
    assert main(["design-campaign", "--robot", "kuka_kr600_r2830", "--poses", "8",
                 "--effects", "lost_motion:j1", "--load-N", "0", "-o", str(out)]) == 0
    _, w, a = _read_design(out / "design.csv")
    assert not w.any()
    assert a is not None and sorted(set(a[:, 0])) == [-1.0, 1.0]
    assert min((a[:, 0] > 0).sum(), (a[:, 0] < 0).sum()) >= 3
    assert not a[:, 1:].any()  # only the joint whose play matters
    js = json.loads((out / "design.json").read_text())
    assert "joint_compliance.c1" in js["not_seen"]  # no load: no stiffness to see


def test_too_few_poses_is_one_line_exit_2(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["design-campaign", "--robot", "zk500", "--poses", "2", "--effects",
                 "payload_gravity", "-o", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "at least 4 poses for the 10 parameters" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "x").exists()
