"""Which physical effect is missing from a model, on a load campaign (``rfsw-plan validate``).

For every candidate (:func:`~rfsw_plan.validation.engine.candidates.candidate_labels`: each library
effect the model lacks, at every joint where it applies) the effect is added, all parameters
are re-identified, and the model is scored on data the fit did not see (k folds, grouped by
pose so that repeats of one pose never sit on both sides;
:func:`~rfsw_plan.validation.engine.crossval.cross_validate`). The held-out F test, the ranking, the
ties and the named candidate are the workbench's one scoring
(:mod:`rfsw_plan.validation.engine.scoring`), shared with ``validate-weld``.

The residual is *at the noise floor* when SSE_0 / sigma^2 is not above chi^2(n) (sigma given)
or F(n, dof) (sigma from repeats) at level ALPHA, or RMS_0 <= NOISE_TOLERANCE sigma.

Verdict: ``adequate`` when the current model's held-out residual is at the noise floor and
within FLOOR_RATIO times it; at the floor (not significantly above it) but beyond FLOOR_RATIO
times it, the selection is run (the same 1.5x rule as "missing"), and with no significant
library effect the verdict is ``unexplained``, never ``adequate``: a test without the power to
see the excess is no evidence that there is none;
``missing`` when the named candidate (and, greedily, at most MAX_CHAIN - 1 more, each round
re-testing every remaining candidate on the extended model) brings the held-out RMS to within
FLOOR_RATIO times the noise floor, checked on the selection's own cross-validation before the
claim is made; ``unexplained`` otherwise, with the features the residual correlates with (time,
pose, torques, extra columns) to point at the physics the library lacks. When the selection
named effects short of that, the message says "partly explained by X (N % of the excess over
the floor)", what the rest correlates with and which ``design-campaign`` would tell the
candidates apart; no effect the selection tested and rejected is offered. Without a noise floor
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
from rfsw_plan.progress import Bar
from rfsw_plan.validation.engine.candidates import candidate_form, candidate_labels
from rfsw_plan.validation.engine.crossval import (
    DEFAULT_FOLDS,
    FIT_TOL,
    CrossValidation,
    Indeterminate,
    cross_validate,
    make_folds,
    single_thread_numpy_blas,
)
from rfsw_plan.validation.engine.residuals import (
    FeatureCorrelation,
    NoiseFloor,
    correlation_json,
    correlations,
    estimate_noise_floor,
    noise_json,
    residual_features,
)
from rfsw_plan.validation.engine.scoring import (
    ALPHA,
    TIE_LEVEL,
    Candidate,
    improvement,
    named,
    rank,
    score,
    ties_of,
)

log = logging.getLogger(__name__)

#: A residual within this factor of the noise floor counts as "at the noise floor".
NOISE_TOLERANCE = 1.1
#: At most this many effects are chained greedily to reach the noise floor.
MAX_CHAIN = 4

Verdict = Literal["adequate", "missing", "unexplained", "undetermined"]

#: What a campaign without a noise floor should add next time.
NO_FLOOR = (
    "no repeats and no measuring noise given: the floor is unknown; for the next campaign, "
    "measure some poses twice in a row at the same load (repeats) or give the measuring "
    "device's noise (rfsw-plan validate --noise-mm)"
)


# --------------------------------------------------------------------------------------------
# Candidates


#: Why a candidate was not fitted: the data cannot identify it (rank, conditioning,
#: correlation with an effect of the model), or the data identify it but the fit does not
#: support it (its estimate lies outside the effect's physical range: no evidence for it).
SkipKind = Literal["not_identifiable", "not_supported"]

#: Notes of the identification that reject an estimate rather than a parameter the data
#: cannot see: a value outside the physical range, or beyond the plausible size.
_NOT_SUPPORTED = ("estimate ",)


@dataclass(frozen=True)
class Skipped:
    """A candidate that was not fitted.

    Attributes:
        label: Effect label.
        reason: Why (the data cannot identify it, too few samples...).
        kind: ``not_identifiable`` (rank, conditioning, correlation with an effect of the
            model, too few samples on each side) or ``not_supported`` (identified, but the
            estimate lies outside the effect's physical range: the data give no evidence for
            it, which is not a question of identifiability).
    """

    label: str
    reason: str
    kind: SkipKind = "not_identifiable"

    def to_json(self) -> dict[str, str]:
        """JSON form."""
        return {"label": self.label, "reason": self.reason}


def _skip(label: str, note: str) -> Skipped:
    """A :class:`Skipped` from an identification note, sorted into its kind."""
    if note.startswith(_NOT_SUPPORTED):
        return Skipped(label, f"not supported by this data: {note}", "not_supported")
    return Skipped(label, f"not identifiable from this data: {note}")


def _fitted(model: ElastostaticModel, data: MeasurementSet, folds: NDArray[np.int_],
            label: str, batch: PoseBatch, F_true: FloatArray, fit_steps: int | None = None
            ) -> tuple[CrossValidation | None, Skipped | None]:
    """Cross-validation of ``model`` with ``label`` added, or None and why it was not fitted."""
    reason = make_effect(model.robot, label).identifiable(batch, F_true)
    if reason:
        return None, _skip(label, reason)
    try:
        cv = cross_validate(model.with_effect(label), data, folds, batch, fit_steps)
    except IdentificationError as exc:
        return None, Skipped(label, str(exc))
    est = [e for e in cv.fit.estimates if e.effect == label]
    if not any(e.identified for e in est):
        return None, _skip(label, next((e.note for e in est if e.note),
                                       "no parameter identified"))
    return cv, None


#: Processes that fit the candidates of one round (the calling process is one of them) ...
CANDIDATE_PROCESSES = 2
#: ... when the data has at least this many measured values (below, a round takes well under a
#: second and a second process costs more than it saves).
PARALLEL_MIN_OBS = 1500

_Fitted = tuple[CrossValidation | None, Skipped | None]


def _processes(data: MeasurementSet, n_labels: int) -> int:
    """Processes for a round of ``n_labels`` candidates on ``data``: CANDIDATE_PROCESSES (at
    most the cores, :func:`rfsw_plan.parallel.cores`), or 1 for a short round."""
    from rfsw_plan.parallel import cores

    if n_labels < 4 or int(data.measured.sum()) < PARALLEL_MIN_OBS:
        return 1
    return max(1, min(CANDIDATE_PROCESSES, cores()))


def _fit_all(model: ElastostaticModel, data: MeasurementSet, folds: NDArray[np.int_],
             labels: Sequence[str], batch: PoseBatch, F_true: FloatArray, fit_steps: int | None
             ) -> list[_Fitted]:
    """:func:`_fitted` of every label, in order. With :func:`_processes` > 1 the candidates
    are shared with forked processes that inherit the data, a free process taking the next
    (:func:`rfsw_plan.parallel.fork_map`); each candidate's fit is the same computation
    wherever it runs, so the results do not depend on the split. A fit comes back without its
    lazily evaluated residual (:func:`~rfsw_plan.validation.engine.crossval.detach`: it
    pickles) and gets it again here (``attach``)."""
    from rfsw_plan.parallel import fork_map
    from rfsw_plan.validation.engine.crossval import attach, detach

    n = _processes(data, len(labels))

    def fit(i: int) -> _Fitted:
        cv, why = _fitted(model, data, folds, labels[i], batch, F_true, fit_steps)
        return (cv if n == 1 or cv is None else detach(cv)), why

    with Bar(len(labels), "diagnosis: candidates", "candidate") as bar:
        fitted = fork_map(fit, len(labels), n, on_done=lambda _: bar.update())
    if n == 1:
        return fitted
    return [(None if cv is None else attach(cv, data, batch, folds), why)
            for cv, why in fitted]


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
    fit_steps: int | None = None,
) -> tuple[list[tuple[Candidate, CrossValidation]], list[Skipped]]:
    """Add each effect in ``labels`` to ``model``, cross-validate, and score against ``base``.

    Effects whose :meth:`~rfsw_plan.elastostatics.effects.base.Effect.identifiable` gives a
    reason, that no data can fit, or none of whose parameters the data identifies are returned
    as :class:`Skipped` with the reason. The scored candidates come ranked
    (:func:`~rfsw_plan.validation.engine.scoring.rank`, ties against the noise floor ``noise``).
    ``fit_steps``: None: every candidate's fit converges; a number: ``model``'s parameters
    are a fit, and a candidate's fit takes that many Gauss-Newton steps from them
    (:func:`~rfsw_plan.validation.engine.crossval.cross_validate`'s ``steps``).
    """
    F_true = model.true_wrench(batch, data.wrench)
    done: list[tuple[str, CrossValidation]] = []
    skipped: list[Skipped] = []
    for label, (cv, why) in zip(labels, _fit_all(model, data, folds, labels, batch, F_true,
                                                 fit_steps), strict=True):
        if cv is None:
            assert why is not None
            skipped.append(why)
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
    """One step of the forward selection of effects (:func:`forward_select`).

    Attributes:
        label: Effect added in this step.
        rms_before: Held-out RMS before the step [m].
        rms_after: Held-out RMS after it [m].
        p_value: p-value of the improvement (held-out F test).
        explained_fraction: 1 - MSE_after / MSE_before of this step's held-out residual.
        share_explained: 1 - MSE_after / MSE_0 with MSE_0 the held-out MSE of the model the
            selection started from: the share of its residual the effects so far explain.
        tested: Candidates tested in this step.
        ties: Significant candidates of this step the data cannot tell from the one added
            (:func:`~rfsw_plan.validation.engine.scoring.ties_of`).
    """

    label: str
    rms_before: float
    rms_after: float
    p_value: float
    explained_fraction: float = float("nan")
    share_explained: float = float("nan")
    tested: int = 0
    ties: tuple[str, ...] = ()

    def to_json(self) -> dict[str, Any]:
        """JSON form (mm)."""
        return {"label": self.label, "heldout_rms_before_mm": self.rms_before * 1e3,
                "heldout_rms_after_mm": self.rms_after * 1e3, "p_value": self.p_value,
                "explained_fraction": _finite(self.explained_fraction),
                "share_explained": _finite(self.share_explained), "tested": self.tested,
                "ties": list(self.ties)}


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


@dataclass(frozen=True)
class Selection:
    """Outcome of :func:`forward_select`.

    Attributes:
        steps: The effects added, in order.
        at_noise: The held-out residual after the last step is at the noise floor (or, with
            the floor unknown, no feature test is significant).
        stop: Why the selection stopped, in words.
        skipped: Candidates not fitted in the last round tested, with the reason.
        model: The model after the last step (its parameters identified on all samples).
        cv: Its cross-validation.
    """

    steps: tuple[ChainStep, ...]
    at_noise: bool
    stop: str
    skipped: tuple[Skipped, ...]
    model: ElastostaticModel = field(repr=False)
    cv: CrossValidation = field(repr=False)


@dataclass(frozen=True)
class Diagnosis:
    """Outcome of :func:`diagnose`.

    Attributes:
        verdict: ``adequate``, ``missing``, ``unexplained`` or ``undetermined``.
        message: One-sentence summary for the user.
        labels: Effects of the diagnosed model.
        heldout_rms: Held-out RMS of the current model (re-identified per fold) [m].
        heldout_residual: Its held-out residual [m], shape (m, 3).
        noise: Noise floor used.
        p_above_noise: p-value of "the held-out residual is at the noise floor" (NaN if the
            noise floor is unknown).
        above_noise: True if the residual is significantly above the noise floor (None if the
            noise floor is unknown).
        candidates: Candidates of the first step, scored on the current model, best (lowest
            held-out RMS) first.
        skipped: Candidates not fitted in the last round of the selection because the data
            cannot identify them (rank, conditioning, correlation with a named effect), with
            the reason.
        chain: The forward selection's steps from the current model (the first names the
            missing effect when the verdict is ``missing``).
        chain_at_noise: True if the last step reached the noise floor.
        correlations: Feature tests of the held-out residual of the current model, most
            explanatory first.
        folds: Number of folds.
        seconds: Wall time of the diagnosis [s].
        not_supported: Candidates of the last round whose fit lies outside the effect's
            physical range (no evidence for them; not a question of identifiability).
        stop: Why the forward selection stopped.
        advice: What the next campaign should add so that the effects the data could not
            separate become identifiable (poses, approach directions, load signs).
        excess_explained: Share of the excess over the noise floor the selection's effects
            explain, (MSE_0 - MSE_1) / (MSE_0 - sigma^2) (:func:`excess_share`; NaN without a
            selection).
        floor_ratio: The selection's held-out RMS over the noise floor (NaN if unknown).
        experiment: With the verdict ``unexplained`` after a selection (partly explained):
            the ``design-campaign`` that would tell its effects from their candidates.
        indeterminate: Samples whose state of an effect of the selected model nothing before
            them in the data sets (the side of a play before the first load on its joint),
            scored against the model's stated spread
            (:class:`~rfsw_plan.validation.engine.crossval.Indeterminate`).
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
    not_supported: tuple[Skipped, ...] = ()
    stop: str = ""
    advice: tuple[str, ...] = ()
    excess_explained: float = float("nan")
    floor_ratio: float = float("nan")
    experiment: str = ""
    indeterminate: tuple[Indeterminate, ...] = ()

    @property
    def missing(self) -> Candidate | None:
        """The first effect the selection names (verdict ``missing``) as scored on the
        diagnosed model, else None (also when the final check put in its place an effect the
        first step could not fit)."""
        if self.verdict != "missing" or not self.chain:
            return None
        return next((c for c in self.candidates if c.label == self.chain[0].label), None)

    @property
    def partly(self) -> tuple[str, ...]:
        """The effects that explain part of the residual but not down to FLOOR_RATIO times
        the floor (verdict ``unexplained`` after a selection), in order."""
        return tuple(s.label for s in self.chain) if self.verdict == "unexplained" else ()

    @property
    def named(self) -> tuple[str, ...]:
        """The effects named, in the order the selection added them (verdict ``missing``)."""
        return tuple(s.label for s in self.chain) if self.verdict == "missing" else ()

    def to_json(self) -> dict[str, Any]:
        """JSON form (mm)."""
        return {
            "verdict": self.verdict,
            "message": self.message,
            "model_effects": list(self.labels),
            "heldout_rms_mm": self.heldout_rms * 1e3,
            "noise": noise_json(self.noise),
            "p_above_noise": None if np.isnan(self.p_above_noise) else self.p_above_noise,
            "above_noise": self.above_noise,
            "missing": None if not self.named else {
                "effect": self.chain[0].label.partition(":j")[0],
                "joint": (int(self.chain[0].label.partition(":j")[2])
                          if ":j" in self.chain[0].label else None),
                "label": self.chain[0].label,
                "heldout_rms_before_mm": self.chain[0].rms_before * 1e3,
                "heldout_rms_after_mm": self.chain[0].rms_after * 1e3,
            },
            "named": list(self.named),
            "partly_explained": list(self.partly),
            "excess_explained": _finite(self.excess_explained),
            "floor_ratio": _finite(self.floor_ratio),
            "experiment": self.experiment,
            "indeterminate": [x.to_json() for x in self.indeterminate],
            "indeterminate_readings": sum(x.count for x in self.indeterminate),
            "candidates": [c.to_json() for c in self.candidates],
            "not_identifiable": [s.to_json() for s in self.skipped],
            "not_supported": [s.to_json() for s in self.not_supported],
            "chain": [s.to_json() for s in self.chain],
            "chain_at_noise": self.chain_at_noise,
            "stop": self.stop,
            "advice": list(self.advice),
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


def forward_select(
    model: ElastostaticModel,
    data: MeasurementSet,
    fold: NDArray[np.int_],
    base: CrossValidation,
    noise: NoiseFloor,
    feats: dict[str, Any],
    batch: PoseBatch,
    *,
    first: tuple[list[tuple[Candidate, CrossValidation]], list[Skipped]] | None = None,
    max_steps: int = MAX_CHAIN,
    fit_steps: int | None = None,
) -> Selection:
    """Forward selection of effects under held-out cross-validation (folds by pose group).

    Each step tests every library effect the current model lacks (the ones a previous step
    could not fit too: an effect whose estimate was negative next to a larger unmodelled one
    may be clear once that one is in), re-identifies all parameters with it on the training
    folds and scores it on the held-out fold (:func:`evaluate_candidates`); the candidate
    :func:`~rfsw_plan.validation.engine.scoring.named` picks (significant by the held-out F test at
    level ALPHA, Bonferroni over the step's candidates, plausible, the simplest among those
    the data cannot tell apart) is added and becomes the next step's starting model.

    Stopping rule: the held-out residual is at the noise floor, or no candidate of the step
    is significant, or ``max_steps`` steps.

    Args:
        model: Starting model.
        data: The samples.
        fold: Fold of every sample (grouped by pose).
        base: Cross-validation of ``model`` on ``fold``.
        noise: Noise floor.
        feats: Residual features (the stopping test without a floor).
        batch: Kinematics of ``data.q``.
        first: The first step's :func:`evaluate_candidates` on ``model``, if already done.
        max_steps: At most this many effects.
        fit_steps: None: every fit converges. A number: each candidate's fit takes that
            many Gauss-Newton steps from the current model's fit (a model nonlinear in its
            parameters; :func:`~rfsw_plan.validation.engine.crossval.cross_validate`).
    """
    at_noise, _ = _at_noise(base, noise, feats)
    mse0 = base.sse / max(base.n_obs, 1)
    current, cv = model, base
    steps: list[ChainStep] = []
    skipped: list[Skipped] = []
    if at_noise and within_ratio(base.heldout_rms, noise):
        return Selection((), True, "the starting model is at the noise floor", (), model, base)
    stop = f"{max_steps} effects added (the most the selection adds)"
    rounds: dict[tuple[str, ...], list[tuple[Candidate, CrossValidation]]] = {}
    while len(steps) < max_steps:
        if first is not None and not steps:
            scored, skipped = first
        else:
            scored, skipped = evaluate_candidates(current, data, fold, cv,
                                                  candidate_labels(current), batch, noise,
                                                  fit_steps)
        rounds[tuple(s.label for s in steps)] = scored
        ranked = [x for x, _ in scored]
        c = named(ranked)
        if c is None:
            stop = (f"no remaining candidate is significant (held-out F test at "
                    f"{ALPHA:g}, Bonferroni over {len(scored)} candidates)")
            break
        cv = dict((x.label, v) for x, v in scored)[c.label]
        current = cv.fit.model
        steps.append(ChainStep(
            c.label, c.rms_before, c.rms_after, c.p_value, c.explained_fraction,
            float(1.0 - (cv.sse / max(cv.n_obs, 1)) / mse0) if mse0 > 0 else 0.0,
            len(scored), tuple(ties_of(ranked, c))))
        skipped = [s for s in skipped if s.label != c.label]
        at_noise, _ = _at_noise(cv, noise, feats)
        if at_noise:
            stop = ("the held-out residual is at the noise floor" if noise.sigma is not None
                    else "no feature test of the held-out residual is significant")
            break
    if len(steps) >= 2:
        swapped = _simpler(model, data, fold, noise, feats, batch, steps, cv, at_noise,
                           fit_steps, rounds)
        if swapped is not None:
            swaps = [f"{a.label} replaced by the simpler {b}, as good with the others in"
                     for a, b in zip(steps, swapped, strict=True) if a.label != b]
            steps, current, cv = _path(model, data, fold, base, batch, swapped, steps,
                                       fit_steps)
            at_noise, _ = _at_noise(cv, noise, feats)
            stop += "; " + "; ".join(swaps)
    return Selection(tuple(steps), at_noise, stop, tuple(skipped), current, cv)


def _n_params(model: ElastostaticModel, label: str) -> int:
    """Parameters of the effect ``label`` the fit identifies (not its profiled ones)."""
    e = make_effect(model.robot, label)
    return sum(n not in e.profiled_params for n in e.param_names())


def _simpler(
    model: ElastostaticModel, data: MeasurementSet, fold: NDArray[np.int_], noise: NoiseFloor,
    feats: dict[str, Any], batch: PoseBatch, steps: Sequence[ChainStep],
    final: CrossValidation, at_noise: bool, fit_steps: int | None = None,
    rounds: dict[tuple[str, ...], list[tuple[Candidate, CrossValidation]]] | None = None,
) -> list[str] | None:
    """The selection's check of each step once the others are in: with every other selected
    effect in the model, all candidates are scored again; if the one named is simpler (fewer
    parameters) than the step's and the model with it is as good (at the noise floor when the
    selection reached it, else no larger held-out error), it replaces the step's. An effect
    that a forward step took because it also soaked up a later effect (full link errors for
    joint offsets plus a play) is so replaced by the simpler one. Returns the new labels in
    step order, or None if none changes. ``rounds``: the forward steps' scored candidates by
    the labels of the model they were added to; a check whose other effects are such a model
    (the last step's: the steps before it) takes them instead of scoring them again."""
    labels = [s.label for s in steps]
    changed = False
    for i, own in enumerate(list(labels)):
        if _n_params(model, own) <= 1:
            continue  # a candidate scored has at least one parameter: none is simpler
        others = labels[:i] + labels[i + 1:]
        scored = (rounds or {}).get(tuple(others))
        if scored is None:
            m = model
            for lab in others:
                m = m.with_effect(lab)
            try:
                cv_o = cross_validate(m, data, fold, batch)
            except IdentificationError:
                continue
            start = cv_o.fit.model
            scored, _ = evaluate_candidates(start, data, fold, cv_o, candidate_labels(start),
                                            batch, noise, fit_steps)
        c = named([x for x, _ in scored])
        if c is None or c.label == own or c.n_params >= _n_params(model, own):
            continue
        cv_c = dict((x.label, v) for x, v in scored)[c.label]
        good = (_at_noise(cv_c, noise, feats)[0] if at_noise
                else cv_c.sse <= final.sse)
        if good:
            labels[i] = c.label
            changed = True
    return labels if changed else None


def _path(
    model: ElastostaticModel, data: MeasurementSet, fold: NDArray[np.int_],
    base: CrossValidation, batch: PoseBatch, labels: Sequence[str],
    old: Sequence[ChainStep], fit_steps: int | None = None,
) -> tuple[list[ChainStep], ElastostaticModel, CrossValidation]:
    """The steps of adding ``labels`` in order from ``model``, each scored against the one
    before it (the held-out F test of :func:`~rfsw_plan.validation.engine.scoring.improvement`)."""
    mse0 = base.sse / max(base.n_obs, 1)
    cv = base
    steps: list[ChainStep] = []
    for lab, prev in zip(labels, old, strict=True):
        nxt = cross_validate(cv.fit.model.with_effect(lab), data, fold, batch, fit_steps)
        _, p, _ = improvement(cv.sse, nxt.sse, _n_params(model, lab),
                              max(nxt.n_obs - nxt.n_free, 1), max(prev.tested, 1))
        steps.append(ChainStep(
            lab, cv.heldout_rms, nxt.heldout_rms, p,
            float(1.0 - nxt.sse / cv.sse) if cv.sse > 0 else 0.0,
            float(1.0 - (nxt.sse / max(nxt.n_obs, 1)) / mse0) if mse0 > 0 else 0.0,
            prev.tested, prev.ties if prev.label == lab else ()))
        cv = nxt
    return steps, cv.fit.model, cv


def advice_for(model: ElastostaticModel, batch: PoseBatch, data: MeasurementSet,
               skipped: Sequence[Skipped], named: Sequence[str], at_noise: bool) -> list[str]:
    """What the next campaign should add so that the effects this data could not identify
    become identifiable (each effect's
    :meth:`~rfsw_plan.elastostatics.effects.base.Effect.campaign_advice`: poses, approach
    directions, load signs), one line per effect that has something to say.

    Above the noise floor every such effect is advised. At the floor only those on the joints
    of the named effects and of the model's own per-joint effects (the data cannot tell those
    from the one in the model); with only whole-robot effects named (joint offsets, which may
    hide a play seen from one side) every one; with nothing named, none."""
    F = model.true_wrench(batch, data.wrench)
    own = [e.label for e in model.effects if not e.setup and e.joint is not None
           and e is not model.joint_compliance]
    joints = {make_effect(model.robot, x).joint for x in [*named, *own]} - {None}
    if at_noise and not joints and not named:
        return []
    out: list[str] = []
    for s in skipped:
        if s.kind != "not_identifiable":
            continue
        eff = make_effect(model.robot, s.label)
        if at_noise and joints and eff.joint not in joints:
            continue
        tip = eff.campaign_advice(batch, F)
        if tip:
            out.append(f"{s.label}: {tip}")
    return out


#: "missing X" only when the model with X (and the selection's other effects) has a held-out RMS
#: within this factor of the noise floor: the verdict checks the claim before it makes it
#: (issue 40). Short of it, the effects are "partly explained" and the rest "unexplained".
FLOOR_RATIO = 1.5


def reaches_floor(rms: float, noise: NoiseFloor, at_noise: bool) -> bool:
    """True if a held-out RMS ``rms`` [m] backs the claim "missing": RMS <= FLOOR_RATIO sigma
    with the noise floor sigma known, else (no floor) no feature test of the residual is
    significant (``at_noise``)."""
    if noise.sigma is None:
        return at_noise
    return bool(rms <= FLOOR_RATIO * noise.sigma)


def within_ratio(rms: float, noise: NoiseFloor) -> bool:
    """True if a held-out RMS ``rms`` [m] is within FLOOR_RATIO x the noise floor (or the
    floor is unknown): "adequate" without testing the library's effects."""
    return noise.sigma is None or bool(rms <= FLOOR_RATIO * noise.sigma)


def excess_share(rms0: float, rms1: float, noise: NoiseFloor) -> float:
    """Share of the excess over the noise floor that a model explains:
    (MSE_0 - MSE_1) / (MSE_0 - sigma^2) with MSE = RMS^2 of the held-out residual (sigma = 0
    when the floor is unknown: the share of the residual), clipped to [0, 1]."""
    s2 = 0.0 if noise.sigma is None else noise.sigma ** 2
    excess = rms0 ** 2 - s2
    if excess <= 0:
        return 1.0
    return float(np.clip((rms0 ** 2 - rms1 ** 2) / excess, 0.0, 1.0))


def _points(corr: Sequence[FeatureCorrelation]) -> str:
    top = [c for c in corr if c.significant][:3]
    return ", ".join(f"{c.feature} (R^2 {c.r2:.2f})" for c in top) or "no tested feature"


def _experiment(model: ElastostaticModel, data: MeasurementSet,
                chain: Sequence[ChainStep]) -> str:
    """The campaign that would tell the chain's effects from the candidates the data could not
    tell them from (``design-campaign`` with the campaign's own largest load and half of it,
    so that a load-dependent residual shows at two load levels)."""
    labels = list(dict.fromkeys([lab for s in chain for lab in (s.label, *s.ties)]))
    f = float(np.max(np.linalg.norm(data.wrench[:, :3], axis=1), initial=0.0))
    n_poses = len(set(data.pose_id)) if data.pose_id is not None else len(data)
    cmd = (f"rfsw-plan design-campaign --robot {model.robot.name} --poses {max(n_poses, 6)} "
           f"--effects {','.join(labels)} --load-N")
    if f <= 0:
        return f"{cmd} 0"
    return (f"{cmd} {f:.0f}, and again with --load-N {f / 2:.0f} (a residual that "
            "depends on the load shows between the two levels)")


def _verdict(
    base: CrossValidation, noise: NoiseFloor, candidates: tuple[Candidate, ...],
    chain: Sequence[ChainStep], corr: Any, at_noise0: bool, at_noise: bool,
    rest: Sequence[FeatureCorrelation] = (), experiment: str = "",
) -> tuple[Verdict, str]:
    """The verdict and its one-line message (see the module docstring).

    ``missing`` only when the selection's held-out RMS reaches FLOOR_RATIO times the floor
    (:func:`reaches_floor`); a selection short of it is "partly explained by X (N % of the
    excess)" and the verdict ``unexplained``, with what the rest (``rest``: the feature tests
    of the selection's held-out residual) correlates with and the ``experiment`` that would
    tell the candidates apart."""
    mm = 1e3
    floor = "unknown" if noise.sigma is None else f"{noise.sigma * mm:.4g} mm"
    if at_noise0 and noise.sigma is None:
        return "undetermined", (
            f"undetermined: held-out RMS {base.heldout_rms * mm:.4g} mm and no tested feature "
            "explains it, but without a noise floor that does not make the model adequate"
        )
    if at_noise0 and not chain:
        if within_ratio(base.heldout_rms, noise):
            return "adequate", (
                f"adequate: held-out RMS {base.heldout_rms * mm:.4g} mm is at the noise floor "
                f"({floor}); no effect is missing"
            )
        # Not significantly above the floor, but beyond FLOOR_RATIO x it: the same 1.5x rule
        # as "missing" keeps it from being "adequate" (a test without the power to see the
        # excess is no evidence that there is none).
        assert noise.sigma is not None
        return "unexplained", (
            f"unexplained: held-out RMS {base.heldout_rms * mm:.4g} mm is "
            f"{base.heldout_rms / noise.sigma:.2f} x the noise floor ({floor}), beyond "
            f"{FLOOR_RATIO:g} x it though not significantly above it on this data, and no "
            f"library effect is significant; the residual correlates most with {_points(corr)}"
        )
    if chain and reaches_floor(chain[-1].rms_after, noise, at_noise):
        first, last = chain[0], chain[-1]
        chosen = next((c for c in candidates if c.label == first.label), None)
        ties = [] if chosen is None else ties_of(candidates, chosen)
        names = " + ".join(s.label for s in chain)
        tail = (f"at the noise floor ({floor})" if at_noise or noise.sigma is None else
                f"{last.rms_after / noise.sigma:.2f} x the noise floor ({floor})")
        return "missing", (
            f"missing: {names} (held-out RMS {first.rms_before * mm:.4g} -> "
            + "".join(f"{s.rms_after * mm:.4g} -> " for s in chain[:-1])
            + f"{last.rms_after * mm:.4g} mm, {tail})"
            + (f"; this data cannot tell {first.label} from {', '.join(ties)}" if ties
               else "")
        )
    if chain:
        last = chain[-1]
        share = excess_share(base.heldout_rms, last.rms_after, noise)
        of = "the excess over the noise floor" if noise.sigma is not None else "the residual"
        ratio = ("" if noise.sigma is None
                 else f", {last.rms_after / noise.sigma:.2f} x the noise floor ({floor})")
        return "unexplained", (
            f"partly explained by {' + '.join(s.label for s in chain)} "
            f"({100 * share:.0f} % of {of}: held-out RMS {base.heldout_rms * mm:.4g} -> "
            f"{last.rms_after * mm:.4g} mm{ratio}); unexplained: no library effect explains "
            f"the rest, which correlates most with {_points(rest or corr)}"
            + (f"; to tell the candidates apart: {experiment}" if experiment else "")
        )
    return "unexplained", (
        f"unexplained: no library effect brings the held-out RMS "
        f"{base.heldout_rms * mm:.4g} mm to the noise floor ({floor}); the "
        f"residual correlates most with {_points(corr)}"
    )


@single_thread_numpy_blas
def _after_chain(model: ElastostaticModel, data: MeasurementSet, sel: Selection,
                 feats: Any) -> tuple[Any, str]:
    """What the residual left by the selection correlates with, and the experiment that
    would tell its effects apart (nothing without a chain)."""
    if not sel.steps:
        return (), ""
    return (correlations(sel.cv.heldout_residual, feats),
            _experiment(model, data, list(sel.steps)))


def _advice(sel: Selection, batch: PoseBatch, data: MeasurementSet,
            skipped: Sequence[Skipped], ind: Sequence[Indeterminate]) -> tuple[str, ...]:
    """What the next campaign should add (:func:`advice_for`), then how it avoids readings
    of unknown state (``ind``)."""
    return (*advice_for(sel.model, batch, data, skipped, [st.label for st in sel.steps],
                        sel.at_noise),
            *(f"{x.label}: {x.advice}" for x in ind if x.advice))


def _excess_explained(base: CrossValidation, chain: list[ChainStep], last_rms: float,
                      noise: NoiseFloor) -> float:
    """Share of the held-out excess over the noise floor the chain explains (NaN without)."""
    return excess_share(base.heldout_rms, last_rms, noise) if chain else float("nan")


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

    # Not significantly above the floor but more than FLOOR_RATIO x it: adequate only if no
    # library effect is significant either (the selection finds none).
    sel = (forward_select(model, data, fold, base, noise, feats, batch,
                          first=(scored, skipped))
           if not (at_noise0 and within_ratio(base.heldout_rms, noise))
           else Selection((), True, "the model is at the noise floor", (), model, base))
    chain, at_noise = list(sel.steps), sel.at_noise
    last_skipped = sel.skipped if sel.steps else tuple(skipped)
    rest, experiment = _after_chain(model, data, sel, feats)
    verdict, message = _verdict(base, noise, candidates, chain, corr, at_noise0, at_noise,
                                rest, experiment)
    last_rms = chain[-1].rms_after if chain else base.heldout_rms
    if noise.sigma is None:
        message += f"; {NO_FLOOR}"
    ind = sel.cv.indeterminate if chain else base.indeterminate
    advice = _advice(sel, batch, data, last_skipped, ind)
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
        skipped=tuple(s for s in last_skipped if s.kind == "not_identifiable"),
        chain=tuple(chain),
        chain_at_noise=bool(chain) and at_noise,
        correlations=corr,
        folds=folds,
        seconds=seconds,
        not_supported=tuple(s for s in last_skipped if s.kind == "not_supported"),
        stop=sel.stop,
        advice=advice,
        excess_explained=_excess_explained(base, chain, last_rms, noise),
        floor_ratio=(last_rms / noise.sigma if noise.sigma else float("nan")),
        experiment=experiment if verdict == "unexplained" else "",
        indeterminate=ind,
    )


#: Names re-exported here: the scoring, candidates and cross-validation this diagnosis uses.
__all__ = ["ALPHA", "DEFAULT_FOLDS", "FIT_TOL", "FLOOR_RATIO", "MAX_CHAIN", "NOISE_TOLERANCE",
           "TIE_LEVEL",
           "Candidate", "ChainStep", "CrossValidation", "Diagnosis", "Selection", "Skipped",
           "candidate_labels", "cross_validate", "diagnose", "evaluate_candidates",
           "forward_select", "make_folds"]
