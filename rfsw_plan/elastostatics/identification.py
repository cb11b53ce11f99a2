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
from dataclasses import dataclass
from typing import Literal

import numpy as np

from rfsw_plan.elastostatics.effects import Effect, PoseBatch
from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import IdentificationError
from rfsw_plan.io.measurements import MeasurementSet

log = logging.getLogger(__name__)

#: A 100 % change of a parameter that moves the measured TCP by less than this RMS [m] is
#: taken as invisible in the data.
SENSITIVITY_FLOOR_M = 1e-9
#: Relative singular value below which normalised regressor columns are called collinear.
COLLINEARITY_TOL = 1e-7


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
    """Predicted loaded TCP positions for every sample [m], base frame, shape (m, 3)."""
    return model.predict_position(data.q, data.wrench)


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
    model: ElastostaticModel, batch: PoseBatch, wrench: FloatArray, effects: Sequence[Effect]
) -> FloatArray:
    """Stacked d(position)/d(theta) for the given effects, shape (m, 3, P): each effect's
    :meth:`~rfsw_plan.elastostatics.effects.base.Effect.pose_regressor` (wrench effects chain
    through the model's compliance, computed once)."""
    F_true = model.true_wrench(batch, wrench)
    through = model.wrench_to_pose()
    blocks = [e.pose_regressor(batch, wrench, F_true, through)[:, :3, :] for e in effects]
    return np.concatenate(blocks, axis=2)


def _set_theta(effects: Sequence[Effect], theta: FloatArray) -> None:
    i = 0
    for e in effects:
        p = e.params.size
        e.params = np.array(theta[i : i + p], dtype=float)
        i += p


def identify(
    model: ElastostaticModel,
    data: MeasurementSet,
    method: Literal["ols", "wls"] = "ols",
    free: Sequence[str] | None = None,
    max_iter: int = 30,
    tol: float = 1e-10,
) -> IdentificationResult:
    """Identify the parameters of ``free`` effects (all by default) from measured positions.

    Args:
        model: Starting model; its parameters are the priors. Not modified.
        data: Samples with joint values, logged wrench and measured TCP positions.
        method: ``ols`` (seed 000 eq. 15), or ``wls``: weights 1/sigma^2 from the file's
            ``sigma_mm`` column, or, without it, from the per-axis residual variance of a
            first OLS pass (feasible generalised least squares).
        free: Labels of the effects to identify; others keep their values.
        max_iter: Gauss-Newton iteration cap.
        tol: Convergence tolerance on the relative parameter step.

    Raises:
        IdentificationError: No measured axis, or fewer observations than free parameters.
    """
    if data.n_joints != model.robot.nq:
        raise IdentificationError(
            f"{data.source}: data has {data.n_joints} joints, robot {model.robot.name} has "
            f"{model.robot.nq}"
        )
    work = model.copy()
    labels = work.labels if free is None else list(free)
    unknown = [x for x in labels if not work.has(x)]
    if unknown:
        raise IdentificationError(f"effects not in the model: {', '.join(unknown)}")
    effects = [e for e in work.effects if e.label in labels]
    names = [(e.label, n) for e in effects for n in e.param_names()]
    prior = np.concatenate([e.params for e in effects])
    P = prior.size

    batch = work.batch(data.q)
    mask = data.measured  # (m, 3)
    n_obs = int(mask.sum())
    if n_obs == 0:
        raise IdentificationError(f"{data.source}: no measured TCP axis in any sample")
    if n_obs < P:
        raise IdentificationError(
            f"{data.source}: {n_obs} measured values cannot identify {P} parameters "
            f"({', '.join(labels)}); need at least {P} (better {3 * P})"
        )
    y = np.where(mask, data.position, 0.0)

    def model_pos() -> FloatArray:
        return batch.T[:, :3, 3] + work.deflection_batch(batch, data.wrench)[:, :3]

    rms_before = rms(np.where(mask, data.position - model_pos(), np.nan))

    # -- identifiability at the prior ---------------------------------------------------------
    A0 = position_jacobian(work, batch, data.wrench, effects)[mask]  # (n_obs, P)
    scale = np.where(np.abs(prior) > 0, np.abs(prior), 1.0)
    sens = np.sqrt(np.mean((A0 * scale) ** 2, axis=0))
    free_mask = np.ones(P, dtype=bool)
    notes = [""] * P
    for k in range(P):
        if sens[k] < SENSITIVITY_FLOOR_M:
            free_mask[k] = False
            notes[k] = (
                f"does not move the measured TCP (a 100 % change moves it {sens[k] * 1e9:.2g} nm "
                "RMS); e.g. a joint whose axis passes through the TCP is invisible to "
                "position-only data; prior kept"
            )
    while True:
        idx = np.nonzero(free_mask)[0]
        if idx.size == 0:
            break
        An = A0[:, idx] / np.linalg.norm(A0[:, idx], axis=0)
        _, sv, Vt = np.linalg.svd(An, full_matrices=False)
        if sv[-1] / sv[0] >= COLLINEARITY_TOL:
            break
        worst = idx[int(np.argmax(np.abs(Vt[-1])))]
        order = np.argsort(-np.abs(Vt[-1]))[1:3]
        partners = [f"{names[idx[j]][0]}.{names[idx[j]][1]}" for j in order]
        free_mask[worst] = False
        notes[worst] = (
            f"collinear with {', '.join(partners)} in this data (cannot be told apart); prior kept"
        )

    # -- weights ------------------------------------------------------------------------------
    w = np.ones(n_obs)
    if method == "wls" and data.sigma is not None:
        w = (1.0 / data.sigma[:, None] ** 2 * np.ones((1, 3)))[mask]
    elif method not in ("ols", "wls"):
        raise IdentificationError(f"unknown method '{method}'; known: ols, wls")

    # Positions are linear in theta when every free effect is a linear compliance or
    # geometric effect (the wrench effects, if any, stay fixed): one least-squares step.
    linear = all(e.pose_linear_in_params() for e in effects)

    def solve(weights: FloatArray) -> tuple[FloatArray, int, bool]:
        theta = np.concatenate([e.params for e in effects])
        idx = np.nonzero(free_mask)[0]
        it, conv = 0, False
        for it in range(1, max_iter + 1):  # noqa: B007 - it is returned
            r = (y - model_pos())[mask]
            A = position_jacobian(work, batch, data.wrench, effects)[mask][:, idx]
            sw = np.sqrt(weights)
            colscale = np.linalg.norm(A * sw[:, None], axis=0)
            colscale[colscale == 0] = 1.0
            step, *_ = np.linalg.lstsq((A * sw[:, None]) / colscale, r * sw, rcond=None)
            step /= colscale
            theta[idx] += step
            _set_theta(effects, theta)
            if linear or np.all(
                np.abs(step) <= tol * np.maximum(np.abs(theta[idx]), scale[idx])
            ):
                conv = True  # a model linear in theta is solved exactly by one step
                break
        return theta, it, conv

    theta, iterations, converged = solve(w)
    if method == "wls" and data.sigma is None:
        var_axis = axis_variances(np.where(mask, data.position - model_pos(), np.nan))
        w = (np.ones((len(data), 1)) / var_axis[None, :])[mask]
        theta, iterations, converged = solve(w)

    # -- physical plausibility: compliances must stay positive --------------------------------
    jc = work.joint_compliance
    if jc in effects:
        off = sum(e.params.size for e in effects[: effects.index(jc)])
        # Fixing one joint changes the others' estimates: repeat until all are positive.
        while True:
            neg = [off + j for j in range(jc.params.size)
                   if free_mask[off + j] and theta[off + j] <= 0]
            if not neg:
                break
            for k in neg:
                free_mask[k] = False
                notes[k] = f"estimate {theta[k]:.3g} rad/(N m) is not positive; prior kept"
                theta[k] = prior[k]
            _set_theta(effects, theta)
            theta, iterations, converged = solve(w)

    # -- uncertainty --------------------------------------------------------------------------
    res = (y - model_pos())[mask]
    idx = np.nonzero(free_mask)[0]
    dof = max(n_obs - idx.size, 1)
    sw = np.sqrt(w)
    s2 = float(np.sum(w * res**2) / dof)
    A = position_jacobian(work, batch, data.wrench, effects)[mask][:, idx]
    Aw = A * sw[:, None]
    std = np.full(P, np.nan)
    cond = float("nan")
    if idx.size:
        colscale = np.linalg.norm(Aw, axis=0)
        colscale[colscale == 0] = 1.0
        An = Aw / colscale
        cond = float(np.linalg.cond(An))
        cov_n = np.linalg.pinv(An.T @ An)
        std[idx] = np.sqrt(np.maximum(np.diag(cov_n), 0.0) * s2) / colscale
    sigma = float(np.sqrt(np.mean(res**2) * n_obs / dof))

    estimates = tuple(
        ParameterEstimate(
            effect=names[k][0], name=names[k][1], value=float(theta[k]), prior=float(prior[k]),
            std_error=float(std[k]), identified=bool(free_mask[k]),
            note=notes[k] or (
                "poorly determined: standard error exceeds the value"
                if free_mask[k] and std[k] > abs(theta[k]) else ""
            ),
        )
        for k in range(P)
    )
    c = work.joint_compliance.params
    k_std = np.full(c.size, np.nan)
    identified_j = np.ones(c.size, dtype=bool)
    if jc in effects:
        off = sum(e.params.size for e in effects[: effects.index(jc)])
        for j in range(c.size):
            identified_j[j] = bool(free_mask[off + j])
            k_std[j] = std[off + j] / c[j] ** 2
    else:
        identified_j[:] = False
    return IdentificationResult(
        model=work,
        estimates=estimates,
        stiffness=1.0 / c,
        stiffness_std=k_std,
        joint_identified=identified_j,
        condition_number=cond,
        rms_before=rms_before,
        rms_after=rms(np.where(mask, data.position - model_pos(), np.nan)),
        sigma=sigma,
        n_samples=len(data),
        n_observations=n_obs,
        iterations=iterations,
        converged=converged,
        method=method,
    )
