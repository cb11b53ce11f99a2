"""Fitting a candidate to one weld: the weld's prediction as the input of the diagnosis engine.

The observations are the measured offsets of the track (lateral, and normal where measured),
stacked; a model predicts them through :meth:`~rfsw_plan.validation.weld.samples.WeldSamples.
predict`. A candidate (:class:`~rfsw_plan.validation.engine.candidates.CandidateForm`) is fitted by
bounded nonlinear least squares on its parameters (scipy ``least_squares``, trust region
reflective, bounds from the effect's ``param_ranges``); its Jacobian at the fit is taken by
finite differences, and the held-out residual over contiguous blocks of s is the workbench's
one cross-validation (:func:`~rfsw_plan.validation.engine.crossval.heldout_residual`), each step
clipped to the physical range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.process.frames import FloatArray
from rfsw_plan.validation.engine.candidates import CandidateForm
from rfsw_plan.validation.engine.crossval import heldout_residual
from rfsw_plan.validation.weld.samples import WeldSamples
from rfsw_plan.validation.weld.track import TrackOnSeam

#: Relative cut-off of small singular values in the held-out steps of a weld (a weld sees few
#: directions: a near-invisible parameter must not swing the held-out prediction).
RCOND = 1e-8


class WeldObservations:
    """The stacked observations of a weld (lateral, and normal if measured), in blocks of s.

    Args:
        samples: The executed plan at the track points.
        track: The measured track.
        reference: The problem's seam reference of the process deflection.
        blocks: Number of contiguous blocks of s (the folds).
    """

    def __init__(self, samples: WeldSamples, track: TrackOnSeam, reference: str,
                 blocks: int) -> None:
        self.samples = samples
        self.reference = reference
        self.y = np.concatenate([track.e_lat] + ([track.e_norm] if track.e_norm is not None
                                                 else []))
        n = track.s.size
        self.n_points = n
        self.n_comp = 1 if track.e_norm is None else 2
        block = np.minimum((np.arange(n) * blocks) // n, blocks - 1)
        self.block = np.tile(block, self.n_comp)
        self.blocks = blocks

    def predict(self, model: ElastostaticModel) -> FloatArray:
        """Predicted offsets of ``model`` [m], stacked like :attr:`y`, shape (n_comp N,)."""
        e_lat, e_norm = self.samples.predict(model, self.reference)
        return np.concatenate([e_lat] + ([e_norm] if self.n_comp == 2 else []))


@dataclass(frozen=True)
class WeldFit:
    """A candidate fitted to a weld.

    Attributes:
        form: The candidate.
        theta: Fitted parameters [SI], shape (p,).
        residual: measured - predicted at theta [m], shape (n_comp N,).
        jacobian: d(prediction)/d(theta) at theta, shape (n_comp N, p).
        heldout: Held-out residual over the blocks of s [m], shape (n_comp N,).
    """

    form: CandidateForm
    theta: FloatArray
    residual: FloatArray
    jacobian: FloatArray
    heldout: FloatArray


def _fd_jacobian(obs: WeldObservations, form: CandidateForm, theta: FloatArray,
                 base: FloatArray) -> FloatArray:
    """Forward differences of the prediction, step 1e-3 of each parameter's size."""
    cols = []
    for i in range(theta.size):
        h = 1e-3 * max(abs(float(theta[i])), abs(float(form.theta0[i])), 1e-9)
        th = theta.copy()
        th[i] += h
        cols.append((obs.predict(form.build(th)) - base) / h)
    return np.stack(cols, axis=1) if cols else np.zeros((base.size, 0))


def fit_form(obs: WeldObservations, form: CandidateForm) -> WeldFit:
    """Bounded nonlinear least squares of a candidate on the weld, and its held-out residual.

    Raises:
        ValueError, numpy.linalg.LinAlgError: The fit failed numerically.
    """
    from scipy.optimize import least_squares

    lb, ub = form.lower, form.upper
    x0 = np.clip(form.theta0, np.where(np.isfinite(lb), lb, -np.inf),
                 np.where(np.isfinite(ub), ub, np.inf))
    scale = np.where(x0 != 0, np.abs(x0), 1.0)

    def fun(z: FloatArray) -> FloatArray:
        out: FloatArray = obs.y - obs.predict(form.build(z * scale))
        return out

    lbz, ubz = lb / scale, ub / scale
    z0 = x0 / scale
    z0 = np.where(z0 <= lbz, lbz + 1e-9, z0)
    z0 = np.where(z0 >= ubz, ubz - 1e-9, z0)
    sol = least_squares(fun, z0, bounds=(lbz, ubz), method="trf", x_scale="jac",
                        diff_step=1e-4, max_nfev=60 * (z0.size + 1))
    theta = sol.x * scale
    pred = obs.predict(form.build(theta))
    J = _fd_jacobian(obs, form, theta, pred)
    r = obs.y - pred
    held = heldout_residual(J, r, obs.block, obs.blocks, rcond=RCOND,
                            room=(form.lower - theta, form.upper - theta))
    return WeldFit(form, theta, r, J, held)


def rms(x: FloatArray) -> float:
    """Root mean square [same unit as x] (NaN if empty)."""
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


__all__ = ["RCOND", "WeldFit", "WeldObservations", "fit_form", "rms"]
