"""Diagnosis: folds, held-out scores against per-fold identification, tests, verdicts."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.elastostatics.identification import identify
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import IdentificationError, InputError
from rfsw_plan.io.measurements import MeasurementSet
from rfsw_plan.validation.campaign.simulation import run_campaign
from rfsw_plan.validation.engine.diagnosis import (
    FIT_TOL,
    candidate_labels,
    cross_validate,
    diagnose,
    make_folds,
)
from rfsw_plan.validation.engine.residuals import NoiseFloor


def _data(hidden: list[str], poses: int = 30, loads: int = 4, noise_mm: float = 0.01,
          seed: int = 1) -> MeasurementSet:
    return run_campaign("zk500", hidden, poses=poses, loads_per_pose=loads, noise_mm=noise_mm,
                        seed=seed).data


def _per_fold_identify(model: ElastostaticModel, data: MeasurementSet,
                       folds: np.ndarray) -> np.ndarray:
    """Reference: identify() on the training folds, predict the held-out fold."""
    out = np.full(data.position.shape, np.nan)
    for f in range(int(folds.max()) + 1):
        fit = identify(model, data.subset(folds != f))
        te = folds == f
        out[te] = data.position[te] - fit.model.predict_position(data.q[te], data.wrench[te])
    return np.where(data.measured, out, np.nan)


def test_folds_are_grouped_by_pose_and_balanced() -> None:
    d = _data([], poses=17)
    folds = make_folds(d, 5, seed=3)
    assert folds.shape == (len(d),)
    assert d.pose_id is not None
    for pid in np.unique(d.pose_id):
        assert np.unique(folds[d.pose_id == pid]).size == 1
    counts = np.bincount(folds) // 4
    assert counts.sum() == 17 and counts.max() - counts.min() <= 1
    assert np.array_equal(folds, make_folds(d, 5, seed=3))
    assert not np.array_equal(folds, make_folds(d, 5, seed=4))


def test_folds_need_enough_poses() -> None:
    d = _data([], poses=3)
    with pytest.raises(IdentificationError, match="need at least 5 poses"):
        make_folds(d, 5)
    with pytest.raises(InputError, match="at least 2 folds"):
        make_folds(d, 1)


def test_heldout_residual_equals_per_fold_identification_for_a_linear_model(
    model: ElastostaticModel,
) -> None:
    d = _data(["tilting_compliance:j3"], poses=24)
    m = model.with_effect("tilting_compliance:j3")
    folds = make_folds(d, 4, seed=0)
    cv = cross_validate(m, d, folds)
    ref = _per_fold_identify(m, d, folds)
    ok = np.isfinite(ref)
    assert np.array_equal(ok, np.isfinite(cv.heldout_residual))
    np.testing.assert_allclose(cv.heldout_residual[ok], ref[ok], rtol=1e-6, atol=1e-10)
    assert cv.heldout_rms == pytest.approx(np.sqrt(np.mean(ref[ok] ** 2)), rel=1e-6)
    assert cv.n_free == 5 + 2  # joint 6 compliance is invisible to position data


def test_heldout_residual_of_a_bilinear_model_is_one_gauss_newton_step_away(
    model: ElastostaticModel,
) -> None:
    d = _data(["payload_gravity"], poses=24)
    m = model.with_effect("payload_gravity")
    folds = make_folds(d, 4, seed=0)
    cv = cross_validate(m, d, folds)
    ref = _per_fold_identify(m, d, folds)
    ok = np.isfinite(ref)
    assert cv.heldout_rms == pytest.approx(np.sqrt(np.mean(ref[ok] ** 2)), rel=0.02)


def test_too_few_samples_says_how_many_are_needed(model: ElastostaticModel) -> None:
    d = _data([], poses=6, loads=1)
    with pytest.raises(IdentificationError, match=r"need at least \d+ samples"):
        cross_validate(model.with_effect("kinematic_offsets"), d, make_folds(d, 5))


def test_candidates_are_the_library_minus_the_model(model: ElastostaticModel) -> None:
    labels = candidate_labels(model)
    assert len(labels) == 7 + 5 * 6  # 7 global (link_errors, flange_compliance), 5 per joint
    assert "joint_compliance" not in labels
    extended = model.with_effect("payload_gravity").with_effect("joint_backlash:j2")
    labels2 = candidate_labels(extended)
    assert set(labels) - set(labels2) == {"payload_gravity", "joint_backlash:j2"}


def test_effect_already_in_the_model_is_never_suggested(model: ElastostaticModel) -> None:
    d = _data(["payload_gravity"])
    extended = model.with_effect("payload_gravity")
    dg = diagnose(extended, d, folds=3)
    assert "payload_gravity" not in [c.label for c in dg.candidates]
    assert dg.verdict == "adequate", dg.message


@pytest.mark.parametrize("noise_mm", [0.01, 0.003])
def test_noise_never_names_an_effect_even_with_a_too_small_noise_floor(
    model: ElastostaticModel, noise_mm: float
) -> None:
    d = _data([], noise_mm=0.01, seed=11)
    dg = diagnose(model, d, NoiseFloor(noise_mm * 1e-3, "given", float("inf")), folds=3)
    assert not any(c.significant for c in dg.candidates)
    assert dg.missing is None
    # With the right floor the model is adequate; with a floor 3x too small it is above the
    # floor, but no effect explains held-out noise, so nothing is named.
    assert dg.verdict == ("adequate" if noise_mm == 0.01 else "unexplained"), dg.message


def test_effects_the_data_cannot_identify_are_reported_not_fitted(
    model: ElastostaticModel,
) -> None:
    d = _data([], poses=30)
    batch = model.batch(d.q)
    tau1 = np.einsum("ma,ma->m", batch.J[:, :, 0], d.wrench)
    one_sign = d.subset(tau1 >= 0)  # joint 1 torque never negative
    dg = diagnose(model, one_sign, folds=3)
    skipped = {s.label: s.reason for s in dg.skipped}
    assert "joint_backlash:j1" in skipped
    assert "does not change sign" in skipped["joint_backlash:j1"]
    # Joint 6's axis passes through the TCP: its torque-driven effects are invisible.
    assert "torque_dependent_stiffness:j6" in skipped
    assert "does not move the measured TCP" in skipped["torque_dependent_stiffness:j6"]
    assert not set(skipped) & {c.label for c in dg.candidates}


def test_indistinguishable_candidates_are_reported_as_a_tie(model: ElastostaticModel) -> None:
    # Tilting of joints 4 and 5 about the wrist centre: the same motion once the joint
    # compliances are free, so the data cannot say which joint it is.
    d = _data(["tilting_compliance:j4"], poses=40)
    dg = diagnose(model, d, folds=3)
    assert dg.verdict == "missing"
    top = {dg.candidates[0].label} | {c.label for c in dg.candidates if c.tied_with_best}
    assert {"tilting_compliance:j4", "tilting_compliance:j5"} <= top
    assert "cannot tell" in dg.message


def test_without_a_noise_floor_the_feature_tests_decide(model: ElastostaticModel) -> None:
    # Two samples per pose (zero load, one load): no repeats, no given noise.
    hidden = _data(["joint_backlash:j3"], poses=60, loads=2, seed=2)
    dg = diagnose(model, hidden, folds=3)
    assert dg.noise.sigma is None and dg.above_noise is None
    assert dg.verdict == "missing" and dg.candidates[0].label == "joint_backlash:j3"
    clean = _data([], poses=60, loads=2, seed=2)
    dg0 = diagnose(model, clean, folds=3)
    # Issue 12: never "adequate" on significance alone; say what the next campaign needs.
    assert dg0.verdict == "undetermined", dg0.message
    assert "floor is unknown" in dg0.message and "repeats" in dg0.message


def test_diagnosis_json_has_the_contract_fields(model: ElastostaticModel) -> None:
    dg = diagnose(model, _data(["force_sensor_bias"]), folds=3)
    js = dg.to_json()
    assert js["verdict"] == "missing"
    assert js["missing"]["effect"] == "force_sensor_bias" and js["missing"]["joint"] is None
    rms = [c["rms_after_mm"] for c in js["candidates"]]
    assert rms == sorted(rms)
    for c in js["candidates"]:
        assert set(c) >= {"effect", "joint", "rms_after_mm", "explained_fraction"}
        assert c["joint"] is None or 1 <= c["joint"] <= 6


@pytest.mark.parametrize("labels", [[], ["payload_gravity", "joint_backlash:j3"],
                                    ["tilting_compliance:j2"]])
def test_fit_in_blocks_is_the_fit_on_the_stacked_regressor(
    model: ElastostaticModel, labels: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """cross_validate visits the samples in blocks (bounded memory on 10^6 samples): with
    blocks of 37 samples (4 blocks here) it gives the stacked regressor's fit and score."""
    import rfsw_plan.elastostatics.identification_blocks as ib
    from rfsw_plan.validation.engine.crossval import _cross_validate_stacked

    monkeypatch.setattr(ib, "BLOCK_SAMPLES", 37)
    d = _data(["payload_gravity", "joint_backlash:j3"], poses=30)
    m = model
    for label in labels:
        m = m.with_effect(label)
    folds = make_folds(d, 5)
    batch = m.batch(d.q)
    obs = np.broadcast_to(folds[:, None], d.measured.shape)[d.measured]
    blocked = cross_validate(m, d, folds, batch)
    assert len(ib.blocks(batch)) == 4
    stacked = _cross_validate_stacked(m, d, folds, batch,
                                      min(int(np.sum(obs != f)) for f in range(5)))
    assert blocked.sse == pytest.approx(stacked.sse, rel=1e-10)
    assert blocked.n_free == stacked.n_free and blocked.n_obs == stacked.n_obs
    np.testing.assert_allclose(blocked.heldout_residual, stacked.heldout_residual, rtol=0,
                               atol=1e-12)
    for a, b in zip(blocked.fit.estimates, stacked.fit.estimates, strict=True):
        assert (a.effect, a.name, a.identified, a.note) == (b.effect, b.name, b.identified,
                                                             b.note)
        # Both stop Gauss-Newton at the relative step FIT_TOL (1e-7) of a bilinear model.
        assert a.value == pytest.approx(b.value, rel=FIT_TOL, abs=1e-15)
        if a.identified:
            assert a.std_error == pytest.approx(b.std_error, rel=1e-6)
    assert blocked.fit.rms_after == pytest.approx(stacked.fit.rms_after, rel=1e-10)
    assert blocked.fit.condition_number == pytest.approx(stacked.fit.condition_number,
                                                          rel=1e-6)


def test_block_caches_stay_within_the_budget_and_do_not_change_the_fit(
    model: ElastostaticModel, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Effect caches kept in the blocks (the complementary-stiffness pose basis, 1.7 KB per
    sample) are bounded by CACHE_BUDGET_BYTES: beyond it they are recomputed, same fit."""
    import rfsw_plan.elastostatics.identification_blocks as ib

    monkeypatch.setattr(ib, "BLOCK_SAMPLES", 37)
    d = _data(["payload_gravity"], poses=30)
    m = model.with_effect("payload_gravity").with_effect("complementary_stiffness")
    folds = make_folds(d, 5)
    seen: list[int] = []
    real = ib._bound_cache

    def spy(b, used):  # type: ignore[no-untyped-def]
        kept = real(b, used)
        seen.append(kept)
        return kept

    monkeypatch.setattr(ib, "_bound_cache", spy)
    cached = cross_validate(m, d, folds, m.batch(d.q))
    assert max(seen) > 0  # the basis was kept
    monkeypatch.setattr(ib, "CACHE_BUDGET_BYTES", 1000)
    seen.clear()
    bounded = cross_validate(m, d, folds, m.batch(d.q))
    assert max(seen) <= 1000
    assert bounded.sse == cached.sse
    assert [e.value for e in bounded.fit.estimates] == [e.value for e in cached.fit.estimates]
