"""Which physical effect is missing: k-fold cross-validation of every candidate effect.

For every effect of the library that is not yet in the model, and every joint where it applies,
the effect is added, all parameters are re-identified, and the model is scored on data the fit
did not see (k folds, grouped by pose so that repeats of one pose never sit on both sides).

Held-out residuals. The model (current or extended) is identified on all samples (Gauss-Newton,
:func:`~rfsw_plan.elastostatics.identification.identify`), giving theta* and the stacked
position Jacobian A (observations x identified parameters) and residual r at theta*. For fold f
the training rows give one least-squares step

    d_f = argmin || r_train - A_train d ||,   r_heldout,f = r_f - A_f d_f.

For a model linear in its parameters this *is* the per-fold fit (the solution does not depend on
the start point); for the bilinear ones (a wrench effect times the joint compliance) it is one
Gauss-Newton step from theta* on the training rows, which removes the leak of theta* to first
order. Kinematics are evaluated once for all samples.

Tests, at level ALPHA (Bonferroni over the candidates where several are compared):

* *above the noise floor*: SSE_0 / sigma^2 against chi^2(n) (sigma given) or F(n, dof)
  (sigma from repeats), and RMS_0 > NOISE_TOLERANCE sigma;
* *a candidate explains something*: held-out F = ((SSE_0 - SSE_1) / p) / (SSE_1 / (n - P_1))
  against F(p, n - P_1), p the candidate's identified parameters. An effect fitted to noise
  does not lower the held-out error, so noise does not name an effect.

Verdict: ``adequate`` when the current model's held-out residual is at the noise floor;
``missing`` when the best candidate (and, greedily, at most MAX_CHAIN - 1 more, each round
re-testing every remaining candidate on the extended model) brings the held-out residual to the
noise floor; ``unexplained`` otherwise, with the features the residual
correlates with (time, pose, torques, extra columns) to point at the physics the library lacks.
Without a noise floor (no repeats, no --noise-mm) "at the noise floor" is replaced by "no
feature test is significant".
"""

from __future__ import annotations

import functools
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from scipy import stats
from threadpoolctl import threadpool_limits

from rfsw_plan.elastostatics.effects import EFFECTS, make_effect
from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch
from rfsw_plan.elastostatics.identification import (
    IdentificationResult,
    identify,
    position_jacobian,
)
from rfsw_plan.elastostatics.identification_blocks import (
    forget_block_caches,
    heldout_blocks,
    heldout_steps,
    identify_blocks,
)
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import IdentificationError, InputError
from rfsw_plan.progress import progress
from rfsw_plan.validation.residuals import (
    FeatureCorrelation,
    NoiseFloor,
    correlation_json,
    correlations,
    estimate_noise_floor,
    noise_json,
    residual_features,
)

log = logging.getLogger(__name__)

#: Significance level of every test (family-wise where several candidates are compared).
ALPHA = 1e-3
#: A residual within this factor of the noise floor counts as "at the noise floor".
NOISE_TOLERANCE = 1.1
#: At most this many effects are chained greedily to reach the noise floor.
MAX_CHAIN = 3
#: Level of the F test below which a candidate is "indistinguishable" from the best one.
TIE_LEVEL = 0.05
#: Relative Gauss-Newton step tolerance of the fits scored here (the held-out RMS does not
#: change in its 10th digit below it; identify's default 1e-10 costs ~40 % more iterations).
FIT_TOL = 1e-7
#: Default number of folds.
DEFAULT_FOLDS = 5

Verdict = Literal["adequate", "missing", "unexplained", "undetermined"]

#: What a campaign without a noise floor should add next time.
NO_FLOOR = (
    "no repeats and no --noise-mm: the floor is unknown; for the next campaign, measure some "
    "poses twice in a row at the same load (repeats) or give the measuring device's noise "
    "with --noise-mm"
)


# --------------------------------------------------------------------------------------------
# Folds and cross-validation


def single_thread_blas(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Run ``fn`` with numpy's BLAS on one thread.

    The least-squares problems here are tall and skinny (3 m rows, tens of columns): a second
    OpenBLAS thread gains little and, on a loaded machine, spins against the other's work. With
    one thread ``validate`` on 10^4 samples with two hidden effects took 60 s instead of 161 s
    on this 2-core machine at a load average of 9-10 (same run; verdicts identical).
    """

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with threadpool_limits(limits=1, user_api="blas"):
            return fn(*args, **kwargs)

    return wrapper


def make_folds(data: MeasurementSet, k: int, seed: int = 0) -> NDArray[np.int_]:
    """Fold index 0..k-1 of every sample, grouped by pose, shape (m,).

    A pose is a ``pose_id`` when the file has one, else a distinct joint vector (to 1e-6 rad),
    so repeated samples and the loads of one pose stay in the same fold.

    Raises:
        InputError: k < 2.
        IdentificationError: Fewer distinct poses than folds.
    """
    if k < 2:
        raise InputError("--folds", "", f"{k}", "at least 2 folds")
    if data.pose_id is not None:
        _, groups = np.unique(data.pose_id, return_inverse=True)
    else:
        _, groups = np.unique(np.round(data.q / 1e-6), axis=0, return_inverse=True)
    groups = np.asarray(groups).reshape(-1)
    n_groups = int(groups.max()) + 1 if groups.size else 0
    if n_groups < k:
        raise IdentificationError(
            f"{data.source}: {n_groups} distinct poses cannot be split into {k} folds; need at "
            f"least {k} poses (use --folds {max(n_groups, 2)} or measure more poses)"
        )
    order = np.random.default_rng(seed).permutation(n_groups)
    fold_of_group = np.empty(n_groups, dtype=np.int_)
    fold_of_group[order] = np.arange(n_groups) % k
    return fold_of_group[groups]


@dataclass(frozen=True)
class CrossValidation:
    """Held-out score of one model form.

    Attributes:
        labels: Effects of the model.
        fit: Identification on all samples (its model is the one to keep).
        heldout_rms: RMS of :attr:`heldout_residual` [m].
        sse: Sum of squared held-out residuals [m^2].
        n_obs: Number of measured values.
        n_free: Number of identified parameters.
    """

    labels: tuple[str, ...]
    fit: IdentificationResult
    heldout_rms: float
    sse: float
    n_obs: int
    n_free: int
    residual_of: Callable[[], FloatArray] = field(repr=False, compare=False)
    _cache: dict[str, FloatArray] = field(default_factory=dict, repr=False, compare=False)

    @property
    def heldout_residual(self) -> FloatArray:
        """Residual of every sample predicted by the fit of the other folds [m], base frame,
        shape (m, 3); NaN = not measured. Computed on first use (one more pass over the
        samples: a candidate's score needs only :attr:`sse`)."""
        if "r" not in self._cache:
            self._cache["r"] = self.residual_of()
        return self._cache["r"]


def min_samples(n_params: int, data: MeasurementSet, k: int) -> int:
    """Samples needed so that every training fold has more observations than parameters."""
    per_sample = max(float(data.measured.sum()) / max(len(data), 1), 1.0)
    return int(np.ceil((n_params + 1) / per_sample * k / (k - 1))) + k


@single_thread_blas
def cross_validate(
    model: ElastostaticModel,
    data: MeasurementSet,
    folds: NDArray[np.int_],
    batch: PoseBatch | None = None,
) -> CrossValidation:
    """Identify all effects of ``model`` and score them on held-out folds (see module doc).

    Position-only data is fitted in blocks of samples
    (:func:`~rfsw_plan.elastostatics.identification_blocks.identify_blocks`: one triangular
    factor of [A | r] per fold, memory bounded whatever the number of samples); data with
    orientation rows goes through :func:`identify` (weighted orientation rows).

    Args:
        model: Model form with prior parameters (not modified).
        data: The samples.
        folds: Fold index of every sample, shape (m,).
        batch: Kinematics of ``data.q`` if already computed.

    Raises:
        IdentificationError: Too few samples for the parameters (says how many are needed).
    """
    k = int(folds.max()) + 1
    mask = data.measured
    obs_fold = np.broadcast_to(folds[:, None], mask.shape)[mask]
    min_train = min(int(np.sum(obs_fold != f)) for f in range(k))
    n_par = sum(e.params.size for e in model.effects)
    if min_train <= n_par:
        raise IdentificationError(
            f"{data.source}: {len(data)} samples cannot cross-validate the {n_par} parameters "
            f"of {', '.join(model.labels)} in {k} folds; need at least "
            f"{min_samples(n_par, data, k)} samples"
        )
    if batch is None:
        batch = model.batch_of(data)
    if data.rotation is not None:
        return _cross_validate_stacked(model, data, folds, batch, min_train)
    try:
        bf = identify_blocks(model, data, batch, folds, tol=FIT_TOL)
    finally:
        forget_block_caches(batch)
    fit = bf.result
    idx = np.flatnonzero([e.identified for e in fit.estimates])
    _check_trainable(data, fit, idx.size, min_train, k)
    steps, sse = heldout_steps(bf.factors, idx)
    n_obs = int(mask.sum())

    def residual_of() -> FloatArray:
        full = np.full(mask.shape, np.nan)
        try:
            for s, held in heldout_blocks(fit.model, data, batch, folds, idx, steps):
                view = full[s]
                view[mask[s]] = held
        finally:
            forget_block_caches(batch)
        return full

    return CrossValidation(
        labels=tuple(fit.model.labels),
        fit=fit,
        heldout_rms=float(np.sqrt(sse / n_obs)),
        sse=sse,
        n_obs=n_obs,
        n_free=int(idx.size),
        residual_of=residual_of,
    )


def _check_trainable(
    data: MeasurementSet, fit: IdentificationResult, n_free: int, min_train: int, k: int
) -> None:
    """Raise if a training fold has no more observations than identified parameters."""
    if min_train <= n_free:
        raise IdentificationError(
            f"{data.source}: {len(data)} samples cannot cross-validate {n_free} parameters "
            f"({', '.join(fit.model.labels)}) in {k} folds; need at least "
            f"{min_samples(n_free, data, k)} samples"
        )


def _cross_validate_stacked(
    model: ElastostaticModel, data: MeasurementSet, folds: NDArray[np.int_], batch: PoseBatch,
    min_train: int,
) -> CrossValidation:
    """:func:`cross_validate` on the stacked regressor of all samples (data with orientation
    rows: :func:`identify` weights them against the positions)."""
    k = int(folds.max()) + 1
    mask = data.measured
    obs_fold = np.broadcast_to(folds[:, None], mask.shape)[mask]
    fit = identify(model, data, tol=FIT_TOL)
    ident = np.array([e.identified for e in fit.estimates], dtype=bool)
    n_free = int(ident.sum())
    _check_trainable(data, fit, n_free, min_train, k)
    m = fit.model
    pred = batch.T[:, :3, 3] + m.deflection_batch(batch, data.wrench)[:, :3]
    r = (data.position - pred)[mask]
    A = position_jacobian(m, batch, data.wrench, m.effects)[mask][:, ident]
    held = np.empty_like(r)
    # One QR per fold; a training set is the stack of the other folds' small R factors, so
    # the k least-squares solves cost one pass over the data (same solution as lstsq).
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    An = A / scale
    blocks = []
    n_col = An.shape[1]
    for f in range(k):
        sel = obs_fold == f
        # R of [A_f | r_f] holds R_f and Q_f^T r_f without forming Q_f.
        Ra = np.asarray(np.linalg.qr(np.column_stack([An[sel], r[sel]]), mode="r"))
        blocks.append((Ra[:n_col, :n_col], Ra[:n_col, n_col]))
    for f in range(k):
        R_tr = np.concatenate([b[0] for g, b in enumerate(blocks) if g != f])
        c_tr = np.concatenate([b[1] for g, b in enumerate(blocks) if g != f])
        step, *_ = np.linalg.lstsq(R_tr, c_tr, rcond=None)
        te = obs_fold == f
        held[te] = r[te] - An[te] @ step
    full = np.full(mask.shape, np.nan)
    full[mask] = held
    sse = float(np.sum(held**2))
    return CrossValidation(
        labels=tuple(m.labels),
        fit=fit,
        heldout_rms=float(np.sqrt(sse / held.size)),
        sse=sse,
        n_obs=int(held.size),
        n_free=n_free,
        residual_of=lambda: full,
    )


# --------------------------------------------------------------------------------------------
# Candidates


@dataclass(frozen=True)
class Candidate:
    """One candidate effect scored on held-out data.

    Attributes:
        label: ``name`` or ``name:jN``.
        effect: Effect name.
        joint: 1-based joint, or None.
        rms_before: Held-out RMS of the model it was added to [m].
        rms_after: Held-out RMS with the effect added and everything re-identified [m].
        explained_fraction: 1 - MSE_after / MSE_before of the held-out residual (negative
            when the effect makes the prediction worse).
        f_stat: Held-out F statistic of the improvement.
        p_value: Its p-value.
        significant: p_value below ALPHA / number of candidates and the error fell.
        n_params: Identified parameters of the effect.
        params: Identified parameters on all samples [SI].
        notes: Notes of the identification for this effect's parameters.
        sse: Held-out sum of squared residuals [m^2].
        tied_with_best: True if its held-out error cannot be told apart from the best
            candidate's (F test at TIE_LEVEL): the data cannot say which of them is missing.
    """

    label: str
    effect: str
    joint: int | None
    rms_before: float
    rms_after: float
    explained_fraction: float
    f_stat: float
    p_value: float
    significant: bool
    n_params: int
    params: dict[str, float]
    notes: tuple[str, ...] = ()
    sse: float = float("nan")
    tied_with_best: bool = False
    std: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """JSON form (mm)."""
        return {
            "effect": self.effect,
            "joint": self.joint,
            "label": self.label,
            "rms_after_mm": self.rms_after * 1e3,
            "rms_before_mm": self.rms_before * 1e3,
            "explained_fraction": self.explained_fraction,
            "f_stat": self.f_stat if np.isfinite(self.f_stat) else None,
            "p_value": self.p_value,
            "significant": self.significant,
            "n_params": self.n_params,
            "params": self.params,
            "notes": list(self.notes),
            "tied_with_best": self.tied_with_best,
        }


@dataclass(frozen=True)
class Skipped:
    """A candidate that was not fitted.

    Attributes:
        label: Effect label.
        reason: Why (the data cannot identify it, too few samples...).
    """

    label: str
    reason: str


def candidate_labels(model: ElastostaticModel) -> list[str]:
    """Every library effect (per joint where it applies) that the model does not contain."""
    out = []
    for name, cls in EFFECTS.items():
        if name == "joint_compliance" or cls.setup:
            continue
        labels = [f"{name}:j{j + 1}" for j in range(model.robot.nq)] if cls.per_joint else [name]
        out += [x for x in labels if not model.has(x)]
    return out


def _split(label: str) -> tuple[str, int | None]:
    name, _, j = label.partition(":j")
    return name, int(j) if j else None


def _improvement(
    before: CrossValidation, after: CrossValidation, n_params: int, n_tests: int
) -> tuple[float, float, bool]:
    """Held-out F test of ``after`` against ``before``: (F, p-value, significant)."""
    dof = max(after.n_obs - after.n_free, 1)
    gain = before.sse - after.sse
    if n_params <= 0 or gain <= 0:
        return (float(gain / max(n_params, 1) / (after.sse / dof)) if after.sse > 0 else 0.0,
                1.0, False)
    F = (gain / n_params) / (after.sse / dof) if after.sse > 0 else float("inf")
    p = float(stats.f.sf(F, n_params, dof)) if np.isfinite(F) else 0.0
    return float(F), p, p < ALPHA / max(n_tests, 1)


def _score(
    label: str, before: CrossValidation, after: CrossValidation, n_tests: int
) -> Candidate:
    est = [e for e in after.fit.estimates if e.effect == label]
    n_par = sum(e.identified for e in est)
    F, p, sig = _improvement(before, after, n_par, n_tests)
    name, joint = _split(label)
    mse0 = before.sse / before.n_obs
    mse1 = after.sse / after.n_obs
    return Candidate(
        label=label,
        effect=name,
        joint=joint,
        rms_before=before.heldout_rms,
        rms_after=after.heldout_rms,
        explained_fraction=float(1.0 - mse1 / mse0) if mse0 > 0 else 0.0,
        f_stat=F,
        p_value=p,
        significant=sig,
        n_params=n_par,
        params={e.name: e.value for e in est},
        notes=tuple(f"{e.name}: {e.note}" for e in est if e.note),
        sse=after.sse,
        std={e.name: e.std_error for e in est if e.identified},
    )


def evaluate_candidates(
    model: ElastostaticModel,
    data: MeasurementSet,
    folds: NDArray[np.int_],
    base: CrossValidation,
    labels: Sequence[str],
    batch: PoseBatch,
) -> tuple[list[tuple[Candidate, CrossValidation]], list[Skipped]]:
    """Add each effect in ``labels`` to ``model``, cross-validate, and score against ``base``.

    Effects whose :meth:`~rfsw_plan.elastostatics.effects.base.Effect.identifiable` gives a
    reason, that no data can fit, or none of whose parameters the data identifies are returned
    as :class:`Skipped` with the reason.
    """
    F_true = model.true_wrench(batch, data.wrench)
    done: list[tuple[str, CrossValidation]] = []
    skipped: list[Skipped] = []
    for label in progress(labels, desc="diagnosis: candidates", total=len(labels),
                          unit="candidate"):
        eff = make_effect(model.robot, label)
        reason = eff.identifiable(batch, F_true)
        if reason:
            skipped.append(Skipped(label, f"not identifiable from this data: {reason}"))
            continue
        try:
            cv = cross_validate(model.with_effect(label), data, folds, batch)
        except IdentificationError as exc:
            skipped.append(Skipped(label, str(exc)))
            continue
        est = [e for e in cv.fit.estimates if e.effect == label]
        if not any(e.identified for e in est):
            why = next((e.note for e in est if e.note), "no parameter identified")
            skipped.append(Skipped(label, f"not identifiable from this data: {why}"))
            continue
        done.append((label, cv))
    n_tests = max(len(done), 1)
    scored = [(_score(label, base, cv, n_tests), cv) for label, cv in done]
    scored.sort(key=lambda x: x[0].rms_after)
    if scored:
        best = scored[0][1]
        crit = float(stats.f.ppf(1.0 - TIE_LEVEL, 1, max(best.n_obs - best.n_free, 1)))
        s2 = best.sse / max(best.n_obs - best.n_free, 1)
        scored = [
            (replace(c, tied_with_best=i > 0 and s2 > 0 and (cv.sse - best.sse) / s2 < crit), cv)
            for i, (c, cv) in enumerate(scored)
        ]
    return scored, skipped


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


def _at_noise(
    cv: CrossValidation, noise: NoiseFloor, feats: dict[str, Any]
) -> tuple[bool, float]:
    """(residual at the noise floor?, p-value of being above it)."""
    if noise.sigma is not None:
        p = noise.above(cv.sse, cv.n_obs)
        above = p < ALPHA and cv.heldout_rms > NOISE_TOLERANCE * noise.sigma
        return not above, p
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
    significant = [(c, cv) for c, cv in scored if c.significant]
    if at_noise0 or not significant:
        return chain, at_noise0
    best, current = significant[0]
    chain.append(ChainStep(best.label, best.rms_before, best.rms_after, best.p_value))
    pool = [c.label for c, _ in scored if c.label != best.label]
    at_noise, _ = _at_noise(current, noise, feats)
    while not at_noise and pool and len(chain) < MAX_CHAIN:
        # Start the next round from the identified values.
        more, _ = evaluate_candidates(current.fit.model, data, fold, current, pool, batch)
        more = [(c, v) for c, v in more if c.significant]
        if not more:
            break
        c, current = more[0]
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
        ties = [c.label for c in candidates if c.tied_with_best]
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


@single_thread_blas
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
        model, data, fold, base, candidate_labels(model), batch
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
