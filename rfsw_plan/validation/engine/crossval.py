"""Cross-validation of a model form: folds, and the held-out residual of a fitted regressor.

The one cross-validation of the workbench, used by ``validate`` (folds of poses) and
``validate-weld`` (blocks of arc length). A model form is fitted on all observations, giving
theta*, the residual r at theta* and the Jacobian A = d(prediction)/d(theta) (observations x
fitted parameters). For fold f the training rows give one least-squares step

    d_f = argmin || r_train - A_train d ||,   r_heldout,f = r_f - A_f d_f,

clipped to the parameters' physical range where one is given. For a model linear in its
parameters this *is* the per-fold fit (the solution does not depend on the start point); for a
nonlinear one it is one Gauss-Newton step from theta* on the training rows, which removes the
leak of theta* to first order.

:func:`heldout_residual` does it on a stacked regressor; :func:`cross_validate` identifies an
:class:`~rfsw_plan.elastostatics.model.ElastostaticModel` on measurement samples and scores it
the same way, in blocks of samples when the data has positions only
(:func:`~rfsw_plan.elastostatics.identification_blocks.heldout_steps`: same solution, memory
bounded on 10^6 samples).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from threadpoolctl import ThreadpoolController

from rfsw_plan.elastostatics.effects.base import Effect, FloatArray, PoseBatch
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

#: Relative Gauss-Newton step tolerance of the fits scored here (the held-out RMS does not
#: change in its 10th digit below it; identify's default 1e-10 costs ~40 % more iterations).
FIT_TOL = 1e-7
#: Gauss-Newton steps of each phase of a fit, at most (identify's default).
FIT_ITER = 30
#: Default number of folds.
DEFAULT_FOLDS = 5


def heldout_residual(
    A: FloatArray,
    r: FloatArray,
    fold: NDArray[np.int_],
    k: int | None = None,
    *,
    rcond: float | None = None,
    room: tuple[FloatArray, FloatArray] | None = None,
) -> FloatArray:
    """Held-out residual r_f - A_f d_f of every observation (module docstring).

    One QR factor of [A_f | r_f] per fold (column-normalised A); the training set of fold f is
    the stack of the other folds' small factors, so the k solves cost one pass over the rows
    (same solution as a least-squares solve on the training rows).

    Args:
        A: Jacobian of the prediction at theta*, shape (N, p).
        r: Residual (measured - predicted) at theta* [m], shape (N,).
        fold: Fold of every observation, 0..k-1, shape (N,).
        k: Number of folds (default: fold.max() + 1).
        rcond: Relative cut-off of small singular values of the column-normalised training
            regressor (numpy's default when None).
        room: (lower - theta*, upper - theta*): each step is clipped to it, so a held-out
            prediction never uses a non-physical parameter (default: no bound).

    Returns:
        Held-out residual [m], shape (N,).
    """
    k = int(fold.max()) + 1 if k is None else k
    held = np.empty_like(r)
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    An = A / scale
    n_col = An.shape[1]
    blocks = []
    for f in range(k):
        sel = fold == f
        # R of [A_f | r_f] holds R_f and Q_f^T r_f without forming Q_f.
        Ra = np.asarray(np.linalg.qr(np.column_stack([An[sel], r[sel]]), mode="r"))
        Ra = np.vstack([Ra, np.zeros((max(n_col + 1 - Ra.shape[0], 0), n_col + 1))])
        blocks.append((Ra[:n_col, :n_col], Ra[:n_col, n_col]))
    for f in range(k):
        R_tr = np.concatenate([b[0] for g, b in enumerate(blocks) if g != f])
        c_tr = np.concatenate([b[1] for g, b in enumerate(blocks) if g != f])
        step = np.linalg.lstsq(R_tr, c_tr, rcond=rcond)[0] / scale
        if room is not None:
            step = np.clip(step, room[0], room[1])
        te = fold == f
        held[te] = r[te] - A[te] @ step
    return held


def single_thread_numpy_blas(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Run ``fn`` with numpy's BLAS on one thread.

    The least-squares problems here are tall and skinny (3 m rows, tens of columns): a second
    OpenBLAS thread gains little and, on a loaded machine, spins against the other's work. With
    one thread ``validate`` on 10^4 samples with two hidden effects took 60 s instead of 161 s
    on this 2-core machine at a load average of 9-10 (same run; verdicts identical).
    """

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        if _ONE_THREAD["depth"]:  # already limited by a caller: no second library scan
            return fn(*args, **kwargs)
        _ONE_THREAD["depth"] += 1
        try:
            with _controller().limit(limits=1, user_api="blas"):
                return fn(*args, **kwargs)
        finally:
            _ONE_THREAD["depth"] -= 1

    return wrapper


#: Nesting depth of :func:`single_thread_numpy_blas` calls (the limit is set once, outermost).
_ONE_THREAD = {"depth": 0}


@functools.cache
def _controller() -> ThreadpoolController:
    """The loaded BLAS libraries, found once (each ``threadpool_limits`` call re-reads the
    process's memory map: 15 ms, 100 times in one ``validate``)."""
    return ThreadpoolController()


def make_folds(data: MeasurementSet, k: int, seed: int = 0) -> NDArray[np.int_]:
    """Fold index 0..k-1 of every sample, grouped by pose, shape (m,).

    A pose is a ``pose_id`` when the file has one, else a distinct joint vector (to 1e-6 rad),
    so repeated samples and the loads of one pose stay in the same fold.

    Raises:
        InputError: k < 2.
        IdentificationError: Fewer distinct poses than folds.
    """
    if k < 2:
        raise InputError("folds", "", f"{k}", "at least 2 folds")
    if data.pose_id is not None:
        _, groups = np.unique(data.pose_id, return_inverse=True)
    else:
        _, groups = np.unique(np.round(data.q / 1e-6), axis=0, return_inverse=True)
    groups = np.asarray(groups).reshape(-1)
    n_groups = int(groups.max()) + 1 if groups.size else 0
    if n_groups < k:
        raise IdentificationError(
            f"{data.source}: {n_groups} distinct poses cannot be split into {k} folds; need at "
            f"least {k} poses (use `folds` {max(n_groups, 2)} or measure more poses)"
        )
    order = np.random.default_rng(seed).permutation(n_groups)
    fold_of_group = np.empty(n_groups, dtype=np.int_)
    fold_of_group[order] = np.arange(n_groups) % k
    return fold_of_group[groups]


@dataclass(frozen=True)
class Indeterminate:
    """Samples whose state of one effect nothing before them in the data sets (the side of a
    joint's play before the first motion or load that sets it): a state of the campaign, not
    a parameter of the robot.

    The held-out score never reads that state from the held-out samples themselves: each is
    scored against the model's own prediction for it, the segment centre +- the effect's
    :meth:`~rfsw_plan.elastostatics.effects.base.Effect.state_spread` (+-b/2 of a play along
    its joint's motion), with the width fitted on the training folds; its residual is the
    distance to that segment.

    Attributes:
        label: The effect.
        rows: The samples, shape (n,).
        poses: Their pose ids (or rows ``#i`` without a pose column), in file order.
        reason: Why their state is unknown, in words.
        advice: How a campaign avoids them, in words.
    """

    label: str
    rows: NDArray[np.int_] = field(repr=False, compare=False)
    poses: tuple[str, ...]
    reason: str
    advice: str = ""

    @property
    def count(self) -> int:
        """Number of samples."""
        return int(self.rows.size)

    def line(self) -> str:
        """One line for the terminal."""
        where = ", ".join(self.poses[:4]) + (" ..." if len(self.poses) > 4 else "")
        return (f"{self.count} reading(s) at pose {where} scored against {self.label}'s "
                f"stated spread (+-b/2), not fitted to their own side: {self.reason}")

    def to_json(self) -> dict[str, Any]:
        """JSON form."""
        return {"effect": self.label, "readings": self.count, "poses": list(self.poses),
                "reason": self.reason, "treatment": "scored against the model's +-b/2 spread",
                "advice": self.advice}


def unknown_states(model: ElastostaticModel, data: MeasurementSet, batch: PoseBatch
                   ) -> list[tuple[int, NDArray[np.bool_]]]:
    """(index of the effect in ``model.effects``, its samples of unknown state, shape (m,))
    for every effect of ``model`` with such samples
    (:meth:`~rfsw_plan.elastostatics.effects.base.Effect.unknown_state`)."""
    if not any(type(e).unknown_state is not Effect.unknown_state for e in model.effects):
        return []
    F = model.true_wrench(batch, data.wrench)
    out = []
    for i, e in enumerate(model.effects):
        u = e.unknown_state(batch, F)
        if u is not None and bool(np.any(u)):
            out.append((i, np.asarray(u, dtype=bool)))
    return out


def _banded(model: ElastostaticModel, data: MeasurementSet, batch: PoseBatch,
            folds: NDArray[np.int_], idx: NDArray[np.int_], steps: FloatArray,
            unknown: list[tuple[int, NDArray[np.bool_]]],
            ) -> tuple[NDArray[np.int_], FloatArray, FloatArray]:
    """(rows of unknown state, their held-out residual [m] (n, 3), its distance to the
    segment centre +- spread of each effect's unknown state [m] (n, 3)); zero where not
    measured. The spread of fold f is the effect's at theta* + d_f (the training fit)."""
    rows = np.flatnonzero(np.any([u for _, u in unknown], axis=0))
    meas = data.measured[rows]
    held = np.zeros((rows.size, 3))
    for s, r in heldout_blocks(model, data.subset(rows), batch.rows(rows), folds[rows], idx,
                               steps):
        view = held[s]
        view[meas[s]] = r
    out = held.copy()
    theta = np.concatenate([e.params for e in model.effects])
    offs = np.cumsum([0] + [e.params.size for e in model.effects])
    fo = folds[rows]
    for f in np.unique(fo):
        th = theta.copy()
        th[idx] += steps[f]
        sel = fo == f
        sub = batch.rows(rows[sel])
        for i, u in unknown:
            v = (model.effects[i].state_spread(sub, th[offs[i]:offs[i + 1]])
                 * meas[sel] * u[rows[sel]][:, None])
            vv = np.einsum("ma,ma->m", v, v)
            t = np.einsum("ma,ma->m", out[sel], v) / np.where(vv > 0, vv, 1.0)
            out[sel] = out[sel] - v * np.clip(t, -1.0, 1.0)[:, None]
    return rows, held, out


def _indeterminate(model: ElastostaticModel, data: MeasurementSet,
                   unknown: list[tuple[int, NDArray[np.bool_]]]) -> tuple[Indeterminate, ...]:
    """What :class:`Indeterminate` says of each effect's samples of unknown state."""
    out = []
    for i, u in unknown:
        e = model.effects[i]
        rows = np.flatnonzero(u)
        poses = ([str(p) for p in data.pose_id[rows]] if data.pose_id is not None
                 else [f"#{r + 1}" for r in rows])
        out.append(Indeterminate(e.label, rows, tuple(dict.fromkeys(poses)),
                                 e.unknown_state_reason(), e.unknown_state_advice()))
    return tuple(out)


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
    #: Identified columns and per-fold steps of a fit in blocks (what :func:`attach` needs to
    #: evaluate the held-out residual again); None for a stacked fit (residual computed).
    cols: NDArray[np.int_] | None = field(default=None, repr=False, compare=False)
    steps: FloatArray | None = field(default=None, repr=False, compare=False)
    #: Samples of unknown state (:func:`unknown_states`), scored against the model's spread.
    indeterminate: tuple[Indeterminate, ...] = field(default=(), compare=False)
    #: (rows, their held-out residual to the segment of their unknown state [m], (n, 3)):
    #: what :attr:`heldout_residual` holds for them.
    band: tuple[NDArray[np.int_], FloatArray] | None = field(default=None, repr=False,
                                                            compare=False)

    @property
    def heldout_residual(self) -> FloatArray:
        """Residual of every sample predicted by the fit of the other folds [m], base frame,
        shape (m, 3); NaN = not measured. Computed on first use (one more pass over the
        samples: a candidate's score needs only :attr:`sse`)."""
        if "r" not in self._cache:
            self._cache["r"] = self.residual_of()
        return self._cache["r"]


def profiled(model: ElastostaticModel, data: MeasurementSet, batch: PoseBatch
             ) -> ElastostaticModel:
    """``model`` with the effects' profiled parameters (a friction threshold: no regressor)
    set from the residual of the model without each such effect
    (:meth:`~rfsw_plan.elastostatics.effects.base.Effect.profile`); ``model`` itself when it
    has none. The other parameters are then fitted as usual."""
    if not any(e.profiled_params for e in model.effects):
        return model
    out = model.copy()
    F = out.true_wrench(batch, data.wrench)
    mask = data.measured
    for e in out.effects:
        if e.profiled_params:
            without = ElastostaticModel(out.robot, [x for x in out.effects if x is not e])
            pred = batch.T[:, :3, 3] + without.deflection_batch(batch, data.wrench)[:, :3]
            e.profile(batch, F, np.where(mask, data.position - pred, 0.0))
    return out


def min_samples(n_params: int, data: MeasurementSet, k: int) -> int:
    """Samples needed so that every training fold has more observations than parameters."""
    per_sample = max(float(data.measured.sum()) / max(len(data), 1), 1.0)
    return int(np.ceil((n_params + 1) / per_sample * k / (k - 1))) + k


@single_thread_numpy_blas
def cross_validate(
    model: ElastostaticModel,
    data: MeasurementSet,
    folds: NDArray[np.int_],
    batch: PoseBatch | None = None,
    steps: int | None = None,
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
        steps: None: the fit converges from the model's parameters (its priors). A number:
            those parameters are a fit (the current model's in a forward selection, the
            candidate at its prior), and a model nonlinear in its parameters takes that many
            Gauss-Newton steps from them, its decisions (positive compliances, plausible
            values) from the first
            (:func:`~rfsw_plan.elastostatics.identification_blocks.identify_blocks`'s
            ``start``).

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
    model = profiled(model, data, batch)
    if data.rotation is not None:
        return _cross_validate_stacked(model, data, folds, batch, min_train)
    try:
        start = None if steps is None else np.concatenate([e.params for e in model.effects])
        bf = identify_blocks(model, data, batch, folds, tol=FIT_TOL, start=start,
                             max_iter=FIT_ITER if steps is None else steps)
    finally:
        forget_block_caches(batch)
    fit = bf.result
    idx = np.flatnonzero([e.identified for e in fit.estimates])
    _check_trainable(data, fit, idx.size, min_train, k)
    fold_steps, sse = heldout_steps(bf.factors, idx)
    n_obs = int(mask.sum())
    unknown = unknown_states(fit.model, data, batch)
    band = None
    if unknown:
        rows, held, to_segment = _banded(fit.model, data, batch, folds, idx, fold_steps, unknown)
        sse += float(np.sum(to_segment ** 2) - np.sum(held ** 2))
        band = (rows, to_segment)
    return CrossValidation(
        labels=tuple(fit.model.labels),
        fit=fit,
        heldout_rms=float(np.sqrt(sse / n_obs)),
        sse=sse,
        n_obs=n_obs,
        n_free=int(idx.size),
        residual_of=_block_residual(fit.model, data, batch, folds, idx, fold_steps, band),
        cols=idx,
        steps=fold_steps,
        indeterminate=_indeterminate(fit.model, data, unknown),
        band=band,
    )


def _block_residual(model: ElastostaticModel, data: MeasurementSet, batch: PoseBatch,
                    folds: NDArray[np.int_], idx: NDArray[np.int_], steps: FloatArray,
                    band: tuple[NDArray[np.int_], FloatArray] | None = None,
                    ) -> Callable[[], FloatArray]:
    """The held-out residual of a fit in blocks, evaluated when called [m], shape (m, 3)
    (the samples of unknown state: their distance to the model's segment, ``band``)."""
    mask = data.measured

    def residual_of() -> FloatArray:
        full = np.full(mask.shape, np.nan)
        try:
            for s, held in heldout_blocks(model, data, batch, folds, idx, steps):
                view = full[s]
                view[mask[s]] = held
        finally:
            forget_block_caches(batch)
        if band is not None:
            rows, to_segment = band
            full[rows] = np.where(mask[rows], to_segment, np.nan)
        return full

    return residual_of


def _detached() -> FloatArray:
    raise RuntimeError("a detached cross-validation needs attach() before its residual")


def detach(cv: CrossValidation) -> CrossValidation:
    """``cv`` without its lazily evaluated residual, so that it pickles (a worker process
    sends it back; :func:`attach` gives the residual back where the data is)."""
    return replace(cv, residual_of=_detached, _cache=dict(cv._cache))


def attach(cv: CrossValidation, data: MeasurementSet, batch: PoseBatch,
           folds: NDArray[np.int_]) -> CrossValidation:
    """A :func:`detach`-ed cross-validation of ``data`` (``batch``, ``folds``) with its
    held-out residual evaluable again."""
    if "r" in cv._cache or cv.cols is None or cv.steps is None:
        return cv
    return replace(cv, residual_of=_block_residual(cv.fit.model, data, batch, folds, cv.cols,
                                                   cv.steps, cv.band), _cache={})


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
    held = heldout_residual(A, r, obs_fold, k)
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
        residual_of=_detached,
        _cache={"r": full},
    )
