"""The one scoring of a diagnosis: held-out F test, ranking, ties, and the candidate it names.

Every candidate (:mod:`rfsw_plan.validation.engine.candidates`) is fitted and cross-validated
(:mod:`rfsw_plan.validation.engine.crossval`) by the command's own prediction: the pose model on a
load campaign (``validate``), the executed pin path on a weld (``validate-weld``). From the
held-out sums of squares this module decides, the same way for both:

* *explains something*: held-out F = ((SSE_0 - SSE_1) / p) / (SSE_1 / (n - P_1)) against
  F(p, n - P_1), p the candidate's fitted parameters, P_1 all fitted parameters of the
  extended model; significant when p-value < ALPHA / (number of candidates), the error fell,
  and the fitted values are inside the effect's physical range (``param_ranges``). An effect
  fitted to noise does not lower the held-out error, so noise does not name an effect.
* *ranking*: by held-out RMS, lowest first.
* *ties*: a candidate the data cannot tell from the best: its held-out SSE is within the F
  test at TIE_LEVEL of the best's, or it and the first candidate that may be named
  (significant and plausible) both bring the held-out residual to the noise floor.
* *the named candidate*: among the best and the candidates tied with it that are significant
  and plausible, the simplest (fewest parameters, then identifiable alone, then lowest held-out
  RMS): a richer effect that fits as well is no evidence for itself.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy import special  # the distributions' tails (scipy.stats costs ~0.9 s more CPU to import)

#: Significance level of every test (family-wise over the candidates compared).
ALPHA = 1e-3
#: Level of the F test below which a candidate is "indistinguishable" from the best one.
TIE_LEVEL = 0.05


@dataclass(frozen=True)
class Candidate:
    """One candidate scored on held-out data.

    Attributes:
        label: ``name`` or ``name:jN``.
        effect: Effect name.
        joint: 1-based joint, or None.
        rms_before: Held-out RMS of the model it was added to [m].
        rms_after: Held-out RMS with the candidate fitted [m].
        explained_fraction: 1 - MSE_after / MSE_before of the held-out residual (negative
            when the candidate makes the prediction worse).
        f_stat: Held-out F statistic of the improvement.
        p_value: Its p-value.
        significant: p_value below ALPHA / number of candidates, the error fell, and the
            fitted values are admissible.
        n_params: Fitted parameters of the candidate.
        params: Fitted parameters [SI].
        notes: Notes of the fit (why a parameter was not identified, implausible values).
        sse: Held-out sum of squared residuals [m^2].
        dof: Residual degrees of freedom of the extended model (observations - all fitted
            parameters).
        tied_with_best: The data cannot tell it from the best candidate (module docstring).
        std: Standard error of each fitted parameter [SI].
        prior: Parameters before the fit [SI].
        fit_rms: RMS residual of the fit on all observations [m] (NaN if not computed).
        admissible: Every fitted value is inside the effect's ``param_ranges``.
        implausible: Why the fitted values are not plausible on a real cell ('' if they are).
        refit: True if the candidate re-fits a parameter of the model (a joint stiffness).
        visible: The data sees the candidate (a weld: a 20 % change moves the track by more
            than 3 sigma, or it is significant); None where not assessed.
        identifiable: Every parameter's standard error is small against its size (a weld);
            None where not assessed.
        relative_std: Standard error / size per parameter [-] (a weld).
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
    dof: int = 1
    tied_with_best: bool = False
    std: dict[str, float] = field(default_factory=dict)
    prior: dict[str, float] = field(default_factory=dict)
    fit_rms: float = float("nan")
    admissible: bool = True
    implausible: str = ""
    refit: bool = False
    visible: bool | None = None
    identifiable: bool | None = None
    relative_std: dict[str, float] = field(default_factory=dict)

    @property
    def plausible(self) -> bool:
        """Admissible, and plausible on a real cell."""
        return self.admissible and not self.implausible

    @property
    def eligible(self) -> bool:
        """May be named as the missing effect: significant and plausible."""
        return self.significant and self.plausible

    @property
    def stiffness_scale(self) -> float | None:
        """Fitted / prior stiffness of a re-fitted joint (compliance prior / fitted), else
        None."""
        if not self.refit or len(self.params) != 1:
            return None
        (k, v), = self.params.items()
        return self.prior[k] / v if v > 0 else float("inf")

    def to_json(self) -> dict[str, Any]:
        """JSON form (lengths in mm, parameters in SI)."""

        def num(x: float | None) -> float | None:
            return None if x is None or not np.isfinite(x) else float(x)

        return {
            "effect": self.effect,
            "joint": self.joint,
            "label": self.label,
            "rms_after_mm": self.rms_after * 1e3,
            "rms_before_mm": self.rms_before * 1e3,
            "fit_rms_mm": num(self.fit_rms * 1e3),
            "explained_fraction": self.explained_fraction,
            "f_stat": num(self.f_stat),
            "p_value": self.p_value,
            "significant": self.significant,
            "n_params": self.n_params,
            "params": self.params,
            "prior": self.prior,
            "std_error": {k: num(v) for k, v in self.std.items()},
            "stiffness_scale": num(self.stiffness_scale),
            "admissible": self.admissible,
            "plausible": self.plausible,
            "implausible": self.implausible or None,
            "visible": self.visible,
            "identifiable": self.identifiable,
            "relative_std": {k: num(v) for k, v in self.relative_std.items()},
            "notes": list(self.notes),
            "tied_with_best": self.tied_with_best,
        }


def improvement(
    sse_before: float, sse_after: float, n_params: int, dof: int, n_tests: int
) -> tuple[float, float, bool]:
    """Held-out F test of a candidate against the model it was added to (module docstring).

    Args:
        sse_before: Held-out SSE of the model [m^2].
        sse_after: Held-out SSE with the candidate [m^2].
        n_params: Fitted parameters of the candidate.
        dof: Observations minus all fitted parameters of the extended model.
        n_tests: Number of candidates compared (Bonferroni).

    Returns:
        (F, p-value, significant before the admissibility check).
    """
    dof = max(dof, 1)
    gain = sse_before - sse_after
    if n_params <= 0 or gain <= 0:
        return (float(gain / max(n_params, 1) / (sse_after / dof)) if sse_after > 0 else 0.0,
                1.0, False)
    F = (gain / n_params) / (sse_after / dof) if sse_after > 0 else float("inf")
    p = float(special.fdtrc(n_params, dof, F)) if np.isfinite(F) else 0.0
    return float(F), p, p < ALPHA / max(n_tests, 1)


def score(
    label: str, effect: str, joint: int | None, *, sse_before: float, sse_after: float,
    n_obs: int, n_free: int, n_params: int, n_tests: int, admissible: bool = True,
    **fields: Any,
) -> Candidate:
    """A scored :class:`Candidate` from the held-out sums of squares of the model before and
    after adding it (``fields``: the other attributes of :class:`Candidate`)."""
    dof = max(n_obs - n_free, 1)
    F, p, sig = improvement(sse_before, sse_after, n_params, dof, n_tests)
    mse0 = sse_before / max(n_obs, 1)
    mse1 = sse_after / max(n_obs, 1)
    return Candidate(
        label=label, effect=effect, joint=joint,
        rms_before=float(np.sqrt(mse0)), rms_after=float(np.sqrt(mse1)),
        explained_fraction=float(1.0 - mse1 / mse0) if mse0 > 0 else 0.0,
        f_stat=F, p_value=p, significant=bool(sig and admissible), n_params=n_params,
        sse=sse_after, dof=dof, admissible=admissible, **fields)


def rank(
    candidates: Sequence[Candidate], at_floor: Callable[[Candidate], bool] | None = None
) -> tuple[Candidate, ...]:
    """Candidates sorted by held-out RMS, each marked whether the data can tell it from the
    best (module docstring).

    Args:
        candidates: Scored candidates.
        at_floor: Whether a candidate's held-out residual is at the noise floor (None: the
            floor is unknown; only the F test decides ties).
    """
    ranked = sorted(candidates, key=lambda c: c.rms_after)
    if not ranked:
        return ()
    best = ranked[0]
    crit = float(special.fdtri(1, best.dof, 1.0 - TIE_LEVEL))
    s2 = best.sse / best.dof
    lead = _lead(ranked)
    lead_floor = at_floor is not None and lead is not None and at_floor(lead)

    def tied(c: Candidate) -> bool:
        by_f = s2 > 0 and (c.sse - best.sse) / s2 < crit
        by_floor = lead_floor and c.eligible and at_floor is not None and at_floor(c)
        return bool(by_f or by_floor)

    return (best, *(replace(c, tied_with_best=tied(c)) for c in ranked[1:]))


def _lead(ranked: Sequence[Candidate]) -> Candidate | None:
    """The first candidate in held-out order that may be named."""
    return next((c for c in ranked if c.eligible), None)


def _group(ranked: Sequence[Candidate]) -> list[Candidate]:
    """The best, the first candidate that may be named, and their ties, in held-out order."""
    lead = _lead(ranked)
    return [c for i, c in enumerate(ranked) if i == 0 or c.tied_with_best or c is lead]


def named(ranked: Sequence[Candidate]) -> Candidate | None:
    """The candidate a diagnosis names (module docstring), or None if none is significant and
    plausible.

    Args:
        ranked: Candidates as :func:`rank` returns them.
    """
    group = [c for c in _group(ranked) if c.eligible]
    if not group:
        return None
    return min(group, key=lambda c: (c.n_params, c.identifiable is False, c.rms_after))


def ties_of(ranked: Sequence[Candidate], chosen: Candidate) -> list[str]:
    """Labels of the significant candidates the data cannot tell from ``chosen`` (the best and
    its ties, ``chosen`` left out)."""
    return [c.label for c in _group(ranked) if c.significant and c.label != chosen.label]


__all__ = ["ALPHA", "TIE_LEVEL", "Candidate", "improvement", "named", "rank", "score",
           "ties_of"]
