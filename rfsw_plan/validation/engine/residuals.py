"""Where the model fails: per-sample residual analysis and the noise floor.

The residual of sample i on measured axis a is ``r[i, a] = x_meas[i, a] - x_pred[i, a]``
(base frame [m]; NaN where the axis was not measured). This module summarises it (RMS, max,
percentiles, per axis, per direction, per joint), estimates the measurement noise floor, and
measures how much of the residual each candidate *feature* explains: time, every joint torque
tau = J^T F, every joint angle, the force magnitude and direction, the TCP position in the
workspace, and every extra numeric column of the measurement file (temperature...). A feature
that explains a large share of the residual points at the missing physics.

Feature test. For a feature with basis B (m, p) (standardised polynomial of degree 3 for a
scalar, quadratic for a vector), each measured axis is regressed on [1, B]; pooled over axes,

    R^2 = 1 - SSE / SST,   F = ((SST - SSE) / p_tot) / (SSE / (n - p_tot - n_axes)),

with SST the sum of squares about each axis mean. The p-value is that of the F statistic.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import special  # the distributions' tails (scipy.stats costs ~0.9 s more CPU to import)

from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch
from rfsw_plan.elastostatics.identification_blocks import predicted_positions
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError

AXES = ("x", "y", "z")
#: Percentiles of |r| reported [%].
PERCENTILES = (50.0, 90.0, 95.0, 99.0)
#: Samples are repeats of each other when their joint values agree to this [rad] ...
REPEAT_Q_TOL_RAD = 1e-4
#: ... and their forces to this [N] and moments to REPEAT_MOMENT_TOL_NM [N m].
REPEAT_FORCE_TOL_N = 5.0
REPEAT_MOMENT_TOL_NM = 1.0
#: Family-wise significance level of the feature tests (Bonferroni over the features).
FEATURE_ALPHA = 1e-3


@dataclass(frozen=True)
class NoiseFloor:
    """1-sigma noise of one measured position axis, in its two parts.

    The floor a model can reach is the measuring device's noise plus the force sensor's
    noise propagated through the model's compliance (a logged force off by dF moves the
    *predicted* TCP by C dF): sigma^2 = sigma_device^2 + sigma_force^2.

    Attributes:
        sigma: Total noise [m], or None when it cannot be estimated (no repeats, none given).
        source: ``given`` (--noise-mm), ``repeats`` (scatter of repeated samples), ``sigma
            column`` (the file's ``sigma_mm``) or ``none``.
        dof: Degrees of freedom of the estimate (inf when given).
        n_groups: Number of groups of repeated samples used (0 if none).
        repeats_sigma: The repeat-based estimate [m] when repeats exist, even if another
            source was used (for comparison), else None.
        device_sigma: The measuring device's part [m] (None if unknown).
        force_sigma: The force sensor's part [m]: its noise propagated through the compliance,
            RMS over the measured values (0 without force readings, None if unknown).
        force_noise: Force sensor noise per axis [N] (None if unknown).
        force_noise_source: ``given`` (--force-noise-N), ``zero-load readings``, ``no force
            sensor`` or ``unknown``.
    """

    sigma: float | None
    source: str
    dof: float
    n_groups: int = 0
    repeats_sigma: float | None = None
    device_sigma: float | None = None
    force_sigma: float | None = None
    force_noise: float | None = None
    force_noise_source: str = "unknown"

    @property
    def known(self) -> bool:
        """True if a noise level is available."""
        return self.sigma is not None

    def above(self, sse: float, n_obs: int) -> float:
        """p-value of ``SSE / n_obs`` being no larger than sigma^2 (one-sided).

        With a given sigma, SSE / sigma^2 ~ chi^2(n_obs); with a sigma estimated on ``dof``
        degrees of freedom, (SSE / n_obs) / sigma^2 ~ F(n_obs, dof). NaN if sigma is unknown.
        """
        if self.sigma is None or n_obs == 0:
            return float("nan")
        ratio = sse / n_obs / self.sigma**2
        if np.isinf(self.dof):
            return float(special.chdtrc(n_obs, ratio * n_obs))
        return float(special.fdtrc(n_obs, self.dof, ratio))


@dataclass(frozen=True)
class AxisStats:
    """Residual statistics of one axis or direction [m].

    Attributes:
        name: Axis or direction name.
        n: Number of values.
        rms: Root mean square.
        mean: Mean (a systematic offset when it is large against rms).
        max_abs: Largest absolute value.
    """

    name: str
    n: int
    rms: float
    mean: float
    max_abs: float


@dataclass(frozen=True)
class FeatureCorrelation:
    """How much of the residual one feature explains.

    Attributes:
        feature: Feature name (``time``, ``tau_j2``, ``q3``, ``force_magnitude``,
            ``force_direction``, ``tcp_position``, an extra column name, ``sample_order``).
        description: What the feature is, with unit.
        r2: Fraction of the residual variance (about each axis mean) explained, 0..1.
        adj_r2: R^2 adjusted for the number of basis functions.
        p_value: p-value of the F test against "explains nothing".
        significant: p_value below FEATURE_ALPHA / number of features.
    """

    feature: str
    description: str
    r2: float
    adj_r2: float
    p_value: float
    significant: bool


@dataclass(frozen=True)
class JointBreakdown:
    """Per-joint view of the residual.

    Attributes:
        joint: 1-based joint number.
        tau_min: Smallest joint torque in the data [N m].
        tau_max: Largest joint torque in the data [N m].
        r2_torque: Residual share explained by this joint's torque (cubic).
        r2_angle: Residual share explained by this joint's angle (cubic).
        r2_joint_motion: Residual share explained by an extra motion of this joint along its
            own Jacobian column, dX = J_j (a0 + a1 tau_j + a2 sign(tau_j)).
        rms_tau_pos: Residual RMS over samples with tau_j > 0 [m] (NaN if none).
        rms_tau_neg: Residual RMS over samples with tau_j < 0 [m] (NaN if none).
    """

    joint: int
    tau_min: float
    tau_max: float
    r2_torque: float
    r2_angle: float
    r2_joint_motion: float
    rms_tau_pos: float
    rms_tau_neg: float


@dataclass(frozen=True)
class ResidualAnalysis:
    """Everything :func:`analyze_residuals` found (SI units).

    Attributes:
        residual: Measured minus predicted TCP position [m], base frame, shape (m, 3); NaN =
            not measured.
        n_samples: Number of samples.
        n_observations: Number of measured axis values.
        rms: RMS over all measured values [m].
        max_abs: Largest absolute residual [m].
        percentiles: |r| percentiles [m] keyed by percent.
        norm_percentiles: Percentiles of the per-sample residual norm [m].
        per_axis: Statistics per base-frame axis x, y, z.
        per_direction: Statistics along and across the force direction (samples with all
            three axes measured and a non-zero force).
        per_joint: Per-joint breakdown.
        correlations: Feature tests, most explanatory (adjusted R^2) first.
        noise: The noise floor.
        features: Feature values used for the plots, each shape (m,) or (m, k).
        tcp: Nominal TCP position [m], base frame, shape (m, 3).
        tau: Joint torques J^T F of the logged wrench [N m], shape (m, n).
    """

    residual: FloatArray
    n_samples: int
    n_observations: int
    rms: float
    max_abs: float
    percentiles: dict[float, float]
    norm_percentiles: dict[float, float]
    per_axis: tuple[AxisStats, ...]
    per_direction: tuple[AxisStats, ...]
    per_joint: tuple[JointBreakdown, ...]
    correlations: tuple[FeatureCorrelation, ...]
    noise: NoiseFloor
    features: dict[str, FloatArray] = field(repr=False)
    tcp: FloatArray = field(repr=False)
    tau: FloatArray = field(repr=False)

    @property
    def rms_3d(self) -> float:
        """RMS over samples of the 3-D error norm [m] (samples measured in x, y and z), NaN
        if none is; equals sqrt(3) x :attr:`rms` when every axis is measured."""
        full = np.all(np.isfinite(self.residual), axis=1)
        if not full.any():
            return float("nan")
        return float(np.sqrt(np.mean(np.sum(self.residual[full] ** 2, axis=1))))

    def to_json(self) -> dict[str, Any]:
        """JSON-ready summary in mm (arrays left out)."""
        mm = 1e3
        return {
            "n_samples": self.n_samples,
            "n_observations": self.n_observations,
            "rms_mm": self.rms * mm,
            "rms_3d_mm": None if not np.isfinite(self.rms_3d) else self.rms_3d * mm,
            "max_abs_mm": self.max_abs * mm,
            "percentiles_mm": {f"p{p:g}": v * mm for p, v in self.percentiles.items()},
            "norm_percentiles_mm": {
                f"p{p:g}": v * mm for p, v in self.norm_percentiles.items()
            },
            "per_axis": [_axis_json(a) for a in self.per_axis],
            "per_direction": [_axis_json(a) for a in self.per_direction],
            "per_joint": [
                {
                    "joint": j.joint,
                    "tau_min_Nm": j.tau_min,
                    "tau_max_Nm": j.tau_max,
                    "r2_torque": j.r2_torque,
                    "r2_angle": j.r2_angle,
                    "r2_joint_motion": j.r2_joint_motion,
                    "rms_tau_pos_mm": j.rms_tau_pos * mm,
                    "rms_tau_neg_mm": j.rms_tau_neg * mm,
                }
                for j in self.per_joint
            ],
            "correlations": [correlation_json(c) for c in self.correlations],
            "noise": noise_json(self.noise),
        }


def _axis_json(a: AxisStats) -> dict[str, Any]:
    return {"name": a.name, "n": a.n, "rms_mm": a.rms * 1e3, "mean_mm": a.mean * 1e3,
            "max_abs_mm": a.max_abs * 1e3}


def correlation_json(c: FeatureCorrelation) -> dict[str, Any]:
    """JSON form of one feature test."""
    return {"feature": c.feature, "description": c.description, "r2": c.r2,
            "adj_r2": c.adj_r2, "p_value": c.p_value, "significant": c.significant}


def noise_json(n: NoiseFloor) -> dict[str, Any]:
    """JSON form of the noise floor (mm)."""
    return {
        "sigma_mm": None if n.sigma is None else n.sigma * 1e3,
        "source": n.source,
        "dof": None if np.isinf(n.dof) else n.dof,
        "n_groups": n.n_groups,
        "repeats_sigma_mm": None if n.repeats_sigma is None else n.repeats_sigma * 1e3,
        "device_sigma_mm": None if n.device_sigma is None else n.device_sigma * 1e3,
        "force_sigma_mm": None if n.force_sigma is None else n.force_sigma * 1e3,
        "force_noise_N": n.force_noise,
        "force_noise_source": n.force_noise_source,
    }


# --------------------------------------------------------------------------------------------
# Noise floor


def repeat_groups(data: MeasurementSet, force_tol_n: float = REPEAT_FORCE_TOL_N
                  ) -> NDArray[np.int_]:
    """Group index of every sample; samples in one group are repeats of each other.

    Repeats are samples of the same pose at the same load step *in sequence*: taken in time
    order (``t_s``, else file order), a sample joins the previous one's group when it has the
    same ``pose_id`` (when the file has one), joint values within REPEAT_Q_TOL_RAD, and the same
    ``load_step`` (when the file has one) or a wrench within ``force_tol_n`` [N] /
    REPEAT_MOMENT_TOL_NM of the previous one, and the same approach direction of every joint
    (:meth:`MeasurementSet.approach_directions`). Zero-load readings of one pose taken at
    different points of a load cycle (different hysteresis states), or reached from different
    directions (different flanks of a gear's play), are therefore never pooled.

    Returns:
        Group index per sample, shape (m,).
    """
    m = len(data)
    order = np.argsort(data.t, kind="stable") if data.t is not None else np.arange(m)
    if m == 0:
        return np.empty(0, dtype=np.int_)
    cur, prev = order[1:], order[:-1]  # every sample against the one before it in time
    same = np.all(np.abs(data.q[cur] - data.q[prev]) <= REPEAT_Q_TOL_RAD, axis=1)
    approach = data.approach_directions()
    same &= np.all(approach[cur] == approach[prev], axis=1)
    if data.pose_id is not None:
        same &= np.asarray(data.pose_id)[cur] == np.asarray(data.pose_id)[prev]
    if data.load_step is not None:
        same &= np.asarray(data.load_step)[cur] == np.asarray(data.load_step)[prev]
    else:
        dw = np.abs(data.wrench[cur] - data.wrench[prev])
        same &= np.all(dw[:, :3] <= force_tol_n, axis=1)
        same &= np.all(dw[:, 3:] <= REPEAT_MOMENT_TOL_NM, axis=1)
    groups = np.empty(m, dtype=np.int_)
    groups[order] = np.concatenate([[0], np.cumsum(~same)])
    return groups


def estimate_force_noise(data: MeasurementSet) -> tuple[float | None, str]:
    """Force sensor noise per axis [N] from the spread of its zero-load readings
    (:meth:`MeasurementSet.zero_load_force_noise`). A log without any non-zero force reading
    (no sensor, or a simulated/tared log) gives no estimate.

    Returns:
        (noise [N] or None, source text).
    """
    if not np.any(data.wrench[:, :3]):
        return None, "no force readings"
    fn = data.zero_load_force_noise()
    return (None, "unknown") if fn is None else (fn, "zero-load readings")


def force_noise_sigma(
    model: ElastostaticModel, data: MeasurementSet, force_noise_n: float,
    batch: PoseBatch | None = None,
) -> float:
    """RMS over measured values of the predicted-position noise from force noise [m].

    Per sample and axis a: sigma_a^2 = sigma_F^2 sum_j C[a, j]^2 over the force columns j of
    the model's Cartesian compliance C (the deflection is C F; force noise independent per
    axis).
    """
    if force_noise_n <= 0:
        return 0.0
    if batch is None:
        batch = model.batch_of(data)
    C = model.cartesian_compliance(batch)[:, :3, :3]  # (m, 3, 3) [m/N]
    var = force_noise_n**2 * np.sum(C**2, axis=2)  # (m, 3) [m^2]
    return float(np.sqrt(np.mean(var[data.measured]))) if data.measured.any() else 0.0


def estimate_noise_floor(
    data: MeasurementSet, residual: FloatArray, noise_m: float | None = None,
    model: ElastostaticModel | None = None, force_noise_n: float | None = None,
    batch: PoseBatch | None = None,
) -> NoiseFloor:
    """Noise floor from a given value, the scatter of repeated samples, or the sigma column,
    plus the force sensor's part (see :class:`NoiseFloor`).

    The repeat estimate pools the within-group variance of the *residuals* (so small
    differences of q and wrench inside a group are corrected by the model):

        sigma^2 = sum_g sum_i (r_gi - mean_g)^2 / sum_g (n_g - 1)   (per axis, pooled).

    A repeat scatter already contains the force sensor's part (each repeat is predicted with
    its own logged force): the device part is what remains. A given device noise (--noise-mm,
    the sigma column) gets the force part added.

    Args:
        data: The samples.
        residual: Measured minus predicted position [m], shape (m, 3).
        noise_m: The measuring device's noise given by the user [m] (takes precedence).
        model: The model whose compliance propagates the force noise (None: no force part).
        force_noise_n: Force sensor noise [N] given by the user (default: from zero-load
            readings).
        batch: Kinematics of ``data.q`` if already computed.

    Raises:
        InputError: noise_m or force_noise_n not positive.
    """
    if noise_m is not None and not (np.isfinite(noise_m) and noise_m > 0):
        raise InputError("noise_m", "", f"{noise_m * 1e3:g} mm", "a positive noise level")
    if force_noise_n is not None and not (np.isfinite(force_noise_n) and force_noise_n >= 0):
        raise InputError("force_noise_n", "", f"{force_noise_n:g} N", "a noise >= 0 N")
    fn: float | None
    if force_noise_n is not None:
        fn, fsrc = float(force_noise_n), "given"
    elif not np.any(data.wrench[:, :3]):
        fn, fsrc = 0.0, "no force sensor"
    else:
        fn, fsrc = estimate_force_noise(data)
    force_sigma = None if fn is None or model is None else force_noise_sigma(
        model, data, fn, batch)
    tol = REPEAT_FORCE_TOL_N if fn is None else max(REPEAT_FORCE_TOL_N, 3.0 * fn)
    groups = repeat_groups(data, tol)
    ss, dof, n_groups = 0.0, 0, 0
    for a in range(3):
        ok = np.isfinite(residual[:, a])
        g = groups[ok]
        r = residual[ok, a]
        if g.size == 0:
            continue
        counts = np.bincount(g)
        sums = np.bincount(g, weights=r)
        means = np.divide(sums, counts, out=np.zeros_like(sums), where=counts > 0)
        ss += float(np.sum((r - means[g]) ** 2))
        multi = counts >= 2
        dof += int(np.sum(counts[multi] - 1))
        n_groups = max(n_groups, int(np.sum(multi)))
    rep = float(np.sqrt(ss / dof)) if dof >= 2 and ss > 0 else None
    fs2 = 0.0 if force_sigma is None else force_sigma**2

    def parts(device: float | None, total_from_device: bool) -> tuple[float | None, float | None]:
        if device is None:
            return None, None
        if total_from_device:  # a given device noise: add the force part
            return float(np.sqrt(device**2 + fs2)), device
        return device, float(np.sqrt(max(device**2 - fs2, 0.0)))  # repeats hold both

    def floor(total: float | None, source: str, dof_: float, ng: int, rep_: float | None,
              dev: float | None) -> NoiseFloor:
        return NoiseFloor(total, source, dof_, ng, rep_, dev, force_sigma, fn, fsrc)

    if noise_m is not None:
        total, dev = parts(float(noise_m), True)
        return floor(total, "given", float("inf"), n_groups, rep, dev)
    if rep is not None:
        total, dev = parts(rep, False)
        return floor(total, "repeats", float(dof), n_groups, rep, dev)
    if data.sigma is not None:
        total, dev = parts(float(np.sqrt(np.mean(data.sigma**2))), True)
        return floor(total, "sigma column", float("inf"), 0, None, dev)
    return floor(None, "none", float("nan"), 0, None, None)


# --------------------------------------------------------------------------------------------
# Feature tests


def _standardise(x: FloatArray) -> FloatArray:
    x = np.asarray(x, dtype=float)
    s = np.std(x, axis=0)
    return (x - np.mean(x, axis=0)) / np.where(s > 0, s, 1.0)


def scalar_basis(x: FloatArray) -> FloatArray:
    """Cubic basis [z, z^2, z^3] of a standardised scalar feature, shape (m, 3)."""
    z = _standardise(x)
    return np.stack([z, z**2, z**3], axis=1)


def vector_basis(x: FloatArray) -> FloatArray:
    """Quadratic basis of a standardised vector feature (m, k): linear, squares, products."""
    z = _standardise(x)
    k = z.shape[1]
    pairs = [(i, j) for i in range(k) for j in range(i, k)]
    out = np.empty((z.shape[0], k + len(pairs)))  # filled in place: no list of columns
    out[:, :k] = z
    for c, (i, j) in enumerate(pairs):
        np.multiply(z[:, i], z[:, j], out=out[:, k + c])
    return out


def _sse_from_factor(R: FloatArray, m: int) -> tuple[int, float]:
    """Rank of X and residual sum of squares of the least-squares fit of r, from the upper
    triangular factor R (p + 1, p + 1) of [X | r] (X: m rows, p columns, m > p).

    The same numbers as ``np.linalg.lstsq(X, r)`` and ``np.linalg.matrix_rank(X)`` (singular
    values below max(m, p) eps s_max dropped): the singular values of X are those of
    R[:p, :p], and R[:p, p] is Q^T r.
    """
    p = R.shape[1] - 1
    U, sv, _ = np.linalg.svd(R[:p, :p])
    rank = int(np.sum(sv > sv[0] * max(m, p) * np.finfo(float).eps)) if sv.size else 0
    qr_ = R[:p, p]  # Q^T r on the span of X; R[p, p] is the part of r outside it
    inside = U[:, :rank].T @ qr_
    return rank, float(R[p, p] ** 2 + np.sum(qr_**2) - np.sum(inside**2))


def _lstsq_sse(X: FloatArray, r: FloatArray) -> tuple[int, float]:
    """Rank of X (m, p) and the residual sum of squares of the least-squares fit of r: one QR
    of [X | r] and the SVD of its p x p factor instead of two SVDs of the tall X (lstsq and
    matrix_rank; 3-4 times faster on 10^6 rows)."""
    m, p = X.shape
    if m <= p:
        coef, *_ = np.linalg.lstsq(X, r, rcond=None)
        return int(np.linalg.matrix_rank(X)), float(np.sum((r - X @ coef) ** 2))
    return _sse_from_factor(np.asarray(np.linalg.qr(np.column_stack([X, r]), mode="r")), m)


#: Rows per block of the feature fits (bounded memory on 10^6 samples).
FIT_ROWS = 65_536


def _axis_fits(residual: FloatArray, basis: FloatArray) -> list[tuple[FloatArray, int, float]]:
    """(measured residual, rank of [1, basis], SSE) of each axis with at least 3 values.

    When every axis is measured on the same samples (the usual case) one QR of
    [1, basis, residual] serves the three axes (the factor of a column subset is the factor of
    the subset of R): one copy of the m x p basis instead of four per axis.
    """
    oks = [np.isfinite(residual[:, a]) for a in range(residual.shape[1])]
    out = []
    if all(np.array_equal(oks[0], ok) for ok in oks) and oks[0].sum() > basis.shape[1] + 1:
        ok = oks[0]
        B = basis if ok.all() else basis[ok]
        keep = np.array([np.std(B[:, j]) > 1e-12 for j in range(B.shape[1])], dtype=bool)
        m, p = int(ok.sum()), int(keep.sum()) + 1
        res = residual[ok]
        R = np.zeros((0, p + res.shape[1]))
        for a0 in range(0, m, FIT_ROWS):  # the factor of a stack is that of the stacked factors
            rows = slice(a0, min(a0 + FIT_ROWS, m))
            M = np.column_stack([np.ones(rows.stop - a0), B[rows][:, keep], res[rows]])
            R = np.asarray(np.linalg.qr(np.vstack([R, M]), mode="r"))
        for a in range(residual.shape[1]):
            cols = [*range(p), p + a]
            Ra = np.asarray(np.linalg.qr(R[:, cols], mode="r"))
            out.append((residual[ok, a], *_sse_from_factor(Ra, m)))
        return out
    for a, ok in enumerate(oks):
        if ok.sum() < 3:
            continue
        r = residual[ok, a]
        B = basis[ok]
        B = B[:, np.std(B, axis=0) > 1e-12]
        X = np.concatenate([np.ones((r.size, 1)), B], axis=1)
        out.append((r, *_lstsq_sse(X, r)))
    return out


def explained_share(residual: FloatArray, basis: FloatArray) -> tuple[float, float, float]:
    """Fit each measured axis on [1, basis] and pool: (R^2, adjusted R^2, p-value).

    Args:
        residual: Residual [m], shape (m, 3), NaN = not measured.
        basis: Feature basis, shape (m, p); constant columns are dropped.
    """
    sse = sst = 0.0
    n = p_tot = n_axes = 0
    for r, rank, sse_a in _axis_fits(residual, basis):
        sse += sse_a
        sst += float(np.sum((r - r.mean()) ** 2))
        n += r.size
        p_tot += rank - 1
        n_axes += 1
    if sst <= 0 or p_tot == 0:
        return 0.0, 0.0, 1.0
    r2 = max(0.0, 1.0 - sse / sst)
    dof_res = n - p_tot - n_axes
    if dof_res <= 0:
        return r2, 0.0, 1.0
    adj = 1.0 - (sse / dof_res) / (sst / max(n - n_axes, 1))
    F = ((sst - sse) / p_tot) / (sse / dof_res) if sse > 0 else np.inf
    p = float(special.fdtrc(p_tot, dof_res, F))
    return r2, float(adj), p


def residual_features(
    data: MeasurementSet, tcp: FloatArray, tau: FloatArray
) -> dict[str, tuple[str, FloatArray]]:
    """Candidate features the residual may depend on, name -> (description, values).

    Args:
        data: The samples (time, joint values, wrench, extra columns).
        tcp: Nominal TCP position [m], base frame, shape (m, 3).
        tau: Joint torques J^T F [N m], shape (m, n).
    """
    feats: dict[str, tuple[str, FloatArray]] = {}
    if data.t is not None:
        feats["time"] = ("time t_s [s]", data.t)
    else:
        feats["sample_order"] = ("row number in the file (no t_s column)",
                                 np.arange(len(data), dtype=float))
    for name, values in data.extra.items():
        feats[name] = (f"extra column '{name}'", values)
    for j in range(tau.shape[1]):
        feats[f"tau_j{j + 1}"] = (f"joint {j + 1} torque (J^T F)_{j + 1} [N m]", tau[:, j])
    for j in range(data.n_joints):
        feats[f"q{j + 1}"] = (f"joint {j + 1} angle [rad]", data.q[:, j])
    f = data.wrench[:, :3]
    fn = np.linalg.norm(f, axis=1)
    feats["force_magnitude"] = ("|f| of the logged force [N]", fn)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(fn[:, None] > 0, f / fn[:, None], 0.0)
    feats["force_direction"] = ("unit vector of the logged force, base frame", u)
    feats["tcp_position"] = ("nominal TCP position in the workspace, base frame [m]", tcp)
    return feats


def correlations(
    residual: FloatArray, features: Mapping[str, tuple[str, FloatArray]]
) -> tuple[FeatureCorrelation, ...]:
    """Feature tests of the residual, most explanatory (adjusted R^2) first."""
    out = []
    n_feat = max(len(features), 1)
    for name, (desc, values) in features.items():
        v = np.asarray(values, dtype=float)
        if not np.all(np.isfinite(v)) or np.ptp(v, axis=0).max() == 0:
            continue
        basis = scalar_basis(v) if v.ndim == 1 else vector_basis(v)
        r2, adj, p = explained_share(residual, basis)
        out.append(FeatureCorrelation(name, desc, r2, adj, p, p < FEATURE_ALPHA / n_feat))
    return tuple(sorted(out, key=lambda c: -c.adj_r2))


# --------------------------------------------------------------------------------------------
# The analysis


def _stats(name: str, v: FloatArray) -> AxisStats:
    v = v[np.isfinite(v)]
    if v.size == 0:
        return AxisStats(name, 0, float("nan"), float("nan"), float("nan"))
    return AxisStats(name, int(v.size), float(np.sqrt(np.mean(v**2))), float(np.mean(v)),
                     float(np.max(np.abs(v))))


def _rms(v: FloatArray) -> float:
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v**2))) if v.size else float("nan")


def analyze_residuals(
    model: ElastostaticModel,
    data: MeasurementSet,
    residual: FloatArray | None = None,
    noise: NoiseFloor | None = None,
    batch: PoseBatch | None = None,
) -> ResidualAnalysis:
    """Summarise the residual of a model on a measurement set.

    Args:
        model: The model whose residual is analysed (also gives the kinematics).
        data: The samples.
        residual: Residual to analyse [m], shape (m, 3) (default: measured - predicted by
            ``model``; pass held-out residuals to analyse those instead).
        noise: Noise floor (default: estimated from repeats / the sigma column).
        batch: Kinematics of ``data.q`` if already computed.
    """
    if batch is None:
        batch = model.batch_of(data)
    if residual is None:
        pred = predicted_positions(model, batch, data.wrench)
        residual = data.position - pred
    residual = np.where(data.measured, residual, np.nan)
    if noise is None:
        noise = estimate_noise_floor(data, residual)
    tcp = batch.T[:, :3, 3]
    tau = np.einsum("mak,ma->mk", batch.J, data.wrench)
    vals = np.abs(residual[np.isfinite(residual)])
    full = np.all(np.isfinite(residual), axis=1)
    norms = np.sqrt(np.nansum(residual**2, axis=1))[np.any(np.isfinite(residual), axis=1)]
    pct = {p: float(np.percentile(vals, p)) for p in PERCENTILES} if vals.size else {}
    npct = {p: float(np.percentile(norms, p)) for p in PERCENTILES} if norms.size else {}

    per_axis = tuple(_stats(AXES[a], residual[:, a]) for a in range(3))
    f = data.wrench[:, :3]
    fn = np.linalg.norm(f, axis=1)
    sel = full & (fn > 0)
    per_dir: tuple[AxisStats, ...] = ()
    if np.any(sel):
        u = f[sel] / fn[sel, None]
        along = np.einsum("ma,ma->m", residual[sel], u)
        across = np.linalg.norm(residual[sel] - along[:, None] * u, axis=1)
        per_dir = (_stats("along force", along), _stats("across force", across))

    feats = residual_features(data, tcp, tau)
    corr = correlations(residual, feats)
    r2_of = {c.feature: c.r2 for c in corr}
    per_joint = []
    for j in range(data.n_joints):
        tj = tau[:, j]
        Jj = batch.J[:, :3, j]
        scale = float(np.std(tj)) or 1.0
        basis = np.stack([np.ones_like(tj), tj / scale, np.sign(tj)], axis=1)  # (m, 3)
        motion = Jj[:, :, None] * basis[:, None, :]  # (m, 3, 3): columns J_j * basis_k
        per_joint.append(
            JointBreakdown(
                joint=j + 1,
                tau_min=float(tj.min()),
                tau_max=float(tj.max()),
                r2_torque=r2_of.get(f"tau_j{j + 1}", 0.0),
                r2_angle=r2_of.get(f"q{j + 1}", 0.0),
                r2_joint_motion=_motion_share(residual, motion),
                rms_tau_pos=_rms(residual[tj > 0]),
                rms_tau_neg=_rms(residual[tj < 0]),
            )
        )
    return ResidualAnalysis(
        residual=residual,
        n_samples=len(data),
        n_observations=int(np.isfinite(residual).sum()),
        rms=_rms(residual),
        max_abs=float(vals.max()) if vals.size else float("nan"),
        percentiles=pct,
        norm_percentiles=npct,
        per_axis=per_axis,
        per_direction=per_dir,
        per_joint=tuple(per_joint),
        correlations=corr,
        noise=noise,
        features={k: v for k, (_, v) in feats.items()},
        tcp=tcp,
        tau=tau,
    )


def _motion_share(residual: FloatArray, regressor: FloatArray) -> float:
    """Share of the residual (about zero) fitted by ``regressor`` (m, 3, p) with one theta."""
    ok = np.isfinite(residual)
    y = residual[ok]
    A = regressor[ok]
    A = A[:, np.linalg.norm(A, axis=0) > 0]
    sst = float(np.sum(y**2))
    if sst <= 0 or A.shape[1] == 0:
        return 0.0
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    return max(0.0, 1.0 - float(np.sum((y - A @ coef) ** 2)) / sst)
