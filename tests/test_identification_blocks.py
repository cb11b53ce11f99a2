"""Identification in blocks (issue 40): a model nonlinear in its parameters is solved by
Gauss-Newton on its linearisation, with one pass over the samples per step; it reaches what the
stacked Gauss-Newton of ``identify`` reaches, and the candidates of a diagnosis round give the
same scores in one process or two."""

from __future__ import annotations

import numpy as np
import pytest

import rfsw_plan.elastostatics.identification_blocks as blocks
from rfsw_plan.elastostatics.identification import identify
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.robot.kinematics import load_robot
from rfsw_plan.validation.campaign.simulation import run_campaign
from rfsw_plan.validation.engine import diagnosis
from rfsw_plan.validation.engine.candidates import candidate_labels
from rfsw_plan.validation.engine.crossval import cross_validate, make_folds


@pytest.fixture(scope="module")
def payload_campaign() -> tuple[ElastostaticModel, object]:
    """zk500 under loads with a hidden spindle weight (bilinear: mass times compliance)."""
    robot = load_robot("zk500")
    camp = run_campaign(robot, ["payload_gravity"], poses=30, loads_per_pose=4, noise_mm=0.01,
                        seed=3)
    return ElastostaticModel(robot).with_effect("payload_gravity"), camp.data


def _passes(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    count = {"n": 0}
    orig = blocks.fold_factors

    def counted(*a: object, **k: object) -> object:
        count["n"] += 1
        return orig(*a, **k)  # type: ignore[arg-type]

    monkeypatch.setattr(blocks, "fold_factors", counted)
    return count


def test_nonlinear_fit_in_blocks_is_identify_in_few_passes(
        payload_campaign: tuple[ElastostaticModel, object],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The fit in blocks of payload gravity with the joint compliances free reaches the
    stacked Gauss-Newton's residual and parameters (an independent solver: every row stacked,
    a pass per iteration), with a few passes over the samples, and started from its own
    solution it stays there."""
    model, data = payload_campaign
    ref = identify(model, data, tol=1e-10)  # type: ignore[arg-type]
    count = _passes(monkeypatch)
    batch = model.batch_of(data)  # type: ignore[arg-type]
    fit = blocks.identify_blocks(model, data, batch,  # type: ignore[arg-type]
                                 np.zeros(len(data), dtype=np.int_)).result  # type: ignore[arg-type]
    assert fit.converged and count["n"] <= 5  # the iteration of every re-solve took 7
    assert fit.rms_after == pytest.approx(ref.rms_after, rel=1e-6)
    got = {(e.effect, e.name): e for e in fit.estimates}
    for e in ref.estimates:
        if e.identified:
            assert got[(e.effect, e.name)].identified
            assert got[(e.effect, e.name)].value == pytest.approx(
                e.value, rel=1e-3, abs=3 * e.std_error), (e.effect, e.name)
    theta = np.array([e.value for e in fit.estimates])
    again = blocks.identify_blocks(model, data, batch,  # type: ignore[arg-type]
                                   np.zeros(len(data), dtype=np.int_),  # type: ignore[arg-type]
                                   max_iter=2, start=theta).result
    assert again.rms_after == pytest.approx(fit.rms_after, rel=1e-6)


def test_a_round_of_candidates_is_the_same_in_two_processes(
        payload_campaign: tuple[ElastostaticModel, object],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The candidates dealt out to a forked process score exactly as in one process, and their
    held-out residual is available after the way back."""
    model, data = payload_campaign
    base_model = ElastostaticModel(model.robot)
    batch = base_model.batch_of(data)  # type: ignore[arg-type]
    folds = make_folds(data, 5, 0)  # type: ignore[arg-type]
    base = cross_validate(base_model, data, folds, batch)  # type: ignore[arg-type]
    labels = candidate_labels(base_model)[:8]
    monkeypatch.setattr(diagnosis, "PARALLEL_MIN_OBS", 0)
    runs = []
    for n in (1, 2):
        monkeypatch.setattr(diagnosis, "CANDIDATE_PROCESSES", n)
        scored, skipped = diagnosis.evaluate_candidates(base_model, data, folds, base,  # type: ignore[arg-type]
                                                        labels, batch)
        runs.append((scored, skipped))
    (one, skip1), (two, skip2) = runs
    assert [s.label for s in skip1] == [s.label for s in skip2]
    assert [c.label for c, _ in one] == [c.label for c, _ in two] and one
    for (c1, cv1), (c2, cv2) in zip(one, two, strict=True):
        assert c1.sse == c2.sse and c1.params == c2.params
        assert np.array_equal(cv1.heldout_residual, cv2.heldout_residual, equal_nan=True)
