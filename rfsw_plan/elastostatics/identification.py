"""Identification of joint stiffness and effect parameters from measured TCP positions.

Observation model, per sample i and measured axis a (x, y, z, base frame):

    x_meas[i, a] = FK(q_i)[a] + dX(q_i, F_i; theta)[a] + noise

For the base model dX = W c is linear in the joint compliances c (seed 000 eq. 13-14, seed 001
eq. 8-9) and one ordinary least-squares step solves it (seed 000 eq. 15). With more effects the
model may be bilinear (payload gravity times compliance), so the solver is Gauss-Newton on the
stacked effect regressors; for a linear model it converges in one step.

Identifiability is checked before fitting: a parameter whose regressor column does not move
the measured TCP (joint 6 compliance when the TCP lies on the joint-6 axis and only positions
are measured), or that is collinear with others, keeps its prior and is reported with the
reason.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.effects import Effect, PoseBatch
from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import IdentificationError

log = logging.getLogger(__name__)

#: A 100 % change of a parameter that moves the measured TCP by less than this RMS [m] is
#: taken as invisible in the data.
SENSITIVITY_FLOOR_M = 1e-9
#: Relative singular value below which normalised regressor columns are called collinear.
COLLINEARITY_TOL = 1e-7
#: Passes that set the prior's weight of regularised parameters from the residual noise of
#: the previous pass (the first pass has no prior; the weight settles within a few passes).
PRIOR_PASSES = 3


@dataclass(frozen=True)
class ParameterEstimate:
    """One identified (or kept) parameter.

    Attributes:
        effect: Effect label, e.g. ``joint_compliance`` or ``tilting_compliance:j2``.
        name: Parameter name within the effect (``c3``).
        value: Estimate (or the kept prior) [SI].
        prior: Value before identification [SI].
        std_error: 1-sigma standard error [SI]; NaN if not identified.
        identified: False if the data could not identify it and the prior was kept.
        note: Why it was not identified, or a warning (empty if fine).
    """

    effect: str
    name: str
    value: float
    prior: float
    std_error: float
    identified: bool
    note: str = ""


@dataclass(frozen=True)
class IdentificationResult:
    """Outcome of :func:`identify`.

    Attributes:
        model: The model with the identified parameters.
        estimates: All parameters of the free effects, in regressor order.
        stiffness: Joint stiffness 1/c [N m/rad], shape (n,).
        stiffness_std: Standard error of the stiffness [N m/rad] (NaN if not identified).
        joint_identified: Whether each joint's compliance was identified, shape (n,).
        condition_number: Condition number of the column-normalised regressor.
        rms_before: RMS position residual with the prior model [m].
        rms_after: RMS position residual with the identified model [m].
        sigma: Estimated 1-sigma observation noise from the residual [m].
        n_samples: Number of samples used.
        n_observations: Number of scalar observations (measured axes).
        iterations: Gauss-Newton iterations.
        converged: True if the step fell below tolerance.
        method: ``ols`` or ``wls``.
    """

    model: ElastostaticModel
    estimates: tuple[ParameterEstimate, ...]
    stiffness: FloatArray
    stiffness_std: FloatArray
    joint_identified: np.ndarray
    condition_number: float
    rms_before: float
    rms_after: float
    sigma: float
    n_samples: int
    n_observations: int
    iterations: int
    converged: bool
    method: str

    def unidentified(self) -> list[ParameterEstimate]:
        """Parameters that kept their prior."""
        return [e for e in self.estimates if not e.identified]


def predicted_positions(model: ElastostaticModel, data: MeasurementSet) -> FloatArray:
    """Predicted loaded TCP positions for every sample [m], base frame, shape (m, 3), with the
    samples' history (:meth:`ElastostaticModel.batch_of`)."""
    batch = model.batch_of(data)
    out: FloatArray = batch.T[:, :3, 3] + model.deflection_batch(batch, data.wrench)[:, :3]
    return out


def residuals(model: ElastostaticModel, data: MeasurementSet) -> FloatArray:
    """Measured minus predicted TCP position [m], shape (m, 3); NaN where not measured."""
    return data.position - predicted_positions(model, data)


def rms(res: FloatArray) -> float:
    """RMS over the measured (finite) entries [m]."""
    r = res[np.isfinite(res)]
    return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")


def axis_variances(res: FloatArray) -> FloatArray:
    """Per-axis residual variance for the feasible-GLS weights of :func:`identify` [m^2].

    Mean square of the measured (finite) entries of each axis of ``res`` (m, 3). An axis
    without a measured entry, or whose residual is exactly zero, takes the largest positive
    variance of the other axes (its weight then does not exceed theirs); if no axis has a
    positive variance (an exact fit), every axis takes 1, i.e. equal weights as in OLS.

    Returns:
        Strictly positive variances, shape (3,).
    """
    measured = np.isfinite(res)
    count = measured.sum(axis=0)
    square = np.where(measured, res, 0.0) ** 2
    var = np.divide(square.sum(axis=0), count, out=np.zeros(res.shape[1]), where=count > 0)
    usable = var > 0
    if not usable.any():
        return np.ones(res.shape[1])
    return np.where(usable, var, var[usable].max())


def position_jacobian(
    model: ElastostaticModel, batch: PoseBatch, wrench: FloatArray, effects: Sequence[Effect],
    rows: int = 3,
) -> FloatArray:
    """Stacked d(position)/d(theta) for the given effects, shape (m, rows, P): each effect's
    :meth:`~rfsw_plan.elastostatics.effects.base.Effect.pose_regressor` (wrench effects chain
    through the model's compliance, computed once). ``rows=6`` adds the rotation rows."""
    F_true = model.true_wrench(batch, wrench)
    through = model.wrench_to_pose()
    blocks = [e.pose_regressor(batch, wrench, F_true, through)[:, :rows, :] for e in effects]
    return np.concatenate(blocks, axis=2)


def rotation_error(measured: FloatArray, nominal: FloatArray) -> FloatArray:
    """Rotation vector of R_meas R_nom^T [rad], shape (m, 3): measured rotation vectors
    (m, 3) against nominal rotation matrices (m, 3, 3), both in the base frame."""
    from scipy.spatial.transform import Rotation

    Rm = Rotation.from_rotvec(np.asarray(measured, dtype=float)).as_matrix()
    return np.asarray(Rotation.from_matrix(Rm @ np.swapaxes(nominal, 1, 2)).as_rotvec())


def set_theta(effects: Sequence[Effect], theta: FloatArray) -> None:
    i = 0
    for e in effects:
        p = e.params.size
        e.params = np.array(theta[i : i + p], dtype=float)
        i += p


@dataclass
class IdentificationProblem:
    """A built least-squares problem: what :func:`solve_identification` iterates on.

    Attributes:
        model: Working copy of the model; its free effects' parameters are updated in place.
        effects: The free effects, in regressor order.
        names: (effect label, parameter name) of every parameter, shape (P,).
        prior: Parameter values before identification, shape (P,).
        data: The samples.
        batch: Kinematics of ``data.q``.
        mask: Measured values, shape (m, 3), or (m, 6) with orientation rows.
        y: Measured positions with unmeasured axes zeroed [m], shape (m, 3); with orientation
            (m, 6), the rotation rows holding log(R_meas R_fk^T) [rad].
        free: Parameters the data can identify (the others keep their prior), shape (P,).
        notes: Why a parameter is not free (empty if free), shape (P,).
        scale: Parameter scales for the step tolerance [SI], shape (P,).
        linear: True if the positions are linear in the free parameters (one step solves).
        method: ``ols`` or ``wls``.
        rms_before: RMS position residual of the prior model [m].
        row_scale: Weight of each observation row, shape (mask.shape[1],): 1 for positions and
            sigma_position / sigma_rotation [m/rad] for orientation rows (their own noise
            level, estimated from the prior model's residual of each block).
        prior_weight: Weight of the Gaussian prior row w_k (theta_k - prior_k) = 0 of each
            parameter [m per SI unit], shape (P,) (0: none; see :attr:`Effect.regularised`),
            or None.
    """

    model: ElastostaticModel
    effects: list[Effect]
    names: list[tuple[str, str]]
    prior: FloatArray
    data: MeasurementSet
    batch: PoseBatch
    mask: np.ndarray
    y: FloatArray
    free: np.ndarray
    notes: list[str]
    scale: FloatArray
    linear: bool
    method: str
    rms_before: float
    row_scale: FloatArray = field(default_factory=lambda: np.ones(3))
    prior_weight: FloatArray | None = None

    @property
    def rows(self) -> int:
        """3 (positions) or 6 (positions and orientations)."""
        return int(self.mask.shape[1])

    @property
    def n_obs(self) -> int:
        """Number of measured scalar values."""
        return int(self.mask.sum())

    def predicted(self) -> FloatArray:
        """Predictions with the current parameters, shape (m, rows): TCP position [m] and,
        with orientation rows, the deflection's rotation [rad]."""
        dX = self.model.deflection_batch(self.batch, self.data.wrench)
        out = dX[:, : self.rows].copy()
        out[:, :3] += self.batch.T[:, :3, 3]
        return out

    def positions(self) -> FloatArray:
        """Predicted positions with the current parameters [m], shape (m, 3)."""
        return self.predicted()[:, :3]

    def residual(self) -> FloatArray:
        """Measured minus predicted, measured values only, weighted rows [m], (n_obs,)."""
        return ((self.y - self.predicted()) * self.row_scale)[self.mask]

    def jacobian(self) -> FloatArray:
        """d(prediction)/d(theta) of the measured values, weighted rows, shape (n_obs, P)."""
        A = position_jacobian(self.model, self.batch, self.data.wrench, self.effects,
                              self.rows)
        return (A * self.row_scale[None, :, None])[self.mask]

    def theta(self) -> FloatArray:
        """Current parameter vector, shape (P,)."""
        return np.concatenate([e.params for e in self.effects])

    def prior_system(self, idx: NDArray[np.int_]) -> tuple[FloatArray, FloatArray]:
        """The prior rows restricted to the columns ``idx``: (A (p, idx.size), r (p,)) with
        A = w_k e_k and r = w_k (prior_k - theta_k) [m]; empty without a prior."""
        w = np.zeros(self.prior.size) if self.prior_weight is None else self.prior_weight
        sel = np.flatnonzero(w > 0)
        A = np.zeros((sel.size, self.prior.size))
        A[np.arange(sel.size), sel] = w[sel]
        return A[:, idx], w[sel] * (self.prior[sel] - self.theta()[sel])


def mark_invisible(
    names: Sequence[tuple[str, str]], free: np.ndarray, notes: list[str], scale: FloatArray,
    A0: FloatArray, n_rows: int,
) -> None:
    """Parameters whose 100 % change does not move the measured point keep their prior.

    Args:
        names: (effect label, parameter name) of every column.
        free: Free flags, updated in place, shape (P,).
        notes: Notes, updated in place.
        scale: Parameter scales [SI], shape (P,).
        A0: The regressor, or any matrix with the same column norms (its R factor).
        n_rows: Rows of the regressor (the norms are turned into RMS over them).
    """
    sens = np.sqrt(np.sum((A0 * scale) ** 2, axis=0) / max(n_rows, 1))
    for k in np.flatnonzero(sens < SENSITIVITY_FLOOR_M):
        free[k] = False
        moved = ("not at all (below 1e-6 nm, rounding only)" if sens[k] < 1e-15
                 else f"{sens[k] * 1e9:.2g} nm RMS")
        notes[k] = (
            f"does not move the measured TCP (a 100 % change moves it {moved}, below "
            f"{SENSITIVITY_FLOOR_M * 1e9:.3g} nm); e.g. a joint whose axis passes through the "
            "TCP is invisible to position-only data; prior kept"
        )


def keep_profiled(effects: Sequence[Effect], free: np.ndarray, notes: list[str]) -> None:
    """The effects' :attr:`~rfsw_plan.elastostatics.effects.base.Effect.profiled_params` (set
    by :meth:`~rfsw_plan.elastostatics.effects.base.Effect.profile`, no regressor) stay fixed,
    without a note. ``free`` and ``notes`` (one per parameter, in the effects' order) are
    updated in place."""
    flags = [n in e.profiled_params for e in effects for n in e.param_names()]
    for k in np.flatnonzero(flags):
        free[k] = False
        notes[k] = ""


def mark_collinear(
    names: Sequence[tuple[str, str]], free: np.ndarray, notes: list[str], setup: np.ndarray,
    A0: FloatArray, first: np.ndarray | None = None,
) -> None:
    """Drop parameters, one at a time, until the free columns are not collinear.

    A measurement set-up parameter (``setup[k]``, :attr:`Effect.setup`: device registration,
    marker offset) is never the one dropped: a joint offset that a free registration absorbs
    is named as unidentifiable instead. Parameters flagged in ``first`` (those of a
    regularised full parameter set, :attr:`Effect.regularised`) go before any other: a link's
    rotation about its joint axis is named as the joint offset's, not the reverse. ``A0`` is
    the regressor or any matrix with the same Gram matrix (its R factor); ``free`` and
    ``notes`` are updated in place.
    """
    while True:
        idx = np.flatnonzero(free)
        if idx.size == 0:
            return
        An = A0[:, idx] / np.linalg.norm(A0[:, idx], axis=0)
        _, sv, Vt = np.linalg.svd(An, full_matrices=False)
        if sv[-1] / sv[0] >= COLLINEARITY_TOL:
            return
        weight = np.abs(Vt[-1]) * np.where(setup[idx], 0.0, 1.0)
        if first is not None and np.any(weight[first[idx]] > 1e-3):
            weight = weight * np.where(first[idx], 1.0, 0.0)
        if not weight.any():
            weight = np.abs(Vt[-1])
        worst = idx[int(np.argmax(weight))]
        order = [j for j in np.argsort(-np.abs(Vt[-1])) if idx[j] != worst][:2]
        partners = [f"{names[idx[j]][0]}.{names[idx[j]][1]}" for j in order]
        # Multiple correlation of the dropped column with all the other free ones.
        w_col = int(np.flatnonzero(idx == worst)[0])
        rest = np.delete(An, w_col, axis=1)
        res = An[:, w_col] - rest @ np.linalg.lstsq(rest, An[:, w_col], rcond=None)[0]
        corr = float(np.sqrt(max(0.0, 1.0 - float(res @ res))))
        free[worst] = False
        why = ("a free device registration absorbs it" if any(setup[idx[j]] for j in order)
               else "cannot be told apart in this data")
        notes[worst] = (f"collinear with {', '.join(partners)} ({why}; multiple correlation "
                        f"|r| = {corr:.6f}, condition ratio {sv[-1] / sv[0]:.2g}); not fitted")


@dataclass(frozen=True)
class Plausibility:
    """What a real robot plausibly shows, per parameter in regressor order [SI], shape (P,).

    Attributes:
        limit: Largest plausible |value| (:attr:`Effect.plausible_limits`), inf if none.
        lo: Lower end of the physically possible range (:attr:`Effect.param_ranges`).
        hi: Upper end of it.
    """

    limit: FloatArray
    lo: FloatArray
    hi: FloatArray
    regularised: NDArray[np.bool_]

    @classmethod
    def of(cls, effects: Sequence[Effect]) -> Plausibility:
        """The bounds of the parameters of ``effects``."""
        lim = [e.plausible_limit(n) for e in effects for n in e.param_names()]
        rng = np.array([e.param_range(n) for e in effects for n in e.param_names()],
                       dtype=float).reshape(-1, 2)
        limit = np.array([np.inf if x is None else x for x in lim], dtype=float)
        reg = np.array([e.regularised for e in effects for _ in e.param_names()], dtype=bool)
        return cls(limit, rng[:, 0], rng[:, 1], reg & np.isfinite(limit))

    def prior_weights(self, sigma_obs: float) -> FloatArray:
        """Weight of each parameter's prior row w_k (theta_k - prior_k) = 0 against
        observations of noise ``sigma_obs`` [m]: sigma_obs / (L_k / 2) for the regularised
        parameters, 0 for the others, shape (P,)."""
        return np.where(self.regularised, sigma_obs / (self.limit / 2), 0.0)


def implausible(
    theta: FloatArray, std: FloatArray, free: np.ndarray, bounds: Plausibility,
) -> tuple[int, str] | None:
    """The free parameter the data does not plausibly identify, worst first, or None.

    An estimate outside its physically possible range (a negative compliance) goes first. A
    parameter with a plausible size L (:attr:`Effect.plausible_limits`) is kept only if its
    standard error is below L / 2 (its 95 % interval is narrower than the plausible range:
    the data tells it apart from zero better than prior knowledge does) and its estimate is
    within L (a 6 mm link error is not a calibration; a joint 1000x softer than any gear
    stands in for another effect). Of those, the worst max(std / (L/2), |value| / L) goes.

    Returns:
        (index, note) of the parameter to hold at its prior, or None.
    """
    out = np.flatnonzero(free & ((theta < bounds.lo) | (theta > bounds.hi)))
    if out.size:
        k = int(out[0])
        return k, (f"estimate {theta[k]:.3g} is outside the physically possible "
                   f"[{bounds.lo[k]:.3g}, {bounds.hi[k]:.3g}] (SI); prior kept")
    idx = np.flatnonzero(free & np.isfinite(bounds.limit))
    if idx.size == 0:
        return None
    lim = bounds.limit[idx]
    # A regularised parameter's error is bounded by its prior: only its value is checked.
    by_std = np.where(bounds.regularised[idx], 0.0,
                      np.nan_to_num(std[idx] / (lim / 2), nan=np.inf))
    by_value = np.abs(theta[idx]) / lim
    score = np.maximum(by_std, by_value)
    j = int(np.argmax(score))
    if score[j] <= 1.0:
        return None
    k = int(idx[j])
    if by_value[j] >= by_std[j]:
        return k, (f"estimate {theta[k]:.3g} is beyond the plausible {lim[j]:.3g} (SI): not "
                   "a calibration but a stand-in for another effect; prior kept")
    return k, (f"standard error {std[k]:.2g} exceeds half the plausible size {lim[j]:.3g} "
               "(SI): this data cannot tell it from zero; prior kept")


def _add_orientation(prob: IdentificationProblem) -> None:
    """Extend the problem with the measured tool orientation (issue 12 §1).

    The rotation rows compare log(R_meas R_fk^T) with the predicted deflection rotation; they
    are weighted by sigma_position / sigma_rotation, both estimated from the prior model's
    residual of each block (each block with its own noise level).
    """
    data = prob.data
    assert data.rotation is not None
    y_rot = rotation_error(data.rotation, prob.batch.T[:, :3, :3])
    pos_mask = prob.mask
    prob.mask = np.concatenate([pos_mask, np.isfinite(y_rot)], axis=1)
    prob.y = np.concatenate([prob.y, np.where(np.isfinite(y_rot), y_rot, 0.0)], axis=1)
    prob.row_scale = np.ones(6)
    r0 = prob.y - prob.predicted()
    s_pos = float(np.sqrt(np.mean(r0[:, :3][pos_mask] ** 2))) if pos_mask.any() else 0.0
    s_rot = float(np.sqrt(np.mean(r0[:, 3:][prob.mask[:, 3:]] ** 2)))
    if s_pos > 0 and s_rot > 0:
        prob.row_scale[3:] = s_pos / s_rot


def build_identification(
    model: ElastostaticModel,
    data: MeasurementSet,
    method: Literal["ols", "wls"] = "ols",
    free: Sequence[str] | None = None,
) -> IdentificationProblem:
    """Set up the least-squares problem and decide which parameters the data can identify.

    Args:
        model: Starting model; its parameters are the priors. Not modified.
        data: Samples with joint values, logged wrench and measured positions (base frame).
        method: ``ols`` or ``wls`` (see :func:`identify`).
        free: Labels of the effects to identify; None frees all.

    Raises:
        IdentificationError: Joint count mismatch, unknown effect, no measured axis, fewer
            observations than parameters, unknown method.
    """
    if data.n_joints != model.robot.nq:
        raise IdentificationError(
            f"{data.source}: data has {data.n_joints} joints, robot {model.robot.name} has "
            f"{model.robot.nq}"
        )
    if method not in ("ols", "wls"):
        raise IdentificationError(f"unknown method '{method}'; known: ols, wls")
    work = model.copy()
    labels = work.labels if free is None else list(free)
    unknown = [x for x in labels if not work.has(x)]
    if unknown:
        raise IdentificationError(f"effects not in the model: {', '.join(unknown)}")
    effects = [e for e in work.effects if e.label in labels]
    names = [(e.label, n) for e in effects for n in e.param_names()]
    prior = np.concatenate([e.params for e in effects])
    mask = data.measured
    n_obs = int(mask.sum())
    if n_obs == 0:
        raise IdentificationError(f"{data.source}: no measured TCP axis in any sample")
    if n_obs < prior.size:
        raise IdentificationError(
            f"{data.source}: {n_obs} measured values cannot identify {prior.size} parameters "
            f"({', '.join(labels)}); need at least {prior.size} (better {3 * prior.size})"
        )
    batch = work.batch_of(data)
    # Positions are linear in theta when every free effect is a linear compliance or
    # geometric effect (the wrench effects, if any, stay fixed): one least-squares step.
    linear = all(e.pose_linear_in_params() for e in effects)
    prob = IdentificationProblem(
        model=work, effects=effects, names=names, prior=prior, data=data, batch=batch,
        mask=mask, y=np.where(mask, data.position, 0.0), free=np.ones(prior.size, dtype=bool),
        notes=[""] * prior.size, scale=np.where(np.abs(prior) > 0, np.abs(prior), 1.0),
        linear=linear, method=method, rms_before=float("nan"),
    )
    prob.rms_before = rms(np.where(mask, data.position - prob.positions(), np.nan))
    if data.rotation is not None:
        _add_orientation(prob)
    A0 = prob.jacobian()
    if not np.all(np.isfinite(A0)):
        raise IdentificationError(f"{data.source}: the regressor is not finite (values out "
                                  "of range in the data?)")
    mark_invisible(prob.names, prob.free, prob.notes, prob.scale, A0, A0.shape[0])
    setup = np.array([any(e.label == lab and e.setup for e in prob.effects)
                      for lab, _ in prob.names], dtype=bool)
    mark_collinear(prob.names, prob.free, prob.notes, setup, A0,
                   Plausibility.of(prob.effects).regularised)
    keep_profiled(prob.effects, prob.free, prob.notes)
    return prob


def _gauss_newton(
    prob: IdentificationProblem, weights: FloatArray, max_iter: int, tol: float
) -> tuple[int, bool]:
    """Iterate weighted Gauss-Newton on the free parameters; returns (iterations, converged)."""
    theta = prob.theta()
    idx = np.flatnonzero(prob.free)
    sw = np.sqrt(weights)
    it, conv = 0, False
    for it in range(1, max_iter + 1):  # noqa: B007 - it is returned
        Ap, rp = prob.prior_system(idx)
        A = np.vstack([prob.jacobian()[:, idx] * sw[:, None], Ap])
        colscale = np.linalg.norm(A, axis=0)
        colscale[colscale == 0] = 1.0
        try:
            step, *_ = np.linalg.lstsq(A / colscale, np.concatenate([prob.residual() * sw, rp]),
                                       rcond=None)
        except np.linalg.LinAlgError as exc:
            raise IdentificationError(f"{prob.data.source}: least squares failed ({exc})") from None
        step /= colscale
        theta[idx] += step
        set_theta(prob.effects, theta)
        if prob.linear or np.all(
            np.abs(step) <= tol * np.maximum(np.abs(theta[idx]), prob.scale[idx])
        ):
            conv = True  # a model linear in theta is solved exactly by one step
            break
    return it, conv


def solve_identification(
    prob: IdentificationProblem, max_iter: int = 30, tol: float = 1e-10,
    plausibility: bool = True,
) -> IdentificationResult:
    """Solve a built problem (:func:`build_identification`) and estimate the uncertainties.

    With ``plausibility`` (the default) a parameter outside its physical range, beyond its
    plausible size or with a standard error above half of it keeps its prior
    (:func:`implausible`); without, only the compliances' positivity is enforced (to see
    what an unconstrained fit would make of the data, e.g. how soft a joint it wants).

    Raises:
        IdentificationError: The solve produced non-finite numbers.
    """
    data, mask = prob.data, prob.mask
    n_obs = prob.n_obs
    w = np.ones(n_obs)
    if prob.method == "wls" and data.sigma is not None:
        w = (1.0 / data.sigma[:, None] ** 2 * np.ones((1, prob.rows)))[mask]
    iterations, converged = _gauss_newton(prob, w, max_iter, tol)
    if prob.method == "wls" and data.sigma is None:
        res0 = (prob.y - prob.predicted()) * prob.row_scale
        var_axis = axis_variances(np.where(mask, res0, np.nan))
        w = (np.ones((len(data), 1)) / var_axis[None, :])[mask]
        iterations, converged = _gauss_newton(prob, w, max_iter, tol)

    # -- physical plausibility: compliances must stay positive --------------------------------
    jc = prob.model.joint_compliance
    theta = prob.theta()
    if jc in prob.effects:
        off = sum(e.params.size for e in prob.effects[: prob.effects.index(jc)])
        # Fixing one joint changes the others' estimates: repeat until all are positive.
        while True:
            neg = [off + j for j in range(jc.params.size)
                   if prob.free[off + j] and theta[off + j] <= 0]
            if not neg:
                break
            for k in neg:
                prob.free[k] = False
                prob.notes[k] = f"estimate {theta[k]:.3g} rad/(N m) is not positive; prior kept"
                theta[k] = prob.prior[k]
            set_theta(prob.effects, theta)
            iterations, converged = _gauss_newton(prob, w, max_iter, tol)
            theta = prob.theta()
    if not np.all(np.isfinite(theta)):
        raise IdentificationError(f"{data.source}: the fit did not give finite parameters "
                                  "(values out of range in the data?)")

    # -- uncertainty, and what the data plausibly identifies ---------------------------------
    bounds = Plausibility.of(prob.effects)
    if bounds.regularised.any():  # the prior's weight against the observations' noise
        for _ in range(PRIOR_PASSES):
            res = prob.residual()
            prob.prior_weight = bounds.prior_weights(
                float(np.sqrt(np.sum(w * res**2) / max(n_obs - int(prob.free.sum()), 1))))
            iterations, converged = _gauss_newton(prob, w, max_iter, tol)
        theta = prob.theta()
    std, cond = _standard_errors(prob, w)
    while plausibility and (drop := implausible(theta, std, prob.free, bounds)) is not None:
        k, prob.notes[k] = drop
        prob.free[k] = False
        theta[k] = prob.prior[k]
        set_theta(prob.effects, theta)
        iterations, converged = _gauss_newton(prob, w, max_iter, tol)
        theta = prob.theta()
        std, cond = _standard_errors(prob, w)
    res = prob.residual()
    dof = max(n_obs - int(prob.free.sum()), 1)
    sigma = float(np.sqrt(np.mean(res**2) * n_obs / dof))
    return build_result(
        model=prob.model, effects=prob.effects, names=prob.names, prior=prob.prior,
        theta=theta, free=prob.free, notes=prob.notes, std=std, cond=cond,
        rms_before=prob.rms_before,
        rms_after=rms(np.where(mask[:, :3], data.position - prob.positions(), np.nan)),
        sigma=sigma, n_samples=len(data), n_obs=n_obs, iterations=iterations,
        converged=converged, method=prob.method,
    )


def _standard_errors(prob: IdentificationProblem, w: FloatArray) -> tuple[FloatArray, float]:
    """1-sigma standard errors of the free parameters (NaN for the others) [SI], shape (P,),
    and the condition number of the column-normalised weighted regressor."""
    res = prob.residual()
    idx = np.flatnonzero(prob.free)
    dof = max(prob.n_obs - idx.size, 1)
    sw = np.sqrt(w)
    s2 = float(np.sum(w * res**2) / dof)
    std = np.full(prob.prior.size, np.nan)
    if not idx.size:
        return std, float("nan")
    Aw = np.vstack([prob.jacobian()[:, idx] * sw[:, None], prob.prior_system(idx)[0]])
    colscale = np.linalg.norm(Aw, axis=0)
    colscale[colscale == 0] = 1.0
    An = Aw / colscale
    cov_n = np.linalg.pinv(An.T @ An)
    std[idx] = np.sqrt(np.maximum(np.diag(cov_n), 0.0) * s2) / colscale
    return std, float(np.linalg.cond(An))


def build_result(
    *, model: ElastostaticModel, effects: Sequence[Effect], names: Sequence[tuple[str, str]],
    prior: FloatArray, theta: FloatArray, free: np.ndarray, notes: Sequence[str],
    std: FloatArray, cond: float, rms_before: float, rms_after: float, sigma: float,
    n_samples: int, n_obs: int, iterations: int, converged: bool, method: str,
) -> IdentificationResult:
    """The typed result of a solved identification (estimates, stiffness and its error).

    Args:
        std: 1-sigma standard error of every parameter [SI] (NaN if not identified), (P,).
        Others: as in :class:`IdentificationResult` and :class:`IdentificationProblem`.
    """
    P = prior.size
    setup = {e.label for e in effects if e.setup}  # corrections about 0: no such note
    estimates = tuple(
        ParameterEstimate(
            effect=names[k][0], name=names[k][1], value=float(theta[k]),
            prior=float(prior[k]), std_error=float(std[k]), identified=bool(free[k]),
            note=notes[k] or (
                "poorly determined: standard error exceeds the value"
                if free[k] and std[k] > abs(theta[k]) and names[k][0] not in setup
                else ""
            ),
        )
        for k in range(P)
    )
    jc = model.joint_compliance
    c = jc.params
    k_std = np.full(c.size, np.nan)
    identified_j = np.zeros(c.size, dtype=bool)
    if jc in effects:
        off = sum(e.params.size for e in effects[: list(effects).index(jc)])
        identified_j = free[off: off + c.size].copy()
        k_std = std[off: off + c.size] / c**2
    return IdentificationResult(
        model=model,
        estimates=estimates,
        stiffness=1.0 / c,
        stiffness_std=k_std,
        joint_identified=identified_j,
        condition_number=cond,
        rms_before=rms_before,
        rms_after=rms_after,
        sigma=sigma,
        n_samples=n_samples,
        n_observations=n_obs,
        iterations=iterations,
        converged=converged,
        method=method,
    )


def identify(
    model: ElastostaticModel,
    data: MeasurementSet,
    method: Literal["ols", "wls"] = "ols",
    free: Sequence[str] | None = None,
    max_iter: int = 30,
    tol: float = 1e-10,
    plausibility: bool = True,
) -> IdentificationResult:
    """Identify the parameters of ``free`` effects (all by default) from measured positions.

    Build (:func:`build_identification`: regressors, identifiability) then solve
    (:func:`solve_identification`: Gauss-Newton, positivity, standard errors).

    Args:
        model: Starting model; its parameters are the priors. Not modified.
        data: Samples with joint values, logged wrench and measured TCP positions.
        method: ``ols`` (seed 000 eq. 15), or ``wls``: weights 1/sigma^2 from the file's
            ``sigma_mm`` column, or, without it, from the per-axis residual variance of a
            first OLS pass (feasible generalised least squares).
        free: Labels of the effects to identify; others keep their values.
        max_iter: Gauss-Newton iteration cap.
        tol: Convergence tolerance on the relative parameter step.
        plausibility: Hold implausible parameters at their prior (see
            :func:`solve_identification`).

    Raises:
        IdentificationError: No measured axis, or fewer observations than free parameters.
    """
    return solve_identification(build_identification(model, data, method, free), max_iter, tol,
                                plausibility)
