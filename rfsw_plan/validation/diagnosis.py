"""Which physical effect is missing from a model, on a load campaign (``rfsw-plan validate``).

For every candidate (:func:`~rfsw_plan.validation.candidates.candidate_labels`: each library
effect the model lacks, at every joint where it applies) the effect is added, all parameters
are re-identified, and the model is scored on data the fit did not see (k folds, grouped by
pose so that repeats of one pose never sit on both sides;
:func:`~rfsw_plan.validation.crossval.cross_validate`). The held-out F test, the ranking, the
ties and the named candidate are the workbench's one scoring
(:mod:`rfsw_plan.validation.scoring`), shared with ``validate-weld``.

The residual is *at the noise floor* when SSE_0 / sigma^2 is not above chi^2(n) (sigma given)
or F(n, dof) (sigma from repeats) at level ALPHA, or RMS_0 <= NOISE_TOLERANCE sigma.

Verdict: ``adequate`` when the current model's held-out residual is at the noise floor;
``missing`` when the named candidate (and, greedily, at most MAX_CHAIN - 1 more, each round
re-testing every remaining candidate on the extended model) brings the held-out residual to the
noise floor; ``unexplained`` otherwise, with the features the residual correlates with (time,
pose, torques, extra columns) to point at the physics the library lacks. Without a noise floor
(no repeats, no --noise-mm) "at the noise floor" is replaced by "no feature test is
significant", and a model without a missing effect is ``undetermined``, never adequate.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.effects import make_effect
from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import IdentificationError
from rfsw_plan.progress import progress
from rfsw_plan.validation.candidates import candidate_form, candidate_labels
from rfsw_plan.validation.crossval import (
    DEFAULT_FOLDS,
    FIT_TOL,
    CrossValidation,
    cross_validate,
    make_folds,
    single_thread_numpy_blas,
)
from rfsw_plan.validation.residuals import (
    FeatureCorrelation,
    NoiseFloor,
    correlation_json,
    correlations,
    estimate_noise_floor,
    noise_json,
    residual_features,
)
from rfsw_plan.validation.scoring import (
    ALPHA,
    TIE_LEVEL,
    Candidate,
    named,
    rank,
    score,
    ties_of,
)

log = logging.getLogger(__name__)

#: A residual within this factor of the noise floor counts as "at the noise floor".
NOISE_TOLERANCE = 1.1
#: At most this many effects are chained greedily to reach the noise floor.
MAX_CHAIN = 3

Verdict = Literal["adequate", "missing", "unexplained", "undetermined"]

#: What a campaign without a noise floor should add next time.
NO_FLOOR = (
    "no repeats and no --noise-mm: the floor is unknown; for the next campaign, measure some "
    "poses twice in a row at the same load (repeats) or give the measuring device's noise "
    "with --noise-mm"
)


# --------------------------------------------------------------------------------------------
# Candidates


@dataclass(frozen=True)
class Skipped:
    """A candidate that was not fitted.

    Attributes:
        label: Effect label.
        reason: Why (the data cannot identify it, too few samples...).
    """

    label: str
    reason: str


def _fitted(model: ElastostaticModel, data: MeasurementSet, folds: NDArray[np.int_],
            label: str, batch: PoseBatch, F_true: FloatArray
            ) -> tuple[CrossValidation | None, str]:
    """Cross-validation of ``model`` with ``label`` added, or None and why it was not fitted."""
    reason = make_effect(model.robot, label).identifiable(batch, F_true)
    if reason:
        return None, f"not identifiable from this data: {reason}"
    try:
        cv = cross_validate(model.with_effect(label), data, folds, batch)
    except IdentificationError as exc:
        return None, str(exc)
    est = [e for e in cv.fit.estimates if e.effect == label]
    if not any(e.identified for e in est):
        why = next((e.note for e in est if e.note), "no parameter identified")
        return None, f"not identifiable from this data: {why}"
    return cv, ""


def _score(model: ElastostaticModel, label: str, before: CrossValidation,
           after: CrossValidation, n_tests: int) -> Candidate:
    """The scored candidate; its admissibility from the effect's ``param_ranges``."""
    form = candidate_form(model, label)
    est = [e for e in after.fit.estimates if e.effect == label]
    theta = np.array([e.value for e in est], dtype=float)
    return score(
        label, form.effect, form.joint, sse_before=before.sse, sse_after=after.sse,
        n_obs=after.n_obs, n_free=after.n_free, n_params=sum(e.identified for e in est),
        n_tests=n_tests, admissible=form.admissible(theta),
        params={e.name: e.value for e in est}, prior=form.split(form.theta0),
        notes=tuple(f"{e.name}: {e.note}" for e in est if e.note),
        std={e.name: e.std_error for e in est if e.identified},
        implausible=form.implausible(theta))


def evaluate_candidates(
    model: ElastostaticModel,
    data: MeasurementSet,
    folds: NDArray[np.int_],
    base: CrossValidation,
    labels: Sequence[str],
    batch: PoseBatch,
    noise: NoiseFloor | None = None,
) -> tuple[list[tuple[Candidate, CrossValidation]], list[Skipped]]:
    """Add each effect in ``labels`` to ``model``, cross-validate, and score against ``base``.

    Effects whose :meth:`~rfsw_plan.elastostatics.effects.base.Effect.identifiable` gives a
    reason, that no data can fit, or none of whose parameters the data identifies are returned
    as :class:`Skipped` with the reason. The scored candidates come ranked
    (:func:`~rfsw_plan.validation.scoring.rank`, ties against the noise floor ``noise``).
    """
    F_true = model.true_wrench(batch, data.wrench)
    done: list[tuple[str, CrossValidation]] = []
    skipped: list[Skipped] = []
    for label in progress(labels, desc="diagnosis: candidates", total=len(labels),
                          unit="candidate"):
        cv, why = _fitted(model, data, folds, label, batch, F_true)
        if cv is None:
            skipped.append(Skipped(label, why))
        else:
            done.append((label, cv))
    n_tests = max(len(done), 1)
    cvs = {label: cv for label, cv in done}
    scored = [_score(model, label, base, cv, n_tests) for label, cv in done]

    def at_floor(c: Candidate) -> bool:
        return noise is not None and noise.sigma is not None and _at_floor(cvs[c.label], noise)

    ranked = rank(scored, at_floor if noise is not None and noise.sigma is not None else None)
    return [(c, cvs[c.label]) for c in ranked], skipped

# --------------------------------------------------------------------------------------------
# Diagnosis


@dataclass(frozen=True)
class ChainStep:
    """One step of the greedy search for the effects that reach the noise floor.

    Attributes:
        label: Effect added in this step.
        rms_before: Held-out RMS before the step [m].
        rms_after: Held-out RMS after it [m].
        p_value: p-value of the improvement.
    """

    label: str
    rms_before: float
    rms_after: float
    p_value: float


@dataclass(frozen=True)
class Diagnosis:
    """Outcome of :func:`diagnose`.

    Attributes:
        verdict: ``adequate``, ``missing`` or ``unexplained``.
        message: One-sentence summary for the user.
        labels: Effects of the diagnosed model.
        heldout_rms: Held-out RMS of the current model (re-identified per fold) [m].
        heldout_residual: Its held-out residual [m], shape (m, 3).
        noise: Noise floor used.
        p_above_noise: p-value of "the held-out residual is at the noise floor" (NaN if the
            noise floor is unknown).
        above_noise: True if the residual is significantly above the noise floor (None if the
            noise floor is unknown).
        candidates: Scored candidates, best (lowest held-out RMS) first.
        skipped: Candidates that were not fitted, with the reason.
        chain: Greedy steps from the current model towards the noise floor (the first names
            the missing effect when the verdict is ``missing``).
        chain_at_noise: True if the last chain step reached the noise floor.
        correlations: Feature tests of the held-out residual of the current model, most
            explanatory first.
        folds: Number of folds.
        seconds: Wall time of the diagnosis [s].
    """

    verdict: Verdict
    message: str
    labels: tuple[str, ...]
    heldout_rms: float
    heldout_residual: FloatArray = field(repr=False)
    noise: NoiseFloor = field(repr=False)
    p_above_noise: float = float("nan")
    above_noise: bool | None = None
    candidates: tuple[Candidate, ...] = ()
    skipped: tuple[Skipped, ...] = ()
    chain: tuple[ChainStep, ...] = ()
    chain_at_noise: bool = False
    correlations: tuple[FeatureCorrelation, ...] = ()
    folds: int = DEFAULT_FOLDS
    seconds: float = 0.0

    @property
    def missing(self) -> Candidate | None:
        """The named missing effect (verdict ``missing``), else None."""
        if self.verdict != "missing" or not self.chain:
            return None
        return next(c for c in self.candidates if c.label == self.chain[0].label)

    def to_json(self) -> dict[str, Any]:
        """JSON form (mm)."""
        miss = self.missing
        return {
            "verdict": self.verdict,
            "message": self.message,
            "model_effects": list(self.labels),
            "heldout_rms_mm": self.heldout_rms * 1e3,
            "noise": noise_json(self.noise),
            "p_above_noise": None if np.isnan(self.p_above_noise) else self.p_above_noise,
            "above_noise": self.above_noise,
            "missing": None if miss is None else {
                "effect": miss.effect,
                "joint": miss.joint,
                "label": miss.label,
                "heldout_rms_before_mm": miss.rms_before * 1e3,
                "heldout_rms_after_mm": miss.rms_after * 1e3,
            },
            "candidates": [c.to_json() for c in self.candidates],
            "not_identifiable": [{"label": s.label, "reason": s.reason} for s in self.skipped],
            "chain": [
                {"label": s.label, "heldout_rms_before_mm": s.rms_before * 1e3,
                 "heldout_rms_after_mm": s.rms_after * 1e3, "p_value": s.p_value}
                for s in self.chain
            ],
            "chain_at_noise": self.chain_at_noise,
            "correlations": [correlation_json(c) for c in self.correlations],
            "folds": self.folds,
            "seconds": self.seconds,
        }


def _at_floor(cv: CrossValidation, noise: NoiseFloor) -> bool:
    """The held-out residual is at the known noise floor (module docstring)."""
    assert noise.sigma is not None
    return not (noise.above(cv.sse, cv.n_obs) < ALPHA
                and cv.heldout_rms > NOISE_TOLERANCE * noise.sigma)


def _at_noise(
    cv: CrossValidation, noise: NoiseFloor, feats: dict[str, Any]
) -> tuple[bool, float]:
    """(residual at the noise floor?, p-value of being above it)."""
    if noise.sigma is not None:
        return _at_floor(cv, noise), noise.above(cv.sse, cv.n_obs)
    corr = correlations(cv.heldout_residual, feats)
    return not any(c.significant for c in corr), float("nan")


def _greedy_chain(
    data: MeasurementSet, fold: NDArray[np.int_], scored: list[tuple[Candidate, CrossValidation]],
    noise: NoiseFloor, feats: dict[str, Any], batch: PoseBatch, at_noise0: bool,
) -> tuple[list[ChainStep], bool]:
    """The greedy search: add the best significant candidate, re-identify from its values and
    test the rest again, until the held-out residual reaches the noise floor (or nothing more is
    significant, or :data:`MAX_CHAIN` steps). Returns the steps and whether the last one is at
    the noise floor."""
    chain: list[ChainStep] = []
    cvs = dict((c.label, cv) for c, cv in scored)
    best = named([c for c, _ in scored])
    if at_noise0 or best is None:
        return chain, at_noise0
    current = cvs[best.label]
    chain.append(ChainStep(best.label, best.rms_before, best.rms_after, best.p_value))
    pool = [c.label for c, _ in scored if c.label != best.label]
    at_noise, _ = _at_noise(current, noise, feats)
    while not at_noise and pool and len(chain) < MAX_CHAIN:
        # Start the next round from the identified values.
        more, _ = evaluate_candidates(current.fit.model, data, fold, current, pool, batch,
                                      noise)
        c = named([c for c, _ in more])
        if c is None:
            break
        current = dict((x.label, cv) for x, cv in more)[c.label]
        chain.append(ChainStep(c.label, c.rms_before, c.rms_after, c.p_value))
        pool.remove(c.label)
        at_noise, _ = _at_noise(current, noise, feats)
    return chain, at_noise


def _verdict(
    base: CrossValidation, noise: NoiseFloor, candidates: tuple[Candidate, ...],
    chain: list[ChainStep], corr: Any, at_noise0: bool, at_noise: bool,
) -> tuple[Verdict, str]:
    """The verdict and its one-line message (see the module docstring)."""
    mm = 1e3
    floor = "unknown" if noise.sigma is None else f"{noise.sigma * mm:.4g} mm"
    if at_noise0 and noise.sigma is None:
        return "undetermined", (
            f"undetermined: held-out RMS {base.heldout_rms * mm:.4g} mm and no tested feature "
            "explains it, but without a noise floor that does not make the model adequate"
        )
    if at_noise0:
        return "adequate", (
            f"adequate: held-out RMS {base.heldout_rms * mm:.4g} mm is at the noise floor "
            f"({floor}); no effect is missing"
        )
    if chain and at_noise:
        first = chain[0]
        rest = ", then ".join(s.label for s in chain[1:])
        chosen = next(c for c in candidates if c.label == first.label)
        ties = ties_of(candidates, chosen)
        return "missing", (
            f"missing: {first.label} (held-out RMS {first.rms_before * mm:.4g} -> "
            f"{first.rms_after * mm:.4g} mm, noise floor {floor})"
            + (f"; this data cannot tell it from {', '.join(ties)}" if ties else "")
            + (f"; then {rest} reaches the noise floor" if rest else "")
        )
    top = [c for c in corr if c.significant][:3]
    points = ", ".join(f"{c.feature} (R^2 {c.r2:.2f})" for c in top) or "no tested feature"
    verb = "explains" if len(chain) == 1 else "explain"
    partial = (
        f"; {' + '.join(s.label for s in chain)} {verb} part of it but not down to the "
        "noise floor" if chain else ""
    )
    return "unexplained", (
        f"unexplained: no library effect brings the held-out RMS "
        f"{base.heldout_rms * mm:.4g} mm to the noise floor ({floor}){partial}; the "
        f"residual correlates most with {points}"
    )


@single_thread_numpy_blas
def diagnose(
    model: ElastostaticModel,
    data: MeasurementSet,
    noise: NoiseFloor | None = None,
    folds: int = DEFAULT_FOLDS,
    seed: int = 0,
    batch: PoseBatch | None = None,
    base: CrossValidation | None = None,
) -> Diagnosis:
    """Find the effect the model misses (see the module docstring for the method).

    Args:
        model: The current model (its effects are never suggested again).
        data: The samples.
        noise: Noise floor (default: estimated from repeated samples, or unknown).
        folds: Number of cross-validation folds.
        seed: Seed of the fold assignment.
        batch: Kinematics of ``data.q`` if already computed.
        base: Cross-validation of ``model`` on the same folds, if already computed.

    Raises:
        IdentificationError: Too few samples or poses for the current model.
    """
    t0 = time.perf_counter()
    if batch is None:
        batch = model.batch_of(data)
    fold = make_folds(data, folds, seed)
    if base is None:
        base = cross_validate(model, data, fold, batch)
    if noise is None:
        noise = estimate_noise_floor(data, base.heldout_residual)
    tau = np.einsum("mak,ma->mk", batch.J, data.wrench)
    feats = residual_features(data, batch.T[:, :3, 3], tau)
    corr = correlations(base.heldout_residual, feats)
    at_noise0, p_above = _at_noise(base, noise, feats)
    above = None if noise.sigma is None else not at_noise0

    scored, skipped = evaluate_candidates(
        model, data, fold, base, candidate_labels(model), batch, noise
    )
    candidates = tuple(c for c, _ in scored)

    chain, at_noise = _greedy_chain(data, fold, scored, noise, feats, batch, at_noise0)
    verdict, message = _verdict(base, noise, candidates, chain, corr, at_noise0, at_noise)
    if noise.sigma is None:
        message += f"; {NO_FLOOR}"
    seconds = time.perf_counter() - t0
    log.info("diagnosis of %s: %d candidates, %d skipped, %d chain step(s), %.2f s: %s",
             ", ".join(model.labels), len(candidates), len(skipped), len(chain), seconds,
             verdict)
    return Diagnosis(
        verdict=verdict,
        message=message,
        labels=tuple(model.labels),
        heldout_rms=base.heldout_rms,
        heldout_residual=base.heldout_residual,
        noise=noise,
        p_above_noise=p_above,
        above_noise=above,
        candidates=candidates,
        skipped=tuple(skipped),
        chain=tuple(chain),
        chain_at_noise=bool(chain) and at_noise,
        correlations=corr,
        folds=folds,
        seconds=seconds,
    )


#: Names re-exported here: the scoring, candidates and cross-validation this diagnosis uses.
__all__ = ["ALPHA", "DEFAULT_FOLDS", "FIT_TOL", "MAX_CHAIN", "NOISE_TOLERANCE", "TIE_LEVEL",
           "Candidate", "ChainStep", "CrossValidation", "Diagnosis", "Skipped",
           "candidate_labels", "cross_validate", "diagnose", "evaluate_candidates",
           "make_folds"]
