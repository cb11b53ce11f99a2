"""Fit the parametric process-force model to a measured force series.

Seed 001 §3 calibrates one model parameter (the equivalent friction coefficient f*) by
minimising the squared distance between model and measured steady forces (eq. 15)::

    e = (F_l(x) - F_l0)^2 + (F_d(x) - F_d0)^2 + (F_r(x) - F_r0)^2

Here the same loss is summed over every sample of the series and the parameters are those of
:class:`~rfsw_plan.process.forces.ProcessForces` (steady forces, plunge peak, dwell lateral
fraction and time constant, weld ramp length)::

    e(x) = sum_k || f_model(t_k; x) - f_meas(t_k) ||^2       (seam frame, [N^2])

solved by bounded nonlinear least squares (scipy ``least_squares``). The spindle torque, which
enters linearly, is fitted separately from the moment about the tool axis when moments are
given. Parameters the series cannot inform (no plunge samples, no dwell samples, no moments)
keep their prior values and are listed in ``notes``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from rfsw_plan.exceptions import IdentificationError, InputError
from rfsw_plan.process.force_series import ForceSeries
from rfsw_plan.process.forces import FIT_PARAMS, ProcessModel
from rfsw_plan.process.frames import FloatArray, LoadSchedule, SeamFrames, tcp_orientation

#: Scale of each parameter in the solver (N, N, N, N, -, s, m, N m).
_SCALE = np.array([1e3, 1e3, 1e3, 1e3, 1.0, 1.0, 1e-3, 1.0])
_LOWER = np.array([0.0, -np.inf, 0.0, 0.0, -1.0, 1e-3, 1e-6, -np.inf])
_UPPER = np.array([np.inf, np.inf, np.inf, np.inf, 2.0, 1e4, 1.0, np.inf])
#: Display units of the parameters (value multiplier, unit).
UNITS = {
    "axial": (1.0, "N"), "lateral": (1.0, "N"), "traverse": (1.0, "N"),
    "plunge_peak_axial": (1.0, "N"), "dwell_lateral_fraction": (1.0, "-"),
    "dwell_tau": (1.0, "s"), "ramp_length": (1e3, "mm"), "spindle_torque": (1.0, "N m"),
}


@dataclass(frozen=True)
class ForceFit:
    """Result of :func:`fit_process_forces`.

    Attributes:
        process: The process with the fitted forces.
        params: Fitted parameters by name (SI; ``lateral`` is signed, + = advancing side).
        std: 1-sigma standard errors of the fitted parameters (SI); fixed ones are absent.
        fixed: Names of parameters kept at their prior values.
        rms: RMS residual per seam component (t, l, n) [N], shape (3,).
        r2: Coefficient of determination per component (t, l, n), shape (3,) (NaN if the
            component is constant).
        rms_total: RMS residual over all force components [N].
        loss: Eq. 15 loss summed over the samples [N^2].
        n_samples: Samples used.
        torque_rms: RMS residual of the moment about the tool axis [N m], or None.
        notes: Human-readable remarks (unidentifiable parameters...).
    """

    process: ProcessModel
    params: dict[str, float]
    std: dict[str, float]
    fixed: tuple[str, ...]
    rms: FloatArray
    r2: FloatArray
    rms_total: float
    loss: float
    n_samples: int
    torque_rms: float | None
    notes: tuple[str, ...]

    def summary(self) -> str:
        """Multi-line text summary of the fit."""
        lines = [f"force fit on {self.n_samples} samples: RMS {self.rms_total:.1f} N"]
        for c, name in enumerate(("traverse t", "lateral l", "axial n")):
            lines.append(f"  {name:<11} RMS {self.rms[c]:8.1f} N   R^2 {self.r2[c]:.3f}")
        for k, v in self.params.items():
            mult, unit = UNITS[k]
            sd = self.std.get(k)
            tag = " (fixed)" if k in self.fixed else (f" +- {sd * mult:.3g}" if sd is not None
                                                      else "")
            lines.append(f"  {k:<24} {v * mult:12.5g} {unit}{tag}")
        lines.extend(f"  note: {n}" for n in self.notes)
        return "\n".join(lines)


def series_in_seam_frame(
    series: ForceSeries, schedule: LoadSchedule, tool_rotation: float = 0.0
) -> tuple[FloatArray, FloatArray | None]:
    """Measured force (and moment) as seam-frame components at the series' samples.

    Args:
        series: Measured series; ``schedule`` must be evaluated at ``series.t``.
        schedule: Load schedule at the same times (gives the frames).
        tool_rotation: Rotation of the TCP about the tool axis [rad] (for ``frame='tool'``).

    Returns:
        (force (N, 3) as (f_t, f_l, f_n) [N], moment (N, 3) in (t, l, n) [N m] or None).
    """
    fr = schedule.frames

    def to_seam(v: FloatArray) -> FloatArray:
        if series.frame == "seam":
            return v
        if series.frame == "tool":
            R = tcp_orientation(fr, tool_rotation)
            v = np.einsum("kij,kj->ki", R, v)
        return fr.to_seam(v)

    m = None if series.moment is None else to_seam(series.moment)
    return to_seam(series.force), m


def fit_process_forces(
    process: ProcessModel,
    frames: SeamFrames,
    series: ForceSeries,
    tool_rotation: float = 0.0,
    free: Sequence[str] | None = None,
) -> ForceFit:
    """Least-squares fit of the force parameters to a measured series (seed 001 eq. 15).

    Args:
        process: Process whose timing (speeds, depth, dwell) matches the measurement; its
            forces are the start values and the priors of fixed parameters.
        frames: Seam waypoint frames (base frame) of the welded seam.
        series: Measured series, time from the process start.
        tool_rotation: TCP rotation about the tool axis [rad] (for a 'tool'-frame series).
        free: Parameters to fit (names from :data:`FIT_PARAMS`); default all the data inform.

    Raises:
        InputError: Unknown parameter names.
        IdentificationError: Fewer samples than free parameters.
    """
    names = list(FIT_PARAMS)
    if free is not None:
        unknown = [f for f in free if f not in names]
        if unknown:
            raise InputError("fit", "free", f"unknown parameter(s) {', '.join(unknown)}",
                             ", ".join(names))
    sched = process.evaluate(frames, series.t)
    f_meas, m_meas = series_in_seam_frame(series, sched, tool_rotation)
    want, notes = _informed(names if free is None else free, sched.phase, m_meas is not None)
    x0 = process.forces.vector()
    idx = [i for i, n in enumerate(names) if n in want and n != "spindle_torque"]
    if 3 * len(series) < len(idx):
        raise IdentificationError(f"{len(series)} samples cannot fit {len(idx)} parameters")
    x, std = _fit_forces(process, frames, series, f_meas, x0, idx, notes)
    torque_rms = None
    if m_meas is not None and "spindle_torque" in want:
        torque_rms = _fit_spindle_torque(process, frames, series, sched, m_meas, x, std)
    forces = process.forces.with_vector(x, source=f"fitted to {series.source}")
    fitted = replace(process, forces=forces)
    _, _, _, F, _ = fitted.profile(series.t, float(frames.s[-1] - frames.s[0]))
    res = F - f_meas
    rms = np.sqrt(np.mean(res**2, axis=0))
    sst = np.sum((f_meas - f_meas.mean(axis=0)) ** 2, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        r2 = np.where(sst > 0, 1.0 - np.sum(res**2, axis=0) / sst, np.nan)
    fixed = tuple(n for n in names if n not in std)
    return ForceFit(
        process=fitted,
        params={n: float(v) for n, v in zip(names, forces.vector(), strict=True)},
        std=std,
        fixed=fixed,
        rms=rms,
        r2=r2,
        rms_total=float(np.sqrt(np.mean(res**2))),
        loss=float(np.sum(res**2)),
        n_samples=len(series),
        torque_rms=torque_rms,
        notes=tuple(notes),
    )


def _informed(free: Sequence[str], phase: NDArray[Any], has_moment: bool
              ) -> tuple[set[str], list[str]]:
    """The free parameters the series informs (a phase it lacks fixes its parameters), and
    a note for each one kept at its prior."""
    want = set(free)
    auto_fixed: list[str] = []
    if not np.any(phase == "plunge"):
        auto_fixed.append("plunge_peak_axial")
    if not np.any(phase == "dwell"):
        auto_fixed.append("dwell_tau")
        if not np.any(phase == "stop"):  # the end stop relaxes to the dwell's lateral share
            auto_fixed.append("dwell_lateral_fraction")
    if not np.any(phase == "weld"):
        auto_fixed += ["axial", "lateral", "traverse", "ramp_length"]
    if not has_moment:
        auto_fixed.append("spindle_torque")
    notes = []
    for a in auto_fixed:
        if a in want:
            want.discard(a)
            notes.append(f"{a} kept at its prior: the series has no samples that inform it")
    return want, notes


def _fit_forces(
    process: ProcessModel, frames: SeamFrames, series: ForceSeries, f_meas: FloatArray,
    x0: FloatArray, idx: list[int], notes: list[str],
) -> tuple[FloatArray, dict[str, float]]:
    """Bounded least squares of the force parameters ``idx`` (seam-frame forces): the full
    parameter vector and the standard error of each fitted one [SI]; appends a note when the
    series does not inform every parameter."""
    names = list(FIT_PARAMS)
    x = x0.copy()
    std: dict[str, float] = {}
    if not idx:
        return x, std

    def resid(p: FloatArray) -> FloatArray:
        xp = x0.copy()
        xp[idx] = p * _SCALE[idx]
        fp = process.forces.with_vector(xp)
        _, _, _, F, _ = process.profile(series.t, float(frames.s[-1] - frames.s[0]), fp)
        return (F - f_meas).ravel()

    p0 = np.clip(x0[idx], _LOWER[idx] + 1e-9, _UPPER[idx] - 1e-9) / _SCALE[idx]
    sol = least_squares(resid, p0, bounds=(_LOWER[idx] / _SCALE[idx],
                                           _UPPER[idx] / _SCALE[idx]),
                        x_scale="jac", method="trf")
    x[idx] = sol.x * _SCALE[idx]
    dof = max(3 * len(series) - len(idx), 1)
    s2 = float(sol.fun @ sol.fun) / dof
    J = sol.jac
    sv = np.linalg.svd(J, compute_uv=False)
    if sv[-1] <= 1e-10 * sv[0]:
        notes.append("the series does not inform every free parameter (rank-deficient "
                     "Jacobian); standard errors are unreliable")
    cov = s2 * np.linalg.pinv(J.T @ J)
    for j, i in enumerate(idx):
        std[names[i]] = float(np.sqrt(max(cov[j, j], 0.0))) * _SCALE[i]
    return x, std


def _fit_spindle_torque(
    process: ProcessModel, frames: SeamFrames, series: ForceSeries, sched: LoadSchedule,
    m_meas: FloatArray, x: FloatArray, std: dict[str, float],
) -> float | None:
    """Linear fit of the spindle torque to the logged moment about the tool axis: sets
    x[7] and its standard error in place; returns the RMS residual [N m] (None if the
    schedule has no torque)."""
    _, _, _, _, g = process.profile(series.t, float(frames.s[-1] - frames.s[0]),
                                    replace(process.forces, spindle_torque=1.0))
    sigma = float(np.sign(np.linalg.det(sched.frames.rotation()[0])))
    mz = sigma * m_meas[:, 2]
    gg = float(g @ g)
    if gg <= 0:
        return None
    x[7] = float(g @ mz) / gg
    r = mz - x[7] * g
    std["spindle_torque"] = float(np.sqrt((r @ r) / max(len(r) - 1, 1) / gg))
    return float(np.sqrt(np.mean(r**2)))


#: Coverage of the derived force uncertainty: +- this many standard deviations of the
#: residual spread (on top of the drift).
COVERAGE_SIGMA = 3.0
#: Length of the running mean that separates the slow drift from the spread, as a fraction
#: of each phase's samples (10 % of the weld length during the weld).
DRIFT_WINDOW = 0.10
#: A log the force model describes: R^2 of the axial component at least this (where the log
#: spans the plunge, i.e. the axial force varies) or an axial RMS residual below
#: ``MAX_AXIAL_RMS_SHARE`` of the steady axial force.
MIN_R2 = 0.5
MAX_AXIAL_RMS_SHARE = 0.10
#: Fewest weld-phase samples a log needs to inform the planned forces.
MIN_WELD_SAMPLES = 10
#: Phases whose uncertainty is derived (the pin is in the material).
LOADED_PHASES = ("plunge", "dwell", "weld")


@dataclass(frozen=True)
class ForceUncertainty:
    """Force uncertainty derived from a fitted log, per phase and seam-frame component.

    For every phase the fit's residual r_k = f_meas(t_k) - f_model(t_k) (seam frame
    (t, l, n)) is split into a slow part, the drift d_k (running mean over
    :data:`DRIFT_WINDOW` of the phase; along the seam during the weld), and the spread
    r_k - d_k with standard deviation sigma. The bound per component is::

        delta_i = max_k |d_k,i| + c sigma_i      (c = coverage, e.g. 3 for +-3 sigma) [N]

    The spread includes the sensor noise; the bound is therefore conservative for a noisy log.

    Attributes:
        coverage: c [-].
        bound: Phase -> delta (t, l, n) [N], shape (3,).
        sigma: Phase -> sigma (t, l, n) [N], shape (3,).
        drift: Phase -> max |d| (t, l, n) [N], shape (3,).
        samples: Phase -> number of log samples in that phase.
        steady: Steady fitted weld force (f_t, f_l, f_n) [N], shape (3,).
        usable: The force model describes the log (see :func:`derive_force_uncertainty`).
        reason: Why not (empty if usable).
    """

    coverage: float
    bound: dict[str, FloatArray]
    sigma: dict[str, FloatArray]
    drift: dict[str, FloatArray]
    samples: dict[str, int]
    steady: FloatArray
    usable: bool
    reason: str = ""

    @property
    def weld_relative(self) -> FloatArray:
        """Weld bound relative to the steady fitted force per component [-], shape (3,)
        (inf where the steady component is zero)."""
        if "weld" not in self.bound:
            return np.full(3, np.inf)
        return np.where(np.abs(self.steady) > 0,
                        self.bound["weld"] / np.maximum(np.abs(self.steady), 1e-300), np.inf)

    def box(self, phase: NDArray[np.str_]) -> FloatArray:
        """Bound of each sample's phase [N], shape (N, 3) (the weld bound where the log has
        no sample of a phase, e.g. the accelerate/decelerate samples of a timed plan)."""
        out = np.tile(self.bound.get("weld", np.zeros(3)), (len(phase), 1))
        for ph, b in self.bound.items():
            out[np.asarray(phase) == ph] = b
        return out

    def summary(self) -> str:
        """Text block: the bound per phase and component."""
        lines = [f"force uncertainty from the log (seam frame, max |drift| + "
                 f"{self.coverage:g} sigma):"]
        for ph in LOADED_PHASES:
            if ph not in self.bound:
                continue
            b, s, d = self.bound[ph], self.sigma[ph], self.drift[ph]
            lines.append(
                f"  {ph:<6} ({self.samples[ph]:>5} samples)  f_t +-{b[0]:7.1f} N  "
                f"f_l +-{b[1]:7.1f} N  f_n +-{b[2]:7.1f} N   (sigma {s[0]:.1f}/{s[1]:.1f}/"
                f"{s[2]:.1f} N, drift {d[0]:.1f}/{d[1]:.1f}/{d[2]:.1f} N)")
        if "weld" in self.bound:
            rel = self.weld_relative
            lines.append("  weld, relative to the fitted steady force: " + ", ".join(
                f"{n} {100 * r:.1f} %" if np.isfinite(r) else f"{n} -"
                for n, r in zip(("f_t", "f_l", "f_n"), rel, strict=True)))
        if not self.usable:
            lines.append(f"  NOT USED: {self.reason}")
        return "\n".join(lines)

    def to_json(self) -> dict[str, object]:
        """JSON-ready form (N, file units)."""
        def vec(d: dict[str, FloatArray]) -> dict[str, list[float]]:
            return {k: [float(x) for x in v] for k, v in d.items()}

        return {
            "frame": "seam (t, l, n)", "coverage_sigma": self.coverage,
            "definition": "max |running mean of the fit residual| + coverage * std of the rest",
            "bound_N": vec(self.bound), "sigma_N": vec(self.sigma), "drift_N": vec(self.drift),
            "samples": dict(self.samples), "steady_weld_force_N": [float(x) for x in self.steady],
            "weld_relative": [float(x) if np.isfinite(x) else None for x in self.weld_relative],
            "usable": self.usable, "reason": self.reason,
        }


def _running_mean(x: FloatArray, n: int) -> FloatArray:
    """Centred running mean of each column of x (N, 3) over n samples (shrinking at the
    ends), shape (N, 3)."""
    n = max(1, min(n, x.shape[0]))
    c = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    k = np.arange(x.shape[0])
    lo = np.clip(k - n // 2, 0, x.shape[0])
    hi = np.clip(k + n - n // 2, 0, x.shape[0])
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


def fit_residual(
    fit: ForceFit, frames: SeamFrames, series: ForceSeries, tool_rotation: float = 0.0
) -> tuple[NDArray[np.str_], FloatArray, FloatArray]:
    """Phase per sample, measured force and residual measured - fitted, seam frame [N].

    Returns:
        phase (N,), f_meas (N, 3) (t, l, n) [N], residual (N, 3) [N].
    """
    sched = fit.process.evaluate(frames, series.t)
    f_meas, _ = series_in_seam_frame(series, sched, tool_rotation)
    return np.asarray(sched.phase), f_meas, f_meas - sched.force_seam


def derive_force_uncertainty(
    fit: ForceFit, frames: SeamFrames, series: ForceSeries, tool_rotation: float = 0.0,
    coverage: float = COVERAGE_SIGMA,
) -> ForceUncertainty:
    """Force uncertainty per phase and seam component from a fit's residual (see
    :class:`ForceUncertainty`), and whether the force model describes the log at all.

    The log is *not usable* when it has fewer than :data:`MIN_WELD_SAMPLES` weld samples (the
    phases are not found: the log does not match the problem's timing), or when the fitted
    axial force leaves R^2 < :data:`MIN_R2` and an RMS residual above
    :data:`MAX_AXIAL_RMS_SHARE` of the steady axial force.

    Raises:
        InputError: coverage not positive.
    """
    if not (np.isfinite(coverage) and coverage > 0):
        raise InputError("force uncertainty", "coverage", f"got {coverage:g}", "> 0")
    phase, _, res = fit_residual(fit, frames, series, tool_rotation)
    bound: dict[str, FloatArray] = {}
    sigma: dict[str, FloatArray] = {}
    drift: dict[str, FloatArray] = {}
    samples: dict[str, int] = {}
    for ph in LOADED_PHASES:
        m = phase == ph
        n = int(np.sum(m))
        if n < 2:
            continue
        r = res[m]
        d = _running_mean(r, round(DRIFT_WINDOW * n) | 1)
        sd = np.std(r - d, axis=0, ddof=1)
        dmax = np.max(np.abs(d), axis=0)
        bound[ph], sigma[ph], drift[ph], samples[ph] = dmax + coverage * sd, sd, dmax, n
    steady = fit.process.forces.steady_seam
    reason = ""
    n_weld = samples.get("weld", 0)
    if n_weld < MIN_WELD_SAMPLES:
        reason = (f"the log has {n_weld} samples in the weld phase of this problem's timing "
                  f"(need {MIN_WELD_SAMPLES}): the phases are not found")
    else:
        r2n = float(fit.r2[2])
        share = float(fit.rms[2]) / max(abs(float(steady[2])), 1e-9)
        if not (np.isfinite(r2n) and r2n >= MIN_R2) and share > MAX_AXIAL_RMS_SHARE:
            reason = (f"the force model does not describe the log: axial R^2 {r2n:.2f} < "
                      f"{MIN_R2:g} and RMS {fit.rms[2]:.0f} N = {100 * share:.0f} % of the "
                      f"axial force")
    return ForceUncertainty(coverage=coverage, bound=bound, sigma=sigma, drift=drift,
                            samples=samples, steady=steady, usable=not reason, reason=reason)
