"""Posture flags against public, sourced facts (``tests/data/vendor/posture_facts.csv``), not
against our own reader: a ROBOGUIDE-derived FANUC configuration table and the statements of
RoboDK's post-processors (issue 23)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.export.config import abb_confdata, fanuc_config, kuka_status_turn, posture
from rfsw_plan.robot.kinematics import load_robot

FACTS = Path(__file__).parent / "data" / "vendor" / "posture_facts.csv"


def _rows(vendor: str, use: str) -> list[dict[str, str]]:
    with FACTS.open(encoding="utf-8") as fh:
        return [r for r in csv.DictReader(fh) if r["vendor"] == vendor and r["use"] == use]


def _q(row: dict[str, str]) -> np.ndarray:
    return np.radians([float(row[f"j{i}_deg"]) for i in range(1, 7)])


def test_every_fact_names_its_source() -> None:
    with FACTS.open(encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) > 80
    assert all(r["source"].strip() for r in rows)
    assert len(_rows("FANUC", "flip")) == 67


@pytest.mark.parametrize("row", _rows("FANUC", "flip"), ids=lambda r: r["case"])
def test_fanuc_wrist_flag_matches_roboguide(row: dict[str, str]) -> None:
    """The first CONFIG letter (flip) depends only on FANUC's J5 (F if J5 > 0, as RoboDK's
    R-30iA post-processor states), so the CRX table's letters hold for any FANUC arm."""
    robot = load_robot("fanuc_s900ib_400")
    assert fanuc_config(robot, _q(row))[0] == row["expected"][0]


def test_fanuc_home_is_nut() -> None:
    """HOME (J5 = -90 deg, the rest 0) is 'N U T' in the ROBOGUIDE table, on our FANUC too."""
    (row,) = _rows("FANUC", "config")
    assert row["expected"] == "N U T"
    assert fanuc_config(load_robot("fanuc_s900ib_400"), _q(row)).startswith("N U T, 0, 0, 0")


def test_fanuc_butt_joint_values_are_no_flip() -> None:
    """fanuc_butt_1700mm welds with J5 between -48.1 and -46.8 deg: the sourced rule gives N
    (the earlier writer said F: a controller following it flips the wrist)."""
    robot = load_robot("fanuc_s900ib_400")
    for j5 in (-48.1, -47.5, -46.8):
        q = np.radians([-2.0, 20.0, -10.0, 1.0, j5, 3.0])
        assert fanuc_config(robot, q).startswith("N U T")


def test_kuka_turn_and_status_rules() -> None:
    """T bit i = axis i+1 < 0 (RoboDK KRC4 post); S bit 1 elbow up, bit 2 flip (A5 < 0), bit 0
    overhead (wrist root behind the A1 axis: KUKA's expert manual)."""
    robot = load_robot("kuka_kr600_r2830")
    (ex,) = _rows("KUKA", "T")
    assert kuka_status_turn(robot, _q(ex))[1] == int(ex["expected"])
    home = np.radians([0.0, -90.0, 90.0, 0.0, 30.0, 0.0])  # upper arm up, forearm forward
    s, t = kuka_status_turn(robot, home)
    assert s == 0b010 and t == 0b000010
    s_neg, _ = kuka_status_turn(robot, np.radians([0.0, -90.0, 90.0, 0.0, -30.0, 0.0]))
    assert s_neg == 0b110
    over = np.radians([0.0, -150.0, 150.0, 0.0, 30.0, 0.0])  # reaching over the shoulder
    F = robot.joint_frames(over)
    wrist_x_in_a1 = (np.linalg.inv(F[0]) @ np.append(F[4, :3, 3], 1.0))[0]
    assert (kuka_status_turn(robot, over)[0] & 1) == int(wrist_x_in_a1 < 0)


def test_abb_confdata_rule() -> None:
    (ex,) = _rows("ABB", "quadrants")
    cf = abb_confdata(load_robot("kuka_kr600_r2830"), _q(ex))
    assert [str(c) for c in cf[:3]] == ex["expected"].split()
    robot = load_robot("kuka_kr600_r2830")
    q = np.radians([0.0, -90.0, 90.0, 0.0, -30.0, 0.0])
    p = posture(robot, q)
    assert cf_x(robot, q) == 4 * (not p.front) + 2 * (not p.elbow_up) + 1


def cf_x(robot: object, q: np.ndarray) -> int:
    return int(abb_confdata(robot, q)[3])  # type: ignore[arg-type]


def test_flip_letter_is_the_sign_of_j5_on_every_fanuc_row() -> None:
    """Summary: of the table's rows with J5 != 0, all but the one that contradicts its own flip
    twin say F exactly when J5 > 0."""
    with FACTS.open(encoding="utf-8") as fh:
        rows = [r for r in csv.DictReader(fh) if r["vendor"] == "FANUC" and r["j5_deg"]
                and float(r["j5_deg"]) != 0.0]
    wrong = [r["case"] for r in rows if (r["expected"][0] == "F") != (float(r["j5_deg"]) > 0)]
    assert [w.split()[0] for w in wrong] == ["14.5"]
    assert len(rows) == 69


# --------------------------------------------------------------------------------------------
# Many joint vectors at once (issue 41): the same flags and encodings as one at a time


@pytest.mark.parametrize("name", ["kuka_kr600_r2830", "fanuc_s900ib_400", "zk500"])
def test_batch_postures_equal_one_at_a_time(name: str) -> None:
    """The writers and the round trip encode many points with one pass of the batch forward
    kinematics; across the whole joint range (every front/back, elbow and wrist side, joints
    on both sides of a turn) each flag and each vendor encoding equals the single-point one,
    whose frames come from Pinocchio's own forward kinematics."""
    from rfsw_plan.export.config import (
        abb_confdatas,
        fanuc_configs,
        kuka_status_turns,
        postures,
    )

    robot = load_robot(name)
    d = robot.description
    rng = np.random.default_rng(7)
    Q = rng.uniform(np.maximum(d.lower, -2 * np.pi), np.minimum(d.upper, 2 * np.pi),
                    size=(400, 6))
    one = [posture(robot, q) for q in Q]
    assert postures(robot, Q) == one
    assert len({(p.front, p.elbow_up, p.wrist_negative) for p in one}) >= 6  # both sides
    assert kuka_status_turns(robot, Q) == [kuka_status_turn(robot, q) for q in Q]
    assert fanuc_configs(robot, Q) == [fanuc_config(robot, q) for q in Q]
    assert abb_confdatas(robot, Q) == [abb_confdata(robot, q) for q in Q]
    assert postures(robot, Q[:0]) == []


def test_seeded_on_branch_is_what_the_search_returns_first() -> None:
    """The round trip's batch step returns, where the seeded solution has the stated posture,
    the joint values :func:`ik_on_branch` returns (bit for bit: the same solve), and None
    where it has not (a point stating another posture: the search goes on from there)."""
    from rfsw_plan.export.config import ik_on_branch, kuka_status_turns, seeded_on_branch

    robot = load_robot("kuka_kr600_r2830")
    rng = np.random.default_rng(3)
    base = np.radians([10.0, -80.0, 100.0, 20.0, 40.0, -30.0])
    Q = base + rng.normal(0.0, 0.05, size=(12, 6))
    targets = np.array([robot.fk(q + 1e-6) for q in Q])  # the written points: off by rounding
    stated = [kuka_status_turn(robot, q) for q in Q]
    s, t = stated[5]
    stated[5] = (s ^ 4, t)  # the other wrist: the seeded solution does not have it
    got = seeded_on_branch(robot, targets, stated, kuka_status_turns, Q)
    for k, q in enumerate(got):
        if k == 5:
            assert q is None
            continue
        assert q is not None
        want = ik_on_branch(robot, targets[k],
                            lambda x, k=k: kuka_status_turn(robot, x) == stated[k], Q[k])
        assert np.array_equal(q, want)
        assert np.allclose(robot.fk(q), targets[k], atol=1e-9)
