"""Which candidate explains the residual of one weld (``rfsw-plan validate-weld``).

The candidates are every joint stiffness of the model and every library effect it lacks
(:func:`~rfsw_plan.validation.engine.candidates.candidate_labels` with ``joint_stiffness``): one
weld does not re-identify the model, so a joint stiffness can be what is missing. Each is fitted to
the weld through the weld's prediction (:func:`~rfsw_plan.validation.weld.fit.fit_form`),
cross-validated over contiguous blocks of s, and scored by the workbench's one scoring
(:mod:`rfsw_plan.validation.engine.scoring`: held-out F test against the model as it is, Bonferroni
over the candidates at level ALPHA, ranking by held-out RMS, ties, the simplest named).

The noise floor sigma is estimated from successive differences of the residual
(:func:`~rfsw_plan.validation.weld.track.noise_floor`); a held-out RMS within NOISE_TOLERANCE
sigma is at the floor. What the weld can identify is stated with the verdict
(:mod:`rfsw_plan.validation.weld.identifiability`).

Verdict: ``adequate`` (the residual is at the noise floor), ``missing`` (the named candidate
brings the held-out residual to the noise floor; the candidates the weld cannot tell from it
are listed), ``unexplained`` (no candidate does).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
from scipy import special  # the distributions' tails (scipy.stats costs ~0.9 s more CPU to import)

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import IdentificationError, InputError
from rfsw_plan.process.frames import FloatArray
from rfsw_plan.progress import progress
from rfsw_plan.validation.engine.candidates import (
    candidate_form,
    candidate_labels,
    stiffness_labels,
)
from rfsw_plan.validation.engine.scoring import ALPHA, Candidate, named, rank, score, ties_of
from rfsw_plan.validation.weld.fit import WeldFit, WeldObservations, fit_form, rms
from rfsw_plan.validation.weld.identifiability import Identifiability, assess, visibility
from rfsw_plan.validation.weld.samples import WeldSamples
from rfsw_plan.validation.weld.track import TrackOnSeam, noise_floor

#: A held-out RMS within this factor of the noise floor is "at the noise floor" (the floor of
#: a weld comes from successive differences, a slight underestimate where the error is smooth).
NOISE_TOLERANCE = 1.15
#: Default number of blocks of s.
DEFAULT_BLOCKS = 5

Verdict = Literal["adequate", "missing", "unexplained"]


@dataclass(frozen=True)
class WeldDiagnosis:
    """Verdict on a weld, with the candidates and what the weld can identify.

    Attributes:
        verdict: ``adequate``, ``missing`` or ``unexplained``.
        message: One sentence for the user.
        sigma: Noise floor [m].
        rms: RMS residual of the model as it is [m] (its held-out RMS too: nothing is fitted).
        heldout_rms: Held-out RMS of the model as it is [m].
        candidates: Scored candidates, lowest held-out RMS first.
        ties: Candidates the weld cannot tell from the named one.
        identifiability: What the weld identifies.
        skipped: (label, why) of the candidates that could not be fitted.
        best: The named candidate (simplest among the best and its ties), or None.
    """

    verdict: Verdict
    message: str
    sigma: float
    rms: float
    heldout_rms: float
    candidates: tuple[Candidate, ...]
    ties: tuple[str, ...]
    identifiability: Identifiability
    skipped: tuple[tuple[str, str], ...] = ()
    best: Candidate | None = None

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary (mm)."""
        return {"verdict": self.verdict, "message": self.message,
                "noise_floor_mm": self.sigma * 1e3, "rms_mm": self.rms * 1e3,
                "heldout_rms_mm": self.heldout_rms * 1e3,
                "best": None if self.best is None else self.best.label,
                "indistinguishable_from_best": list(self.ties),
                "identifiability": self.identifiability.to_json(),
                "candidates": [c.to_json() for c in self.candidates],
                "skipped": [{"label": a, "reason": b} for a, b in self.skipped]}


def describe(c: Candidate) -> str:
    """The candidate with its fitted values, e.g. ``joint_compliance:j1 (joint 1 stiffness
    x0.801)``; an implausible fit says so."""
    k = c.stiffness_scale
    if k is not None:
        text = f"{c.label} (joint {c.joint} stiffness x{k:.3f})"
    else:
        text = c.label + " (" + ", ".join(f"{n} {v:.4g}" for n, v in c.params.items()) + ")"
    return text + (" [implausible]" if not c.plausible else "")


def _sigma(obs: WeldObservations, s: FloatArray, r0: FloatArray) -> float:
    """Noise floor of the stacked residual: RMS of each component's successive-difference
    floor [m]."""
    n = obs.n_points
    return float(np.sqrt(np.mean([noise_floor(s, r0[k * n:(k + 1) * n]) ** 2
                                  for k in range(obs.n_comp)])))


def _fits(model: ElastostaticModel, obs: WeldObservations, labels: Sequence[str]
          ) -> tuple[list[WeldFit], list[tuple[str, str]]]:
    """Every candidate fitted to the weld, and (label, why) of those that could not be."""
    fits: list[WeldFit] = []
    skipped: list[tuple[str, str]] = []
    for label in progress(labels, desc="candidates", unit="cand"):
        try:
            fit = fit_form(obs, candidate_form(model, label))
        except (InputError, IdentificationError, np.linalg.LinAlgError, ValueError) as exc:
            skipped.append((label, str(exc)))
            continue
        if not np.all(np.isfinite(fit.residual)):
            skipped.append((label, "the fit diverged"))
            continue
        fits.append(fit)
    return fits, skipped


def _scored(fit: WeldFit, r0: FloatArray, sigma: float, n_tests: int
            ) -> tuple[Candidate, FloatArray]:
    """The scored candidate of one fit and its change columns."""
    form, theta = fit.form, fit.theta
    vis = visibility(fit, sigma)
    admissible = form.admissible(theta)
    c = score(
        form.label, form.effect, form.joint, sse_before=float(r0 @ r0),
        sse_after=float(fit.heldout @ fit.heldout), n_obs=r0.size, n_free=theta.size,
        n_params=theta.size, n_tests=n_tests, admissible=admissible,
        params=form.split(theta), prior=form.split(form.theta0), fit_rms=rms(fit.residual),
        implausible=form.implausible(theta), refit=form.refit, identifiable=vis.identifiable,
        relative_std=dict(zip(form.names, map(float, vis.relative_std), strict=True)),
        notes=() if admissible else ("fitted value is not physical",))
    return replace(c, visible=vis.visible or c.significant), vis.change


def _verdict(r0: FloatArray, sigma: float, best: Candidate | None, ties: Sequence[str]
             ) -> tuple[Verdict, str]:
    """The verdict and its one-line message (module docstring)."""
    rms0 = rms(r0)
    chi_p = float(special.chdtrc(r0.size, float(r0 @ r0) / max(sigma, 1e-15) ** 2))
    if rms0 <= NOISE_TOLERANCE * sigma or chi_p >= ALPHA:
        return "adequate", (f"adequate: RMS {rms0 * 1e3:.4f} mm against a noise floor of "
                            f"{sigma * 1e3:.4f} mm (the model explains the weld)")
    if best is not None and best.rms_after <= NOISE_TOLERANCE * sigma:
        msg = (f"missing: {describe(best)} brings the held-out RMS from {rms0 * 1e3:.4f} to "
               f"{best.rms_after * 1e3:.4f} mm (noise floor {sigma * 1e3:.4f} mm)")
        if ties:
            msg += (f"; this weld cannot tell it from {', '.join(ties[:6])}"
                    f"{' ...' if len(ties) > 6 else ''} (they explain it as well)")
        return "missing", msg
    msg = f"unexplained: RMS {rms0 * 1e3:.4f} mm, noise floor {sigma * 1e3:.4f} mm; "
    if best is not None:
        msg += (f"the best candidate {describe(best)} lowers the held-out RMS only to "
                f"{best.rms_after * 1e3:.4f} mm")
    else:
        msg += "no library effect or joint stiffness explains it significantly"
    return "unexplained", msg


def diagnose_weld(
    model: ElastostaticModel, samples: WeldSamples, track: TrackOnSeam, reference: str,
    labels: Sequence[str] | None = None, blocks: int = DEFAULT_BLOCKS,
) -> WeldDiagnosis:
    """Which candidate explains the residual of the weld (module docstring).

    Args:
        model: The current robot model.
        samples: The executed plan at the track points.
        track: The measured track.
        reference: The problem's seam reference.
        labels: Candidates (default: :func:`candidate_labels` with the joint stiffnesses).
        blocks: Blocks of s of the cross-validation.

    Raises:
        InputError: Fewer than 2 blocks or fewer points than 4 per block.
    """
    if blocks < 2:
        raise InputError("blocks", "", f"{blocks}", "at least 2")
    if track.s.size < 4 * blocks:
        raise InputError("track", "", f"{track.s.size} points on the seam",
                         f"at least {4 * blocks} for {blocks} blocks of s")
    obs = WeldObservations(samples, track, reference, blocks)
    r0 = obs.y - obs.predict(model)
    sigma = _sigma(obs, track.s, r0)
    labels = list(labels) if labels is not None else candidate_labels(model,
                                                                       joint_stiffness=True)
    fits, skipped = _fits(model, obs, labels)
    scored = [_scored(f, r0, sigma, max(len(fits), 1)) for f in fits]
    ranked = rank([c for c, _ in scored], lambda c: c.rms_after <= NOISE_TOLERANCE * sigma)
    best = named(ranked)
    ties = tuple(ties_of(ranked, best)) if best is not None else ()
    ident = assess(ranked, {c.label: ch for c, ch in scored}, stiffness_labels(model), sigma)
    verdict, msg = _verdict(r0, sigma, best, ties)
    return WeldDiagnosis(verdict, msg, sigma, rms(r0), rms(r0), ranked, ties, ident,
                         tuple(skipped), best)


__all__ = ["DEFAULT_BLOCKS", "NOISE_TOLERANCE", "WeldDiagnosis", "describe", "diagnose_weld"]
