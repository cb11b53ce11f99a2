"""Property test of the diagnosis (issue 34): random campaigns on the three bundled
industrial robots, random poses, one or two random hidden effects of random plausible size
(backlash, lost motion and load hysteresis among them). A campaign counts as *named right*
when the forward selection names exactly the hidden effects (or an effect it declares the
data cannot tell from a hidden one: the tilting of joints 4 and 5 of a spherical wrist, or
lost motion whose side the load torque sets in every sample, which the diagnosis reports as
joint_backlash's model) and brings the held-out RMS to <= 1.5 x the noise floor. The share is
printed and must be >= 90 %: a small seeded sample in the default run, the full one under
``-m slow``."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.robot.kinematics import load_robot
from rfsw_plan.validation.campaign.simulation import run_campaign
from rfsw_plan.validation.workbench import validate

ROBOTS = ("zk500_seed001", "kuka_kr600_r2830", "fanuc_s900ib_400")
#: Hidden effects drawn from ({} is a joint 1..5; joint 6 lies on the tool axis).
POOL = ("payload_gravity", "kinematic_offsets", "force_sensor_bias", "sensor_misalignment",
        "joint_backlash:j{}", "lost_motion:j{}", "load_hysteresis:j{}",
        "torque_dependent_stiffness:j{}", "tilting_compliance:j{}")
NOISE_MM = 0.01
FLOOR_RATIO = 1.5
SHARE = 0.9


def _case(seed: int) -> tuple[str, list[str], int, int]:
    """(robot, hidden effects, poses, campaign seed) of case ``seed``."""
    rng = np.random.default_rng(seed)
    robot = ROBOTS[int(rng.integers(len(ROBOTS)))]
    model = ElastostaticModel(load_robot(robot))
    k = 1 + int(rng.integers(2))
    hidden: list[str] = []
    while len(hidden) < k:
        e = POOL[int(rng.integers(len(POOL)))]
        if "{}" in e:
            e = e.format(int(rng.integers(1, 6)))
        kinds = {h.split(":")[0] for h in hidden}
        if not model.has(e) and e.split(":")[0] not in kinds:
            hidden.append(e)
    return robot, hidden, int(rng.integers(25, 45)), int(rng.integers(1_000_000))


def _named_right(seed: int) -> tuple[bool, str]:
    robot, hidden, poses, cseed = _case(seed)
    camp = run_campaign(robot, hidden, poses=poses, loads_per_pose=8, noise_mm=NOISE_MM,
                        seed=cseed)
    dg = validate(ElastostaticModel(load_robot(robot)), camp.data).diagnosis
    named = list(dg.named)
    alias = {t: s.label for s in dg.chain for t in s.ties}
    # An effect the diagnosis says is another named one's model on this data (lost motion whose
    # side the load torque sets in every sample is joint_backlash's torque-only model).
    alias |= {s.label: n for s in dg.skipped for n in named if n in s.reason}
    last = dg.chain[-1].rms_after if dg.chain else dg.heldout_rms
    assert dg.noise.sigma is not None
    ratio = last / dg.noise.sigma
    right = (len(named) == len(hidden) and all(h in named or alias.get(h) in named
                                               for h in hidden) and ratio <= FLOOR_RATIO)
    line = (f"{robot:17s} {' + '.join(hidden):48s} -> {' + '.join(named) or dg.verdict:48s} "
            f"{ratio:5.2f} x floor {'ok' if right else 'WRONG'}")
    return right, line


def _share(seeds: range) -> None:
    results = [_named_right(s) for s in seeds]
    for _, line in results:
        print(line)
    share = sum(r for r, _ in results) / len(results)
    print(f"named right and <= {FLOOR_RATIO} x the floor: {sum(r for r, _ in results)} of "
          f"{len(results)} ({100 * share:.1f} %)")
    assert share >= SHARE, [line for r, line in results if not r]


def test_a_small_seeded_sample_is_named_right() -> None:
    _share(range(1000, 1010))


@pytest.mark.slow
def test_the_full_seeded_sample_is_named_right() -> None:
    _share(range(1000, 1150))
