"""``validate-weld --add``: candidates added to the model and fitted jointly to the weld."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import IdentificationError
from rfsw_plan.validation.engine.candidates import candidate_form, joint_form, parts_of
from rfsw_plan.validation.weld.diagnosis import DEFAULT_BLOCKS
from rfsw_plan.validation.weld.fit import WeldObservations, fit_form, rms
from rfsw_plan.validation.weld.samples import WeldSamples
from rfsw_plan.validation.weld.track import TrackOnSeam


@dataclass(frozen=True)
class WeldAddResult:
    """``--add``: the candidates fitted jointly to the weld.

    Attributes:
        labels: What was added.
        model: The re-identified model.
        params: Fitted parameters by label [SI].
        rms_before: RMS residual (lateral, and normal if measured) of the model as given [m].
        rms_after: RMS residual of the re-identified model [m].
        heldout_before: Held-out RMS of the model as given (nothing fitted: its RMS) [m].
        heldout_after: Held-out RMS of the re-identified model over blocks of s [m].
    """

    labels: tuple[str, ...]
    model: ElastostaticModel
    params: dict[str, dict[str, float]]
    rms_before: float
    rms_after: float
    heldout_before: float
    heldout_after: float

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {"added": list(self.labels), "params": self.params,
                "rms_before_mm": self.rms_before * 1e3, "rms_after_mm": self.rms_after * 1e3,
                "heldout_rms_before_mm": self.heldout_before * 1e3,
                "heldout_rms_after_mm": self.heldout_after * 1e3,
                "stiffness_N_m_per_rad": [float(x) for x in self.model.stiffness]}


def add_and_identify(
    model: ElastostaticModel, samples: WeldSamples, track: TrackOnSeam, reference: str,
    labels: Sequence[str], blocks: int = DEFAULT_BLOCKS,
) -> WeldAddResult:
    """Add the candidates and fit their parameters jointly to the weld.

    Raises:
        InputError: Unknown or duplicated label, a label already in the model.
        IdentificationError: The fit gives a value outside the effect's physical range (e.g. a
            negative compliance).
    """
    forms = [candidate_form(model, lab) for lab in labels]
    joint = joint_form(forms)
    obs = WeldObservations(samples, track, reference, blocks)
    r0 = obs.y - obs.predict(model)
    fit = fit_form(obs, joint)
    parts = parts_of(forms, fit.theta)
    for f, theta in zip(forms, parts, strict=True):
        if not f.admissible(theta):
            raise IdentificationError(
                f"`add` {f.label}: the weld fits a value outside its physical range "
                f"({f.implausible(theta)}); this effect does not explain the weld")
    params = {f.label: f.split(theta) for f, theta in zip(forms, parts, strict=True)}
    return WeldAddResult(tuple(labels), joint.build(fit.theta), params, rms(r0),
                         rms(fit.residual), rms(r0), rms(fit.heldout))


__all__ = ["WeldAddResult", "add_and_identify"]
