"""The mission of issue 5 (§6): hidden effects are found, added, and the error falls to noise.

Every campaign is simulated with :func:`run_campaign` (zk500, tool down in front of the robot,
per pose: zero load, +W, -W, zero load again, so repeats give the noise floor) and validated
with 3-fold cross-validation. The noise floor is the one ``validate`` estimates from the
repeated samples, never the truth.
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.elastostatics.effects import EFFECTS
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.io.measurements import MeasurementSet, write_measurements
from rfsw_plan.robot.kinematics import load_robot
from rfsw_plan.validation.campaign.simulation import THERMAL_DRIFT, CampaignResult, run_campaign
from rfsw_plan.validation.workbench import ValidationResult, validate

ROBOT = "zk500"
POSES = 40
LOADS = 4
NOISE_MM = 0.01
FOLDS = 3

# Per-joint effects on the joints where zk500 position data can see *and* tell them apart:
# joint 6's axis passes through the TCP (its torque-driven effects are invisible), and the
# tilting of joints 4 and 5 about the wrist centre is the same motion once the joint
# compliances are re-identified (test_diagnosis checks that they are reported as a tie).
# complementary_stiffness is physically tiny at 1-5 kN (~7 um), so its campaign uses a
# low-noise measurement to make it visible.
CASES: list[tuple[str, float]] = [
    ("complementary_stiffness", 0.002),
    ("tilting_compliance:j1", NOISE_MM),
    ("tilting_compliance:j2", NOISE_MM),
    ("tilting_compliance:j3", NOISE_MM),
    ("tilting_compliance:j6", NOISE_MM),
    ("torque_dependent_stiffness:j1", NOISE_MM),
    ("torque_dependent_stiffness:j2", NOISE_MM),
    ("torque_dependent_stiffness:j3", NOISE_MM),
    ("torque_dependent_stiffness:j4", NOISE_MM),
    ("torque_dependent_stiffness:j5", NOISE_MM),
    ("joint_backlash:j1", NOISE_MM),
    ("joint_backlash:j2", NOISE_MM),
    ("joint_backlash:j3", NOISE_MM),
    ("joint_backlash:j4", NOISE_MM),
    ("joint_backlash:j5", NOISE_MM),
    ("lost_motion:j1", NOISE_MM),  # joint 1's axis is vertical: unloaded, the approach decides
    ("load_hysteresis:j2", NOISE_MM),
    ("link_errors", NOISE_MM),
    ("payload_gravity", NOISE_MM),
    ("sensor_misalignment", NOISE_MM),
    ("force_sensor_bias", NOISE_MM),
    ("kinematic_offsets", NOISE_MM),
    ("flange_compliance", NOISE_MM),
]


def _campaign(hidden: list[str], noise_mm: float = NOISE_MM, seed: int = 1) -> CampaignResult:
    return run_campaign(ROBOT, hidden, poses=POSES, loads_per_pose=LOADS, noise_mm=noise_mm,
                        seed=seed)


def test_cases_cover_every_library_effect() -> None:
    covered = {label.split(":")[0] for label, _ in CASES}
    assert covered == {n for n, c in EFFECTS.items() if not c.setup} - {"joint_compliance"}


@pytest.mark.parametrize(("hidden", "noise_mm"), CASES, ids=[c[0] for c in CASES])
def test_hidden_effect_is_ranked_first_and_adding_it_reaches_the_noise_floor(
    model: ElastostaticModel, hidden: str, noise_mm: float
) -> None:
    camp = _campaign([hidden], noise_mm)
    res = validate(model, camp.data, folds=FOLDS)
    dg = res.diagnosis
    assert dg.noise.source == "repeats"
    assert dg.verdict == "missing", dg.message
    best = dg.candidates[0]
    assert best.label == hidden, dg.message
    assert best.significant
    # The data may not tell the hidden effect from a more general one (link_errors contains
    # kinematic offsets): such a tie is allowed, but the named one is the simplest of them.
    ties = [c for c in dg.candidates if c.tied_with_best]
    assert all(c.n_params > best.n_params for c in ties), [(c.label, c.n_params) for c in ties]
    name, _, joint = hidden.partition(":j")
    assert (best.effect, best.joint) == (name, int(joint) if joint else None)

    after = validate(model, camp.data, add=[hidden], folds=FOLDS)
    assert after.add is not None
    assert after.add.added == (hidden,)
    floor = after.diagnosis.noise.sigma
    assert floor is not None
    assert after.add.after.heldout_rms <= 1.5 * floor
    assert after.add.after.heldout_rms < after.add.before.heldout_rms
    assert after.verdict == "adequate", after.diagnosis.message
    assert hidden not in [c.label for c in after.diagnosis.candidates]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_nothing_hidden_is_adequate(model: ElastostaticModel, seed: int) -> None:
    res = validate(model, _campaign([], seed=seed).data, folds=FOLDS)
    assert res.verdict == "adequate", res.diagnosis.message
    assert res.diagnosis.missing is None


@pytest.mark.parametrize("seed", [1, 2])
def test_drift_with_time_is_never_explained_away_and_points_at_time(
    model: ElastostaticModel, seed: int
) -> None:
    """A drift with time is physics outside the library. Since issue 34 a library effect that
    explains most of the held-out residual is named ("never unexplained while a library effect
    is significant and explains most of it": here a geometric effect takes up the drift's
    pose-dependent part), but never as the whole story: the selection does not reach the
    noise floor, and the message points at time for the rest."""
    camp = _campaign([THERMAL_DRIFT], seed=seed)
    res = validate(model, camp.data, folds=FOLDS)
    dg = res.diagnosis
    assert dg.verdict in ("unexplained", "missing"), dg.message
    assert res.verdict != "adequate" and not dg.chain_at_noise, dg.message
    if dg.verdict == "missing":
        assert dg.missing is not None
        assert "the rest is above the noise floor" in dg.message, dg.message
        assert "correlates most with time" in dg.message, dg.message
    assert dg.correlations[0].feature == "time"
    assert dg.correlations[0].significant
    assert "time" in dg.message


def _round_trip(
    model: ElastostaticModel, data: MeasurementSet, rounds: int
) -> list[ValidationResult]:
    """validate -> add the named effect -> validate ..., at most ``rounds`` additions."""
    results = [validate(model, data, folds=FOLDS)]
    added: list[str] = []
    while results[-1].verdict == "missing" and len(added) < rounds:
        miss = results[-1].diagnosis.missing
        assert miss is not None
        added.append(miss.label)
        results.append(validate(model, data, add=added, folds=FOLDS))
    return results


@pytest.mark.parametrize(
    "hidden",
    [
        ["payload_gravity", "tilting_compliance:j2"],
        ["joint_backlash:j3", "force_sensor_bias"],
    ],
    ids=["payload+tilting_j2", "backlash_j3+sensor_bias"],
)
def test_two_hidden_effects_are_found_within_two_rounds(
    model: ElastostaticModel, hidden: list[str]
) -> None:
    camp = _campaign(hidden, seed=3)
    results = _round_trip(model, camp.data, rounds=2)
    found = [r.diagnosis.missing.label for r in results if r.diagnosis.missing is not None]
    assert sorted(found) == sorted(hidden)
    assert len(results) <= 3
    final = results[-1]
    assert final.verdict == "adequate", final.diagnosis.message
    assert final.add is not None and final.diagnosis.noise.sigma is not None
    assert final.add.after.heldout_rms <= 1.5 * final.diagnosis.noise.sigma


def test_cli_loop_converges_to_adequate_through_saved_robot_files(tmp_path: Path) -> None:
    """validate -> --add --save-robot -> validate --robot NEW ... until adequate (CLI)."""
    camp = _campaign(["payload_gravity", "joint_backlash:j2"], seed=5)
    csv = write_measurements(tmp_path / "campaign.csv", camp.data)
    robot = ROBOT
    verdicts = []
    for k in range(4):
        out = tmp_path / f"round{k}"
        args = ["validate", "--robot", robot, "--data", str(csv), "--folds", str(FOLDS),
                "-o", str(out), "--json", "--no-report"]
        result = _cli_json(args)
        verdicts.append(result["verdict"])
        if result["verdict"] != "missing":
            break
        label = result["missing"]["label"]
        new_robot = tmp_path / f"robot{k + 1}.toml"
        _cli_json([*args, "--add", label, "--save-robot", str(new_robot)])
        robot = str(new_robot)
    assert verdicts[-1] == "adequate", verdicts
    assert len(verdicts) <= 3
    final = ElastostaticModel(load_robot(robot))
    assert {"payload_gravity", "joint_backlash:j2"} <= set(final.labels)


def _cli_json(args: list[str]) -> dict[str, Any]:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(args) == 0
    return json.loads(buf.getvalue())


def test_robot_file_effects_are_kept_and_a_hidden_one_is_found_on_kuka() -> None:
    """The KUKA file already holds tilting compliance of every joint: never suggested again."""
    kuka = ElastostaticModel(load_robot("kuka_kr600_r2830"))
    assert any(lab.startswith("tilting_compliance") for lab in kuka.labels)
    camp = run_campaign(kuka, ["joint_backlash:j3"], poses=POSES, loads_per_pose=LOADS,
                        noise_mm=NOISE_MM, seed=1)
    res = validate(kuka, camp.data, folds=FOLDS)
    dg = res.diagnosis
    assert dg.verdict == "missing" and dg.candidates[0].label == "joint_backlash:j3", dg.message
    assert not {c.label for c in dg.candidates} & set(kuka.labels)
    after = validate(kuka, camp.data, add=["joint_backlash:j3"], folds=FOLDS)
    assert after.verdict == "adequate", after.diagnosis.message


#: Seeds of the robustness matrix; each effect has one of them in the default run (the seeds
#: taken in turn down :data:`CASES`), the other three under ``-m slow``.
MORE_SEEDS = (2, 3, 4, 5)


@pytest.mark.parametrize(("hidden", "noise_mm", "seed"), [
    pytest.param(hidden, noise_mm, seed, id=f"{hidden}-{seed}",
                 marks=() if seed == MORE_SEEDS[i % len(MORE_SEEDS)] else pytest.mark.slow)
    for i, (hidden, noise_mm) in enumerate(CASES) for seed in MORE_SEEDS])
def test_hidden_effect_matrix_over_more_seeds(
    model: ElastostaticModel, hidden: str, noise_mm: float, seed: int
) -> None:
    """Robustness of the default-run matrix: other poses, loads, parameters and noise."""
    camp = _campaign([hidden], noise_mm, seed=seed)
    dg = validate(model, camp.data, folds=FOLDS).diagnosis
    assert dg.verdict == "missing" and dg.candidates[0].label == hidden, dg.message
    after = validate(model, camp.data, add=[hidden], folds=FOLDS)
    assert after.add is not None and after.diagnosis.noise.sigma is not None
    assert after.add.after.heldout_rms <= 1.5 * after.diagnosis.noise.sigma
    assert after.verdict == "adequate", after.diagnosis.message
