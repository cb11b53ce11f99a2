"""``rfsw-plan identify``: joint stiffness (and effect parameters) from a measurement file.

Least squares on measured TCP positions (seed 000 eq. 13-15, seed 001 eq. 8-11; see
:func:`rfsw_plan.elastostatics.identification.identify`), after the sanity checks of the data
(:func:`~rfsw_plan.validation.sanity.prepare_data`), optionally written as a new robot file
(:func:`~rfsw_plan.validation.derived_robot.save_derived_robot`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.identification import IdentificationResult, identify
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import IdentificationError, UnknownNameError
from rfsw_plan.robot.description import DeviceFrame
from rfsw_plan.validation.derived_robot import save_derived_robot
from rfsw_plan.validation.sanity import prepare_data


def _num(x: float) -> float | None:
    return None if not math.isfinite(x) else float(x)


@dataclass(frozen=True)
class IdentifiedRobot:
    """Outcome of :func:`identify_robot`.

    Attributes:
        robot: Robot name.
        result: The identification.
        output: The robot file written, or None.
    """

    robot: str
    result: IdentificationResult
    output: Path | None

    def to_json(self) -> dict[str, Any]:
        """The JSON object of ``identify --json`` (stiffness in N m/rad, lengths in mm)."""
        res = self.result
        base = res.model.joint_compliance.label
        jc = [e for e in res.estimates if e.effect == base]
        joints = []
        for j in range(res.stiffness.size):
            note = next((e.note for e in jc if e.name == f"c{j + 1}"), "not free in this fit")
            joints.append({
                "joint": j + 1,
                "stiffness_Nm_per_rad": float(res.stiffness[j]),
                "std_error_Nm_per_rad": _num(float(res.stiffness_std[j])),
                "identified": bool(res.joint_identified[j]),
                "note": note,
            })
        others = [
            {"effect": e.effect, "param": e.name, "value": e.value, "prior": e.prior,
             "std_error": _num(e.std_error), "identified": e.identified, "note": e.note}
            for e in res.estimates if e.effect != base
        ]
        return {
            "robot": self.robot,
            "method": res.method,
            "joints": joints,
            "effects": others,
            "condition_number": _num(res.condition_number),
            "rms_before_mm": res.rms_before * 1e3,
            "rms_after_mm": res.rms_after * 1e3,
            "sigma_mm": res.sigma * 1e3,
            "n_samples": res.n_samples,
            "n_observations": res.n_observations,
            "converged": res.converged,
            "output": None if self.output is None else str(self.output),
        }


def identify_robot(
    model: ElastostaticModel, data: MeasurementSet, *, method: Literal["ols", "wls"] = "ols",
    free: Sequence[str] | None = None, held: DeviceFrame | None = None,
    marker: FloatArray | None = None, output: str | Path | None = None,
    name: str | None = None,
) -> IdentifiedRobot:
    """Check the data, identify, and optionally write the identified robot file.

    Args:
        model: The robot file's model (its values are the priors).
        data: The measurements.
        method: ``ols`` or ``wls``.
        free: Effect labels to identify (None: every effect); device-frame set-up effects are
            added.
        held: A known registration of device-frame data (held, not fitted).
        marker: A known marker offset in the tool frame [m], shape (3,).
        output: Robot file to write (None: none).
        name: Robot name in that file (default: the parent's plus what was added).

    Raises:
        UnknownNameError: A free effect the model does not have.
        InputError: Data that cannot belong to this robot in these units.
        IdentificationError: The fit gave non-finite values (nothing is written).
    """
    unknown = [x for x in free or [] if not model.has(x)]
    if unknown:
        raise UnknownNameError("effect in the model", unknown[0], model.labels)
    setup = prepare_data(model, data, held, marker)
    fit_model, fit_data = model, data
    if setup is not None:
        fit_model, fit_data = setup.model(model), setup.data(data)
        if free is not None:
            free = [*free, *setup.effect_labels]
    res = identify(fit_model, fit_data, method=method, free=None if free is None else list(free))
    if not (math.isfinite(res.rms_after) and all(math.isfinite(e.value)
                                                 for e in res.estimates)):
        raise IdentificationError(f"{data.source}: the fit gave non-finite values; nothing "
                                  "written")
    written = None
    if output is not None:
        desc = model.robot.description
        note = (f"identified by rfsw-plan identify ({res.method}, {res.n_samples} samples) "
                f"from {Path(data.source).name}; prior: "
                f"{desc.sources.get('stiffness', 'not stated')}")
        written = save_derived_robot(res.model, output, parent=desc, note=note,
                                     data=data.source, command="rfsw-plan identify", name=name,
                                     setup=setup, estimates=res.estimates)
    return IdentifiedRobot(model.robot.name, res, written)


__all__ = ["IdentifiedRobot", "identify_robot"]
