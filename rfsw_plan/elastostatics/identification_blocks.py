"""Identification in blocks of samples: the same least squares, with bounded memory.

:func:`~rfsw_plan.elastostatics.identification.identify` stacks the regressor of every sample
(3 m rows, P columns, plus the effects' intermediate arrays), which for a 1 kHz log of 17 min
(10^6 samples) needs gigabytes. Least squares only needs the triangular factor R of the stacked
matrix [A | r] (A the Jacobian, r the residual): for any x,

    || A x - r ||^2 = || R [x; -1] ||^2,   [A | r] = Q R,

and R of a stack is the R of the stacked R's of its parts (a tall-skinny QR in blocks). So the
samples are visited in blocks of :data:`BLOCK_SAMPLES`, each block's rows are folded into one
(P + 1) x (P + 1) factor per cross-validation fold, and every quantity of the fit comes from
those factors: the Gauss-Newton step, the column norms (invisible parameters), the singular
values (collinear parameters), the standard errors, the residual sums of squares, and the
per-fold least-squares steps of the held-out score. A model linear in its parameters (pose
affine in theta) needs one pass over the samples: at theta = theta0 + delta,
[A | r0 - A delta] = [A | r0] [[I, -delta], [0, 1]], so its factor is R0 times that matrix.

Only ordinary least squares on position rows is done here (what the diagnosis scores);
:func:`identify` keeps orientation rows and weighted least squares.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.effects import Effect, PoseBatch
from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.identification import (
    PRIOR_PASSES,
    IdentificationResult,
    Plausibility,
    build_result,
    implausible,
    keep_profiled,
    mark_collinear,
    mark_invisible,
    position_jacobian,
    set_theta,
)
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import IdentificationError

#: Samples per block: large enough that numpy's per-call cost is small, small enough that a
#: block's regressors and the effects' intermediate arrays stay in the tens of MB.
BLOCK_SAMPLES = 16_384

_CHUNKS_KEY = "_blocks"
#: Bytes of effect caches (e.g. the complementary-stiffness pose basis, 1.7 KB per sample)
#: kept in the blocks across the passes of one fit; beyond it a block's cache is dropped after
#: its pass and recomputed on the next (10^6 samples would otherwise keep 1.7 GB).
CACHE_BUDGET_BYTES = 128 * 2**20


def blocks(batch: PoseBatch, size: int | None = None) -> list[tuple[slice, PoseBatch]]:
    """The batch cut into views of at most ``size`` samples (default :data:`BLOCK_SAMPLES`),
    kept in ``batch.cache``, so a block's own cache, e.g. an effect's pose basis, lives as long
    as the batch."""
    size = BLOCK_SAMPLES if size is None else size
    key = f"{_CHUNKS_KEY}{size}"
    got: list[tuple[slice, PoseBatch]] | None = batch.cache.get(key)
    if got is None:
        got = []
        for a in range(0, len(batch), size):
            s = slice(a, min(a + size, len(batch)))
            got.append((s, batch.rows(s)))
        batch.cache[key] = got
    return got


def forget_block_caches(batch: PoseBatch) -> None:
    """Drop what effects cached in the blocks of ``batch`` (a candidate effect's pose basis
    is 1.7 KB per sample: kept for the passes of one fit, not for the whole diagnosis)."""
    for key, value in list(batch.cache.items()):
        if key.startswith(_CHUNKS_KEY):
            for _, b in value:
                b.cache.clear()


def predicted_positions(model: ElastostaticModel, batch: PoseBatch, wrench: FloatArray
                        ) -> FloatArray:
    """Predicted TCP positions T + dX [m], base frame, shape (m, 3), evaluated block by block
    (the effects' intermediate arrays are those of one block, not of every sample)."""
    out = np.empty((len(batch), 3))
    for s, b in blocks(batch):
        out[s] = b.T[:, :3, 3] + model.deflection_batch(b, wrench[s])[:, :3]
        b.cache.clear()
    return out


def _bound_cache(b: PoseBatch, used: int) -> int:
    """After a block's pass: keep its cache while the blocks' caches stay within
    :data:`CACHE_BUDGET_BYTES`, else drop it. Returns the bytes kept so far."""
    size = sum(int(getattr(v, "nbytes", 0)) for v in b.cache.values())
    if used + size > CACHE_BUDGET_BYTES:
        b.cache.clear()
        return used
    return used + size


def _qr_r(M: FloatArray, n: int) -> FloatArray:
    """Upper-triangular R (n x n) of M (rows x n), zero-padded when M has fewer rows."""
    R = np.asarray(np.linalg.qr(M, mode="r"))
    if R.shape[0] < n:
        R = np.vstack([R, np.zeros((n - R.shape[0], n))])
    return R


@dataclass(frozen=True)
class FoldFactors:
    """Triangular factors of [A | r] per fold at one parameter vector.

    Attributes:
        R: Factor of each fold, shape (k, P + 1, P + 1): columns 0..P-1 the Jacobian of the
            position rows with respect to every parameter, column P the residual [m].
        n_obs: Measured values of each fold, shape (k,).
    """

    R: FloatArray
    n_obs: NDArray[np.int_]
    prior: FloatArray | None = None

    @property
    def total(self) -> FloatArray:
        """Factor of all folds together (and the prior rows), shape (P + 1, P + 1)."""
        return _qr_r(self.training(None), self.R.shape[2])

    def training(self, held: int | None) -> FloatArray:
        """Rows of every fold but ``held`` (None: all) and the prior rows, stacked."""
        keep = self.R if held is None else self.R[np.arange(len(self.R)) != held]
        rows = keep.reshape(-1, self.R.shape[2])
        return rows if self.prior is None else np.vstack([rows, self.prior])

    @property
    def data_sse(self) -> float:
        """Sum of squared residuals of the observations (the prior rows left out) [m^2]."""
        return float(np.sum(self.R[:, :, -1] ** 2))

    def shifted(self, delta: FloatArray) -> FoldFactors:
        """Factors at theta + delta of a model linear in theta: r -> r - A delta."""
        P = self.R.shape[2] - 1
        M = np.eye(P + 1)
        M[:P, P] = -delta
        return FoldFactors(self.R @ M, self.n_obs, None if self.prior is None else self.prior @ M)


def prior_rows(weights: FloatArray, prior: FloatArray, theta: FloatArray) -> FloatArray | None:
    """The Gaussian prior of the regularised parameters as rows of [A | r]: for each k with
    weight w_k > 0, A = w_k e_k and r = w_k (prior_k - theta_k) [m]; None if there is none.
    Shape (p, P + 1)."""
    sel = np.flatnonzero(weights > 0)
    if not sel.size:
        return None
    out = np.zeros((sel.size, prior.size + 1))
    out[np.arange(sel.size), sel] = weights[sel]
    out[:, -1] = weights[sel] * (prior[sel] - theta[sel])
    return out


def _rows(
    model: ElastostaticModel, effects: list[Effect], data: MeasurementSet, s: slice,
    b: PoseBatch, jacobian: bool = True,
) -> tuple[FloatArray | None, FloatArray]:
    """Jacobian (n_meas, P) and residual (n_meas,) of the measured position rows of a block."""
    wrench = data.wrench[s]
    mask = data.measured[s]
    pred = b.T[:, :3, 3] + model.deflection_batch(b, wrench)[:, :3]
    r = (data.position[s] - pred)[mask]
    if not jacobian:
        return None, r
    A = position_jacobian(model, b, wrench, effects)[mask]
    return A, r


def fold_factors(
    model: ElastostaticModel, effects: list[Effect], data: MeasurementSet, batch: PoseBatch,
    folds: NDArray[np.int_], k: int,
) -> FoldFactors:
    """One pass over the samples: the factor of [A | r] of each fold at the model's parameters.

    Raises:
        IdentificationError: The regressor is not finite (values out of range in the data).
    """
    P = sum(e.params.size for e in effects)
    R = np.zeros((k, P + 1, P + 1))
    n_obs = np.zeros(k, dtype=np.int_)
    kept = 0
    for s, b in blocks(batch):
        A, r = _rows(model, effects, data, s, b)
        kept = _bound_cache(b, kept)
        assert A is not None
        if not np.all(np.isfinite(A)):
            raise IdentificationError(f"{data.source}: the regressor is not finite (values out "
                                      "of range in the data?)")
        fo = np.broadcast_to(folds[s][:, None], data.measured[s].shape)[data.measured[s]]
        Ar = np.column_stack([A, r])
        for f in range(k):
            sel = fo == f
            if sel.any():
                R[f] = _qr_r(np.vstack([R[f], Ar[sel]]), P + 1)
                n_obs[f] += int(sel.sum())
    return FoldFactors(R, n_obs)


@dataclass(frozen=True)
class BlockFit:
    """An identification done in blocks, with what the held-out score needs.

    Attributes:
        result: The identification (same fields as :func:`identify`'s).
        factors: Factors of [A | r] per fold at the identified parameters (every parameter's
            column; ``result.estimates`` says which are identified).
    """

    result: IdentificationResult
    factors: FoldFactors


def _step(R: FloatArray, idx: NDArray[np.int_]) -> FloatArray:
    """Least-squares step of the columns ``idx`` from a factor of [A | r] (columns scaled to
    unit norm first, as :func:`identify` does)."""
    A = R[:, idx]
    colscale = np.linalg.norm(A, axis=0)
    colscale[colscale == 0] = 1.0
    try:
        step, *_ = np.linalg.lstsq(A / colscale, R[:, -1], rcond=None)
    except np.linalg.LinAlgError as exc:
        raise IdentificationError(f"least squares failed ({exc})") from None
    return np.asarray(step / colscale)


def identify_blocks(
    model: ElastostaticModel,
    data: MeasurementSet,
    batch: PoseBatch,
    folds: NDArray[np.int_],
    max_iter: int = 30,
    tol: float = 1e-10,
    start: FloatArray | None = None,
) -> BlockFit:
    """:func:`~rfsw_plan.elastostatics.identification.identify` (ordinary least squares,
    position rows, every effect free) computed in blocks of samples.

    A model whose pose is not linear in theta (a wrench effect times the compliances) is
    solved by Gauss-Newton on its linearisation: at theta_k the factors of [A | r] are
    evaluated once (one pass over the samples), and the whole solve (positive compliances,
    the prior of the regularised parameters, the plausibility checks) runs on the linear model
    r(theta) = r_k - A_k (theta - theta_k), whose factors are those of theta_k times
    [[I, -(theta - theta_k)], [0, 1]] (no pass over the samples). Its solution is theta_k+1
    (halved while it raises the sum of squares); the iteration stops when no parameter moves by
    more than ``tol`` times its size or the sum of squares falls by less than :data:`SSE_TOL`
    of itself. At a fixed point the step of the linearisation is zero: the optimality
    condition of the nonlinear least squares with the same parameters held. Before, every
    re-solve (each positivity or plausibility decision, each prior pass) iterated Gauss-Newton
    with a pass per iteration: the FANUC R-2000iC fit with payload gravity, lost motion and
    torque-dependent stiffness took 184 passes, now 35 (measured). The decisions are taken
    after a first, unconstrained Gauss-Newton (to :data:`ROUGH_SSE_TOL`), where the fit is.
    A linear model needs one pass.

    Args:
        model: Starting model; its parameters are the priors. Not modified.
        data: Samples (position rows only: ``data.rotation`` is not used).
        batch: Kinematics of ``data.q``.
        folds: Fold index of every sample, shape (m,): the factors are kept per fold.
        max_iter: Gauss-Newton iteration cap (linearisations).
        tol: Convergence tolerance on the relative parameter step.
        start: Where Gauss-Newton starts [SI], shape (P,) (default: the prior). The priors
            stay the model's parameters. A start is taken as a converged fit (of all samples,
            for a fit without one fold): the decisions are taken from the first step, and
            ``max_iter`` Gauss-Newton steps from it refit a nonlinear model.

    Raises:
        IdentificationError: Fewer observations than parameters, no measured axis, regressor
            not finite, non-finite fit.
    """
    work = model.copy()
    effects = list(work.effects)
    names = [(e.label, n) for e in effects for n in e.param_names()]
    prior = np.concatenate([e.params for e in effects])
    P = prior.size
    n_obs = int(data.measured.sum())
    if n_obs == 0:
        raise IdentificationError(f"{data.source}: no measured TCP axis in any sample")
    if n_obs < P:
        raise IdentificationError(
            f"{data.source}: {n_obs} measured values cannot identify {P} parameters "
            f"({', '.join(work.labels)}); need at least {P} (better {3 * P})"
        )
    k = int(folds.max()) + 1
    sol = _Solver(work, effects, data, batch, folds, k, prior, n_obs)
    R0 = sol.ff_lin.total
    rms_before = float(np.sqrt(np.sum(R0[:, P] ** 2) / n_obs))
    if start is not None and not sol.linear and not np.array_equal(start, prior):
        sol.relinearise(np.array(start, dtype=float))
        R0 = sol.ff_lin.total
    setup = np.array([any(e.label == lab and e.setup for e in effects) for lab, _ in names],
                     dtype=bool)
    scale = np.where(np.abs(prior) > 0, np.abs(prior), 1.0)
    mark_invisible(names, sol.free, sol.notes, scale, R0[:, :P], n_obs)
    mark_collinear(names, sol.free, sol.notes, setup, R0[:, :P], sol.bounds.regularised)
    keep_profiled(effects, sol.free, sol.notes)
    theta, ff, iterations, converged = sol.gauss_newton(max_iter, tol, scale, start is not None)
    set_theta(effects, theta)
    free = sol.free
    std, cond = _standard_errors(ff, free, n_obs)
    sse = ff.data_sse
    dof = max(n_obs - int(free.sum()), 1)
    result = build_result(
        model=work, effects=effects, names=names, prior=prior, theta=theta, free=free,
        notes=sol.notes, std=std, cond=cond, rms_before=rms_before,
        rms_after=float(np.sqrt(sse / n_obs)), sigma=float(np.sqrt(sse / dof)),
        n_samples=len(data), n_obs=n_obs, iterations=iterations, converged=converged,
        method="ols",
    )
    return BlockFit(result, ff)


class _Solver:
    """The least squares of :func:`identify_blocks` on the linearisation at ``theta_lin``
    (factors ``ff_lin``), and the Gauss-Newton iteration that moves it (see there)."""

    def __init__(self, work: ElastostaticModel, effects: list[Effect], data: MeasurementSet,
                 batch: PoseBatch, folds: NDArray[np.int_], k: int, prior: FloatArray,
                 n_obs: int) -> None:
        self.work, self.effects, self.data, self.batch = work, effects, data, batch
        self.folds, self.k, self.prior, self.n_obs = folds, k, prior, n_obs
        self.linear = all(e.pose_linear_in_params() for e in effects)
        self.free = np.ones(prior.size, dtype=bool)
        self.notes = [""] * prior.size
        self.bounds = Plausibility.of(effects)
        #: Prior rows' weights of the regularised parameters (none on the first pass).
        self.weights = np.zeros(prior.size)
        jc = work.joint_compliance
        off = sum(e.params.size for e in effects[: effects.index(jc)])
        self.compliances = range(off, off + jc.params.size)
        self.theta_lin = prior.copy()
        self.ff_lin = fold_factors(work, effects, data, batch, folds, k)

    def evaluate(self, theta: FloatArray) -> FoldFactors:
        """The true factors at ``theta`` (a pass over the samples), with the prior rows."""
        set_theta(self.effects, theta)
        got = fold_factors(self.work, self.effects, self.data, self.batch, self.folds, self.k)
        return replace(got, prior=prior_rows(self.weights, self.prior, theta))

    def relinearise(self, theta: FloatArray) -> FoldFactors:
        """Move the linearisation to ``theta``; its factors with the prior rows."""
        ff = self.evaluate(theta)
        self.theta_lin, self.ff_lin = theta, replace(ff, prior=None)
        return ff

    def at(self, theta: FloatArray) -> FoldFactors:
        """Factors at ``theta`` of the linearisation (exact for a linear model)."""
        set_theta(self.effects, theta)
        return replace(self.ff_lin.shifted(theta - self.theta_lin),
                       prior=prior_rows(self.weights, self.prior, theta))

    def refit(self, theta: FloatArray) -> tuple[FloatArray, FoldFactors, int, bool]:
        """One least-squares step of the free parameters on the linearisation."""
        idx = np.flatnonzero(self.free)
        theta = theta.copy()
        theta[idx] += _step(self.at(theta).total, idx)
        return theta, self.at(theta), 1, True

    def solve(self) -> tuple[FloatArray, FoldFactors]:
        """The regularised, plausible least squares of the linearisation."""
        theta, ff, _, _ = self.refit(self.theta_lin)
        free, notes, prior = self.free, self.notes, self.prior
        while True:  # compliances must stay positive (see solve_identification)
            neg = [i for i in self.compliances if free[i] and theta[i] <= 0]
            if not neg:
                break
            for i in neg:
                free[i] = False
                notes[i] = f"estimate {theta[i]:.3g} rad/(N m) is not positive; prior kept"
                theta[i] = prior[i]
            theta, ff, _, _ = self.refit(theta)
        if not np.all(np.isfinite(theta)):
            raise IdentificationError(f"{self.data.source}: the fit did not give finite "
                                      "parameters (values out of range in the data?)")
        got = _plausible_fit(_Fit(theta, ff, 1, True), free, notes, prior, self.bounds,
                             self.weights, self.refit, self.n_obs)
        return got.theta, got.ff

    def gauss_newton(self, max_iter: int, tol: float, scale: FloatArray, decide: bool
                     ) -> tuple[FloatArray, FoldFactors, int, bool]:
        """(theta, true factors there, iterations, converged). First plain Gauss-Newton
        (nothing held yet; skipped with ``decide``: the start is a fit), then Gauss-Newton
        whose every step is the whole :meth:`solve`: the decisions are taken where the
        unconstrained fit converged. A step that raises the sum of squares (data and prior
        rows) is halved (undamped Gauss-Newton on a bilinear model can cycle)."""
        iterations, decide = 0, decide or self.linear
        for _ in range(2 * max_iter):
            held = int(self.free.sum())
            theta, ff = self.solve() if decide else self.refit(self.theta_lin)[:2]
            iterations += 1
            if self.linear:
                return theta, ff, iterations, True
            step = theta - self.theta_lin
            base = _sse(replace(self.ff_lin,
                                prior=prior_rows(self.weights, self.prior, self.theta_lin)))
            for _half in range(HALVINGS + 1):
                theta = self.theta_lin + step
                ff = self.evaluate(theta)
                if held != int(self.free.sum()) or _sse(ff) <= base:
                    break
                step = step / 2
            self.theta_lin, self.ff_lin = theta, replace(ff, prior=None)
            fell = base - _sse(ff)
            small = held == int(self.free.sum()) and (
                bool(np.all(np.abs(step) <= tol * np.maximum(np.abs(theta), scale)))
                or 0.0 <= fell <= (SSE_TOL if decide else ROUGH_SSE_TOL) * base)
            if small or iterations >= max_iter:
                if decide:
                    return theta, ff, iterations, small
                decide, iterations = True, 0
        return self.theta_lin, ff, iterations, False


#: A Gauss-Newton iteration that lowers the sum of squares by less than this share of it
#: ends the fit: the fit has converged in what it predicts (on an ill-conditioned model the
#: parameters can still creep along a flat valley for tens of iterations, each a pass over
#: the samples, without changing the prediction).
SSE_TOL = 1e-6
#: The same for the first, unconstrained Gauss-Newton: it only has to come close enough for
#: the decisions (positive compliances, plausible values) to be taken where the fit is.
ROUGH_SSE_TOL = 1e-4
#: Halvings of a Gauss-Newton step that raises the sum of squares, at most.
HALVINGS = 3


def _sse(ff: FoldFactors) -> float:
    """Sum of squares of the residual, data and prior rows [m^2]."""
    extra = 0.0 if ff.prior is None else float(np.sum(ff.prior[:, -1] ** 2))
    return ff.data_sse + extra


@dataclass(frozen=True)
class _Fit:
    """Where a Gauss-Newton solve ended: parameters, factors, iterations, converged."""

    theta: FloatArray
    ff: FoldFactors
    iterations: int
    converged: bool


def _plausible_fit(
    fit: _Fit, free: np.ndarray, notes: list[str], prior: FloatArray, bounds: Plausibility,
    weights: FloatArray, refit: Callable[[FloatArray], tuple[FloatArray, FoldFactors, int, bool]],
    n_obs: int,
) -> _Fit:
    """The prior of the regularised parameters, then what the data plausibly identifies.

    The prior's weight (``weights``, updated in place: the factors' prior rows read it) is set
    from the residual noise of the previous pass, :data:`PRIOR_PASSES` times; then the
    parameters :func:`~rfsw_plan.elastostatics.identification.implausible` names keep their
    prior, one at a time, each followed by a refit. ``free`` and ``notes`` are updated.
    """
    if bounds.regularised.any():
        for _ in range(PRIOR_PASSES):
            weights[:] = bounds.prior_weights(
                float(np.sqrt(fit.ff.data_sse / max(n_obs - int(free.sum()), 1))))
            fit = _Fit(*refit(fit.theta))
    std, _ = _standard_errors(fit.ff, free, n_obs)
    while (drop := implausible(fit.theta, std, free, bounds)) is not None:
        i, notes[i] = drop
        free[i] = False
        theta = fit.theta.copy()
        theta[i] = prior[i]
        fit = _Fit(*refit(theta))
        std, _ = _standard_errors(fit.ff, free, n_obs)
    return fit


def _standard_errors(ff: FoldFactors, free: np.ndarray, n_obs: int
                     ) -> tuple[FloatArray, float]:
    """Standard errors of the free parameters (NaN for the others) [SI], shape (P,), from the
    factor of [A | r] with the prior rows (a posterior error for regularised parameters) and
    the observations' residual variance, and the condition number of the column-normalised
    regressor."""
    R = ff.total
    P = free.size
    idx = np.flatnonzero(free)
    sse = ff.data_sse
    dof = max(n_obs - idx.size, 1)
    std = np.full(P, np.nan)
    if not idx.size:
        return std, float("nan")
    Aw = R[:, idx]
    colscale = np.linalg.norm(Aw, axis=0)
    colscale[colscale == 0] = 1.0
    An = Aw / colscale
    cov_n = np.linalg.pinv(An.T @ An)
    std[idx] = np.sqrt(np.maximum(np.diag(cov_n), 0.0) * sse / dof) / colscale
    return std, float(np.linalg.cond(An))


def heldout_blocks(
    model: ElastostaticModel, data: MeasurementSet, batch: PoseBatch, folds: NDArray[np.int_],
    cols: NDArray[np.int_], steps: FloatArray,
) -> Iterator[tuple[slice, FloatArray]]:
    """Held-out residual block by block: r - A[:, cols] steps[fold] of the measured rows.

    Args:
        model: The identified model (its residual r and Jacobian A are evaluated).
        steps: Per-fold parameter step (unscaled), shape (k, len(cols)).

    Yields:
        (block slice, residual of the measured values of that block, (n_meas,)) [m].
    """
    effects = list(model.effects)
    kept = 0
    for s, b in blocks(batch):
        A, r = _rows(model, effects, data, s, b)
        kept = _bound_cache(b, kept)
        assert A is not None
        fo = np.broadcast_to(folds[s][:, None], data.measured[s].shape)[data.measured[s]]
        yield s, r - np.einsum("ip,ip->i", A[:, cols], steps[fo])


def heldout_steps(factors: FoldFactors, idx: NDArray[np.int_]) -> tuple[FloatArray, float]:
    """Per-fold least-squares steps of the columns ``idx`` and the held-out sum of squares.

    For fold f the step d_f solves the other folds' least squares (their stacked factors), and
    the held-out residual of fold f is r_f - A_f d_f, whose squared norm is
    || R_f [-d_f; 1] || ^ 2 (``R_f`` restricted to the columns ``idx`` and the residual).

    Args:
        factors: Factors of [A | r] per fold at the identified parameters.
        idx: Identified columns, shape (p,).

    Returns:
        Steps, shape (k, p) [SI], and the held-out sum of squared residuals [m^2].
    """
    R = factors.R
    k, n, _ = R.shape
    cols = np.append(idx, n - 1)
    steps = np.zeros((k, idx.size))
    sse = 0.0
    for f in range(k):
        train = factors.training(f)[:, cols]
        steps[f] = _step(_qr_r(train, cols.size), np.arange(idx.size))
        sse += float(np.sum((R[f][:, cols] @ np.append(-steps[f], 1.0)) ** 2))
    return steps, sse
