"""The validate -> add -> re-identify loop of the model-against-measurement workbench.

:func:`validate` compares a model with measurements: it predicts every sample, analyses the
residual (:mod:`rfsw_plan.validation.engine.residuals`), optionally adds effects and re-identifies
all parameters (scoring before/after on held-out folds), and always runs the diagnosis
(:mod:`rfsw_plan.validation.engine.diagnosis`) on the resulting model. :func:`save_extended_robot`
writes the re-identified model as a robot description that ``predict`` and the planner load
with its effects.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.effects import make_effect, parse_effect_label
from rfsw_plan.elastostatics.effects.base import PoseBatch
from rfsw_plan.elastostatics.identification import IdentificationResult
from rfsw_plan.elastostatics.identification_blocks import predicted_positions
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.elastostatics.registration import DeviceSetup
from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.description import DeviceFrame
from rfsw_plan.validation.derived_robot import save_derived_robot
from rfsw_plan.validation.engine.diagnosis import (
    DEFAULT_FOLDS,
    CrossValidation,
    Diagnosis,
    Skipped,
    cross_validate,
    diagnose,
    make_folds,
)
from rfsw_plan.validation.engine.residuals import (
    ResidualAnalysis,
    analyze_residuals,
    estimate_noise_floor,
)


@dataclass(frozen=True)
class AddResult:
    """Outcome of adding effects and re-identifying everything.

    Attributes:
        requested: Effect labels asked for.
        added: Effects actually added.
        not_added: Effects not added, with the reason: the effect says the data cannot
            identify it, or identification kept all its parameters at their priors.
        before: Held-out score of the model before adding.
        after: Held-out score of the extended model (its fit is the re-identified model).
        rms_before: RMS residual of the model as given, all samples [m].
        rms_after: RMS residual of the re-identified extended model, all samples [m].
    """

    requested: tuple[str, ...]
    added: tuple[str, ...]
    not_added: tuple[Skipped, ...]
    before: CrossValidation = field(repr=False)
    after: CrossValidation = field(repr=False)
    rms_before: float
    rms_after: float

    def to_json(self) -> dict[str, Any]:
        """JSON form (mm)."""
        return {
            "requested": list(self.requested),
            "added": list(self.added),
            "not_added": [{"label": s.label, "reason": s.reason} for s in self.not_added],
            "heldout_rms_before_mm": self.before.heldout_rms * 1e3,
            "heldout_rms_after_mm": self.after.heldout_rms * 1e3,
            "rms_before_mm": self.rms_before * 1e3,
            "rms_after_mm": self.rms_after * 1e3,
            "parameters": [
                {"effect": e.effect, "name": e.name, "value": e.value, "prior": e.prior,
                 "std_error": None if np.isnan(e.std_error) else e.std_error,
                 "identified": e.identified, "note": e.note}
                for e in self.after.fit.estimates
            ],
        }


@dataclass(frozen=True)
class ValidationResult:
    """Everything ``rfsw-plan validate`` computed.

    Attributes:
        robot: Robot name.
        data_source: Measurement file.
        model: The evaluated model: the given one, or the re-identified extended one when
            effects were added.
        rms: RMS residual of ``model`` on all samples [m].
        analysis: Residual analysis of ``model`` on all samples.
        diagnosis: Diagnosis of ``model``'s form.
        identification: ``model``'s form re-identified on all samples (what --save-robot
            writes).
        add: The add-and-re-identify step, if effects were added.
        seconds: Wall time [s].
        setup: How device-frame data was registered (None for base-frame data).
        device_frame: The registration and marker offset used: fitted on this data (folded
            from the identification) or held as given; None for base-frame data.
    """

    robot: str
    data_source: str
    model: ElastostaticModel = field(repr=False)
    rms: float
    analysis: ResidualAnalysis = field(repr=False)
    diagnosis: Diagnosis
    identification: IdentificationResult = field(repr=False)
    add: AddResult | None = None
    seconds: float = 0.0
    setup: DeviceSetup | None = field(default=None, repr=False)
    device_frame: DeviceFrame | None = None
    dialect: str = ""

    @property
    def rms_3d(self) -> float:
        """RMS over samples of the 3-D position error |measured - predicted| [m] (samples
        measured in all three axes); what motion-capture calibration papers quote."""
        return self.analysis.rms_3d

    @property
    def verdict(self) -> str:
        """The diagnosis verdict."""
        return self.diagnosis.verdict

    def to_json(self) -> dict[str, Any]:
        """The JSON object of ``validate --json`` and ``validate.json`` (lengths in mm)."""
        d = self.diagnosis
        noise = d.noise
        return {
            "robot": self.robot,
            "data": self.data_source,
            "model_effects": list(self.model.labels),
            "rms_mm": self.rms * 1e3,
            "rms_3d_mm": None if not np.isfinite(self.rms_3d) else self.rms_3d * 1e3,
            "frame": "base" if self.setup is None else "device",
            "dialect": self.dialect,
            "device_frame": None if self.device_frame is None else device_frame_json(
                self.device_frame, self.setup),
            "heldout_rms_mm": d.heldout_rms * 1e3,
            "refit_rms_mm": self.identification.rms_after * 1e3,
            "noise_floor_mm": None if noise.sigma is None else noise.sigma * 1e3,
            "noise_source": noise.source,
            "verdict": d.verdict,
            "message": d.message,
            "missing": d.to_json()["missing"],
            "candidates": [c.to_json() for c in d.candidates],
            "not_identifiable": [{"label": s.label, "reason": s.reason} for s in d.skipped],
            "correlations": d.to_json()["correlations"],
            "diagnosis": d.to_json(),
            "residuals": self.analysis.to_json(),
            "add": None if self.add is None else self.add.to_json(),
            "folds": d.folds,
            "n_samples": self.analysis.n_samples,
            "seconds": self.seconds,
        }


def device_frame_json(frame: DeviceFrame, setup: DeviceSetup | None) -> dict[str, Any]:
    """JSON form of a registration (mm, deg; the base frame seen from the device)."""
    from rfsw_plan.robot.description import _matrix_to_rpy

    return {
        "base_in_device_xyz_mm": [float(v) for v in frame.translation * 1e3],
        "base_in_device_rpy_deg": [float(v) for v in np.degrees(_matrix_to_rpy(frame.rotation))],
        "marker_xyz_mm": [float(v) for v in frame.marker * 1e3],
        "std": dict(frame.std),
        "registration": "fitted" if setup is not None and setup.fit_registration else "held",
        "marker": "fitted" if setup is not None and setup.fit_marker else "held",
    }


def check_effect_labels(model: ElastostaticModel, labels: Sequence[str]) -> list[str]:
    """Validate effect labels to add (name known, joint in range, not already in the model).

    Raises:
        UnknownNameError: Unknown effect name (lists the known ones).
        InputError: Joint index missing / out of range, effect given twice or already in the
            model.
    """
    out: list[str] = []
    for raw in labels:
        cls, joint = parse_effect_label(raw, model.robot.nq)
        label = cls.name if joint is None else f"{cls.name}:j{joint + 1}"
        if model.has(label):
            raise InputError("add", label, "effect is already in the model",
                             f"one of the effects it lacks (it has {', '.join(model.labels)})")
        if label in out:
            raise InputError("add", label, "given more than once")
        out.append(label)
    return out


def _rms(res: np.ndarray) -> float:
    r = res[np.isfinite(res)]
    return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")


def validate(
    model: ElastostaticModel,
    data: MeasurementSet,
    *,
    noise_m: float | None = None,
    add: Sequence[str] = (),
    folds: int = DEFAULT_FOLDS,
    seed: int = 0,
    setup: DeviceSetup | None = None,
    force_noise_n: float | None = None,
) -> ValidationResult:
    """Compare a model with measurements, optionally add effects, and diagnose what is missing.

    Args:
        model: The model of the robot file (its effects are never suggested again).
        data: Samples with joint values, logged wrench (TCP, base frame) and measured TCP
            position (base frame).
        noise_m: Noise floor given by the user [m] (default: from repeated samples).
        add: Effect labels (``name`` or ``name:jN``) to add before re-identifying.
        folds: Cross-validation folds.
        seed: Seed of the fold assignment.
        force_noise_n: Force sensor noise [N] (default: from zero-load readings); its effect
            through the compliance is part of the noise floor.
        setup: For device-frame data (:func:`~rfsw_plan.elastostatics.registration.
            prepare_device_setup`): the registration and marker offset are held or fitted
            jointly with every other parameter, in every fold.

    Raises:
        IdentificationError: Too few samples/poses for what was asked (says how many).
        UnknownNameError, InputError: Bad effect label, bad noise, mismatched joints.
    """
    t0 = time.perf_counter()
    model, data = _registered(model, data, setup)
    labels = check_effect_labels(model, add)
    batch = model.batch_of(data, force_noise_n)
    pred = predicted_positions(model, batch, data.wrench)
    residual0 = np.where(data.measured, data.position - pred, np.nan)
    noise = estimate_noise_floor(data, residual0, noise_m, model=model,
                                 force_noise_n=force_noise_n, batch=batch)
    fold = make_folds(data, folds, seed)
    before = cross_validate(model, data, fold, batch)
    add_result = (_add_effects(model, data, fold, batch, labels, before, _rms(residual0))
                  if labels else None)
    base = before if add_result is None else add_result.after
    evaluated = base.fit.model if add_result is not None else model
    analysis = analyze_residuals(evaluated, data, noise=noise, batch=batch)
    diagnosis = diagnose(evaluated, data, noise, folds, seed, batch=batch, base=base)
    return ValidationResult(
        robot=model.robot.name,
        data_source=data.source,
        model=evaluated,
        rms=analysis.rms,
        analysis=analysis,
        diagnosis=diagnosis,
        identification=base.fit,
        add=add_result,
        seconds=time.perf_counter() - t0,
        setup=setup,
        device_frame=_device_frame(setup, base),
        dialect=data.dialect or "in memory",
    )


def _registered(model: ElastostaticModel, data: MeasurementSet, setup: DeviceSetup | None
                ) -> tuple[ElastostaticModel, MeasurementSet]:
    """The model and data with the device set-up applied, checked to match."""
    if setup is None and data.frame != "base":
        raise InputError(data.source, "frame", f"positions are in the {data.frame} frame",
                         "a device set-up (rfsw-plan validate --frame device)")
    if setup is not None:
        model = setup.model(model)
        data = setup.data(data)
    if data.n_joints != model.robot.nq:
        raise InputError(data.source, "joint columns",
                         f"data has {data.n_joints} joints but robot {model.robot.name} has "
                         f"{model.robot.nq}", f"{model.robot.nq} joint columns")
    return model, data


def _device_frame(setup: DeviceSetup | None, base: CrossValidation) -> DeviceFrame | None:
    """The registration used: as held, or folded from the identification where fitted."""
    if setup is None:
        return None
    if setup.fit_registration or setup.fit_marker:
        return setup.fold(base.fit.model, base.fit.estimates)[1]
    return setup.frame


def _with_effects(model: ElastostaticModel, labels: Sequence[str]) -> ElastostaticModel:
    for label in labels:
        model = model.with_effect(label)
    return model


def _unidentified(after: CrossValidation, labels: Sequence[str]) -> list[Skipped]:
    """The added effects none of whose parameters the data identified."""
    out = []
    for label in labels:
        est = [e for e in after.fit.estimates if e.effect == label]
        if not any(e.identified for e in est):
            why = next((e.note for e in est if e.note), "no parameter identified")
            out.append(Skipped(label, f"not identified from this data: {why}"))
    return out


def _add_effects(
    model: ElastostaticModel, data: MeasurementSet, fold: NDArray[np.int_], batch: PoseBatch,
    labels: Sequence[str], before: CrossValidation, rms_before: float,
) -> AddResult:
    """Add the effects the data can identify, re-identify everything and score it on the same
    folds. An effect the data cannot fit would only carry its prior: it is left out."""
    F_true = model.true_wrench(batch, data.wrench)
    not_added: list[Skipped] = []
    added: list[str] = []
    for label in labels:
        reason = make_effect(model.robot, label).identifiable(batch, F_true)
        if reason:
            not_added.append(Skipped(label, f"not identifiable from this data: {reason}"))
        else:
            added.append(label)
    after = cross_validate(_with_effects(model, added), data, fold, batch) if added else before
    dropped = _unidentified(after, added)
    if dropped:
        not_added += dropped
        added = [x for x in added if x not in {s.label for s in dropped}]
        after = (cross_validate(_with_effects(model, added), data, fold, batch) if added
                 else before)
    return AddResult(requested=tuple(labels), added=tuple(added), not_added=tuple(not_added),
                     before=before, after=after, rms_before=rms_before,
                     rms_after=after.fit.rms_after)


def save_extended_robot(result: ValidationResult, path: str | Path,
                        name: str | None = None) -> Path:
    """Write the re-identified model (stiffness and effects) as a robot description TOML.

    The file keeps the robot's kinematics and limits; it gets a new name (``name``, or the
    parent's name plus the added effects, e.g. ``zk500+payload_gravity``) and a
    ``[provenance]`` table: the parent robot file, the data file and its SHA-256, the date.
    ``predict`` and the planner load its ``[[effects]]`` through
    :class:`~rfsw_plan.elastostatics.model.ElastostaticModel`.
    """
    fit = result.identification
    note = (
        f"re-identified by rfsw-plan validate from {result.data_source} "
        f"({fit.n_samples} samples, RMS {fit.rms_after * 1e3:.4g} mm, effects: "
        f"{', '.join(fit.model.labels)})"
    )
    device_note = (
        f"identified by rfsw-plan validate --frame device from {result.data_source} "
        f"({fit.n_samples} samples), jointly with "
        f"{', '.join(e.label for e in fit.model.effects if not e.setup)}")
    return save_derived_robot(fit.model, path, parent=result.model.robot.description, note=note,
                              data=result.data_source, command="rfsw-plan validate", name=name,
                              setup=result.setup, estimates=fit.estimates,
                              device_note=device_note)
