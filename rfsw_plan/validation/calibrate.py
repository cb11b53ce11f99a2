"""``rfsw-plan calibrate``: from a robot file and measurement files to a calibrated robot file.

One job for any robot and any laser-tracker or motion-capture campaign (issue 34):

1. **Read** every ``--data`` file through the column map (CSV dialects, MATLAB files, several
   markers per pose: :mod:`rfsw_plan.io.measurements`) and check it against the robot
   (:func:`~rfsw_plan.validation.sanity.check_data`).
2. **Register** each file's device frame separately (closed-form start,
   :func:`~rfsw_plan.elastostatics.registration.estimate_device_frame`): a tracker set up anew
   for each series has its own frame, the marker on the tool is the same for all files.
3. **Choose the model on the training files only**: the geometry every real arm has (joint
   zero offsets, the links' own errors), then the workbench's forward selection
   (:func:`~rfsw_plan.validation.engine.diagnosis.forward_select`, the engine of ``validate``)
   adds effects under cross-validation by pose group (poses with equal joint values form one
   group, so repeats never sit on both sides of a split) until the held-out residual is at the
   noise floor or nothing significant is left (:func:`choose_effects`). With several markers
   per pose every marker is a row of the fit (:func:`marker_rows`), so the tool's rotation
   is fitted and selection, fit and score use the same quantity. With several files, each
   file's registration is estimated again with the chosen model (marker held) and the model
   refitted, :data:`REGISTRATION_ROUNDS` times.
4. **Score it held out**: leave one pose group out (``k``-fold by pose group beyond
   :data:`MAX_LOGO_GROUPS` groups), the whole fit (registration included) redone without the
   group; the error is the 3-D distance of every marker (the markers' positions on the tool
   fitted on the training groups), pooled as an RMS (:attr:`CalibrationResult.heldout_rms`).
   Repeated poses give the repeatability and the ISO 9283 pose figures (:class:`Iso9283`).
5. **Write** the calibrated robot file: the robot with the chosen effects and a
   ``[device_frame]`` whose ``registration = "each_file"`` makes ``validate`` register the
   frame of any other file again, holding everything else.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch
from rfsw_plan.elastostatics.identification import IdentificationResult
from rfsw_plan.elastostatics.identification_blocks import identify_blocks, predicted_positions
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.elastostatics.registration import DeviceSetup, estimate_device_frame
from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.description import DeviceFrame
from rfsw_plan.validation.engine.crossval import (
    CrossValidation,
    cross_validate,
    make_folds,
)
from rfsw_plan.validation.engine.crossval import single_thread_numpy_blas as _single_thread
from rfsw_plan.validation.engine.diagnosis import Skipped
from rfsw_plan.validation.engine.residuals import estimate_noise_floor
from rfsw_plan.validation.sanity import check_data
from rfsw_plan.validation.workbench import check_effect_labels, device_frame_json

#: The geometry of a real arm, always fitted (not put to a vote): joint zeros and the links'
#: own errors (6 per link, FIGAROH's ``full_params``).
GEOMETRY = ("kinematic_offsets", "link_errors")
#: At most this many effects are added beyond the geometry.
MAX_EFFECTS = 4
#: Folds of the selection's cross-validation on the training files (by pose group).
SELECTION_FOLDS = 5
#: Up to this many pose groups the held-out figure leaves one group out at a time; beyond,
#: :data:`HELDOUT_FOLDS` folds by pose group.
MAX_LOGO_GROUPS = 60
HELDOUT_FOLDS = 10
#: Gauss-Newton steps of a held-out fold's refit of a model nonlinear in its parameters, from
#: the fit of all samples (the fold changes it by little: the linearisation there is exact to
#: first order in the change; a second step takes up the rest).
HELDOUT_STEPS = 2
#: Gauss-Newton steps of a candidate's fit in the selection, from the current model's fit with
#: the candidate at its prior (a linear model needs one); the chosen form is then fitted to
#: convergence.
SELECTION_STEPS = 3
#: At most this many alternations of per-file registration and model fit (several files),
#: stopped when no registration moves by more than FRAME_TOL_M.
REGISTRATION_ROUNDS = 40
FRAME_TOL_M = 1e-6
#: Joint values equal to this [rad or m] are one pose (one group).
GROUP_TOL = 1e-6


@dataclass(frozen=True)
class CalibrationRequest:
    """What ``rfsw-plan calibrate`` is asked.

    Attributes:
        robot: Bundled robot name or robot TOML file (the nominal model).
        data: Training measurement files (each with its own device frame).
        columns: Column map (``--columns``), or None for files in the documented format.
        frame: ``device`` or ``base`` (None: the map or the file says).
        geometry: Effects always fitted (default :data:`GEOMETRY`).
        max_effects: At most this many effects added by selection.
        folds: Folds of the selection's cross-validation.
        heldout_folds: Folds of the held-out figure (None: leave one pose group out up to
            :data:`MAX_LOGO_GROUPS` groups, else :data:`HELDOUT_FOLDS`).
        every: Keep every n-th pose group of each file (a deterministic subsample, 1 = all).
        keep_registration: The fitted registration holds for other files (a fixed
            motion-capture body); default: each file is registered anew.
        save_robot: Calibrated robot file to write (None: none).
        name: Robot name in that file.
        seed: Seed of the fold split.
        score: Other files scored with the calibrated model as ``validate`` scores them
            (:func:`score_file`), never used to choose or fit anything.
    """

    robot: str
    data: tuple[str, ...]
    columns: str | None = None
    frame: str | None = None
    geometry: tuple[str, ...] = GEOMETRY
    max_effects: int = MAX_EFFECTS
    folds: int = SELECTION_FOLDS
    heldout_folds: int | None = None
    every: int = 1
    keep_registration: bool = False
    save_robot: str | None = None
    name: str | None = None
    seed: int = 0
    score: tuple[str, ...] = ()

    def check(self) -> None:
        """Refuse impossible options (one line each)."""
        if not self.data:
            raise InputError("data", "", "no training file", "one or more in `data`")
        if len(set(self.data)) != len(self.data):
            raise InputError("data", "", "a file given twice", "each training file once")
        both = sorted(set(self.data) & set(self.score))
        if both:
            raise InputError("score", both[0], "is a training file too",
                             "files not given in `data` (held out)")
        if not 0 <= self.max_effects <= 10:
            raise InputError("max_effects", "", f"{self.max_effects}", "0 .. 10")
        if self.folds < 2:
            raise InputError("folds", "", f"{self.folds}", "at least 2")
        if self.heldout_folds is not None and self.heldout_folds < 2:
            raise InputError("heldout_folds", "", f"{self.heldout_folds}", "at least 2")
        if self.every < 1:
            raise InputError("every", "", f"{self.every}", "1 or more")


@dataclass(frozen=True)
class Iso9283:
    """ISO 9283-style pose figures of the tracked markers, per pose group [m].

    ``AP`` (pose accuracy, position part) is the distance between the barycentre of a group's
    measured positions and the held-out prediction of the calibrated model (the "commanded"
    pose of the standard is what the model says the joint values give); ``RP`` (pose
    repeatability) is ``l_mean + 3 S_l`` of the distances ``l_j`` of the repeats to their
    barycentre (groups with at least 3 repeats). Both over every marker of every group.
    """

    ap_mean: float
    ap_max: float
    rp_mean: float | None
    rp_max: float | None
    groups: int
    repeated_groups: int
    repeat_rms_3d: float | None

    def to_json(self) -> dict[str, Any]:
        def mm(v: float | None) -> float | None:
            return None if v is None else v * 1e3

        return {"AP_mean_mm": mm(self.ap_mean), "AP_max_mm": mm(self.ap_max),
                "RP_mean_mm": mm(self.rp_mean), "RP_max_mm": mm(self.rp_max),
                "pose_groups": self.groups, "repeated_groups": self.repeated_groups,
                "repeat_rms_3d_mm": mm(self.repeat_rms_3d)}


@dataclass(frozen=True)
class FileScore:
    """One training file: its registration and its fit."""

    source: str
    samples: int
    pose_groups: int
    frame: DeviceFrame | None
    fit_rms_3d: float
    heldout_rms_3d: float

    def to_json(self) -> dict[str, Any]:
        return {"data": self.source, "samples": self.samples, "pose_groups": self.pose_groups,
                "fit_rms_3d_mm": self.fit_rms_3d * 1e3,
                "heldout_rms_3d_mm": self.heldout_rms_3d * 1e3,
                "device_frame": None if self.frame is None else device_frame_json(
                    self.frame, None) | {"registration": "fitted", "marker": "fitted"}}


@dataclass(frozen=True)
class SelectionStep:
    """One step of the effect choice: the model form and its training cross-validation."""

    added: str
    cv_rms: float
    fit_rms: float | None

    def to_json(self) -> dict[str, Any]:
        return {"added": self.added, "training_cv_rms_mm": self.cv_rms * 1e3,
                "fit_rms_mm": None if self.fit_rms is None else self.fit_rms * 1e3}


@dataclass(frozen=True)
class CalibrationResult:
    """What :func:`run` computed.

    Attributes:
        request: The request.
        model: The calibrated robot model (its effects, no set-up effects).
        frames: Each training file's registration (device frame) or None (base frame).
        effects: The chosen effects beyond the robot file's (geometry first).
        steps: The selection's steps.
        heldout_rms: Held-out 3-D RMS over markers [m] (see module doc).
        heldout_groups: Pose groups scored held out.
        heldout_scheme: ``leave-one-pose-group-out`` or ``k-fold by pose group``.
        fit_rms: In-sample 3-D RMS over markers of the final model [m].
        nominal_rms: 3-D RMS over markers of the robot file's model with only the
            registration (and marker positions) fitted [m].
        iso: ISO 9283-style figures.
        files: Per-file figures.
        parameters: The identified robot parameters (JSON rows).
        not_identifiable: Effects or parameters the data could not identify, with why.
        saved: The calibrated robot file, if written.
        seconds: Wall time [s].
        markers: Markers per pose.
        samples: Samples used (after ``every``).
        scores: The ``score`` files: 3-D RMS of the tracked point [m] and samples.
    """

    request: CalibrationRequest
    model: ElastostaticModel = field(repr=False)
    frames: tuple[DeviceFrame | None, ...]
    effects: tuple[str, ...]
    steps: tuple[SelectionStep, ...]
    heldout_rms: float
    heldout_groups: int
    heldout_scheme: str
    fit_rms: float
    nominal_rms: float
    iso: Iso9283
    files: tuple[FileScore, ...]
    parameters: tuple[dict[str, Any], ...]
    not_identifiable: tuple[dict[str, str], ...]
    saved: Path | None
    seconds: float
    markers: int
    samples: int
    scores: tuple[tuple[str, float, int], ...] = ()

    @property
    def repeatability(self) -> float | None:
        """ISO 9283 RP of the worst pose group [m], None without repeats."""
        return self.iso.rp_max

    def to_json(self) -> dict[str, Any]:
        """The JSON object ``calibrate --json`` prints (lengths in mm)."""
        r = self.request
        return {
            "robot": self.model.robot.description.name,
            "parent_robot": r.robot,
            "data": list(r.data),
            "columns": r.columns,
            "samples": self.samples,
            "markers_per_pose": self.markers,
            "every": r.every,
            "heldout_rms_mm": self.heldout_rms * 1e3,
            "heldout_scheme": self.heldout_scheme,
            "heldout_pose_groups": self.heldout_groups,
            "fit_rms_mm": self.fit_rms * 1e3,
            "registration_only_rms_mm": self.nominal_rms * 1e3,
            "repeatability_mm": None if self.repeatability is None else self.repeatability * 1e3,
            "iso9283": self.iso.to_json(),
            "effects": list(self.effects),
            "selection": [s.to_json() for s in self.steps],
            "parameters": list(self.parameters),
            "not_identifiable": list(self.not_identifiable),
            "files": [f.to_json() for f in self.files],
            "scores": [{"data": d, "rms_3d_mm": v * 1e3, "samples": n}
                       for d, v, n in self.scores],
            "registration": "held" if r.keep_registration else "each_file",
            "saved_robot": None if self.saved is None else str(self.saved),
            "seconds": self.seconds,
        }

    def write(self, folder: str | Path) -> Path:
        """Write ``calibrate.json`` into ``folder`` (atomically), without the wall time (the same
        input writes the same bytes; ``--json`` prints it); returns its path."""
        from rfsw_plan.files import without_wall_times, write_json

        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        return write_json(out / "calibrate.json", without_wall_times(self.to_json()))


# -- data ----------------------------------------------------------------------------------------
def pose_groups(q: FloatArray) -> NDArray[np.int_]:
    """Group index of every sample: equal joint values (to :data:`GROUP_TOL`) are one group,
    numbered in order of first appearance, shape (m,)."""
    _, first, inverse = np.unique(np.round(q / GROUP_TOL), axis=0, return_index=True,
                                  return_inverse=True)
    order = np.argsort(np.argsort(first))
    return np.asarray(order[np.asarray(inverse).reshape(-1)], dtype=np.int_)


def _subsample(data: MeasurementSet, every: int) -> MeasurementSet:
    """Every ``every``-th pose group (in order of first appearance), all its samples."""
    if every == 1:
        return data
    return data.subset(pose_groups(data.q) % every == 0)


def read_training(request: CalibrationRequest, model: ElastostaticModel
                  ) -> list[MeasurementSet]:
    """Every ``--data`` file, read for ``model``'s robot, subsampled, checked."""
    from rfsw_plan.io.measurements import read_measurements

    robot = model.robot
    out = []
    for path in request.data:
        data = read_measurements(path, robot.nq, prismatic=list(robot.prismatic),
                                 columns=request.columns, frame=request.frame)
        data = _subsample(data, request.every)
        check_data(model, data)
        out.append(data)
    frames = {d.frame for d in out}
    if len(frames) > 1:
        raise InputError("data", "", "some files are in the base frame, some in a device "
                         "frame", "one frame for every training file")
    return out


def _concat(sets: Sequence[MeasurementSet], source: str) -> MeasurementSet:
    """The samples of several sets as one (same columns; text and history kept per row)."""
    def cat(name: str) -> Any:
        vals = [getattr(s, name) for s in sets]
        return None if any(v is None for v in vals) else np.concatenate(vals)

    extra_keys = set.intersection(*(set(s.extra) for s in sets))
    return MeasurementSet(
        q=np.concatenate([s.q for s in sets]), wrench=np.concatenate([s.wrench for s in sets]),
        position=np.concatenate([s.position for s in sets]), t=None,
        pose_id=cat("pose_id"), sigma=cat("sigma"),
        extra={k: np.concatenate([s.extra[k] for s in sets]) for k in sorted(extra_keys)},
        source=source, frame=sets[0].frame, rotation=None, load_step=cat("load_step"),
        dialect=sets[0].dialect, columns=sets[0].columns, approach=cat("approach"),
        load_change=cat("load_change"), markers=cat("markers"),
    )


def _registered(data: MeasurementSet, frame: DeviceFrame | None) -> MeasurementSet:
    """Positions and markers brought into the base frame with ``frame`` (kept as "device":
    the common set-up's identity registration then fits what is left)."""
    if frame is None:
        return data
    markers = None if data.markers is None else frame.to_base(
        data.markers.reshape(-1, 3)).reshape(data.markers.shape)
    return replace(data, position=frame.to_base(data.position), markers=markers,
                   rotation=None)


def _compose(frame: DeviceFrame, correction: DeviceFrame) -> DeviceFrame:
    """The registration of a file pre-registered with ``frame`` and then corrected by
    ``correction`` (both: p_outer = R p_inner + t): R = R_f R_c, t = R_f t_c + t_f; the
    marker is the correction's."""
    return DeviceFrame(frame.rotation @ correction.rotation,
                       frame.rotation @ correction.translation + frame.translation,
                       correction.marker, dict(correction.std))


# -- the fit -------------------------------------------------------------------------------------
def _common_setup(model: ElastostaticModel, marker: FloatArray) -> DeviceSetup:
    """Registration and marker fitted on pre-registered data (identity start)."""
    return DeviceSetup(DeviceFrame(np.eye(3), np.zeros(3), np.asarray(marker, float)),
                       True, True, model.robot)


@dataclass(frozen=True)
class Choice:
    """The model :func:`choose_effects` chose, identified on all training samples.

    Attributes:
        identification: The chosen form identified on every sample (registration included).
        cv: Its cross-validation by pose group on the training files.
        not_added: Effects asked for (the geometry) that the data could not identify, why.
        setup: The device set-up the data was registered with (None: base frame).
    """

    identification: IdentificationResult = field(repr=False)
    cv: CrossValidation = field(repr=False)
    not_added: tuple[Skipped, ...] = ()
    setup: DeviceSetup | None = field(default=None, repr=False)


def marker_layout(model: ElastostaticModel, data: MeasurementSet) -> FloatArray:
    """Where each marker sits on the tool, relative to the tracked point, in the tool frame
    [m], shape (k, 3): the mean over ``data`` of the measured markers seen from the predicted
    tool pose, l_k = mean_i R_i^T (y_ik - p_i), less their mean, so that the tracked point is
    the markers' centroid (sum_k l_k = 0: the centroid's rows and the rotation's rows of the
    marker rows are then orthogonal)."""
    assert data.markers is not None
    p, R = _tool_poses(model, data)
    local = np.einsum("mba,mkb->mka", R, data.markers - p[:, None, :]).mean(axis=0)
    out: FloatArray = local - local.mean(axis=0)
    return out


def marker_rows(model: ElastostaticModel, data: MeasurementSet, batch: PoseBatch
                ) -> tuple[MeasurementSet, PoseBatch]:
    """Every marker of every pose as a sample of its own, so that a fit of position rows fits
    what :func:`marker_errors` scores: the markers, which constrain the tool's rotation as well
    as its position (the rotation rows of a pose measured by k >= 2 markers).

    Sample (i, k) is pose i with the model's TCP moved by the layout l_k
    (:func:`marker_layout`, fitted closed-form on ``data`` with ``model``): T_ik = T_i Trans(l_k)
    and the point's Jacobian J_p,ik = J_p,i + J_w,i x (R_i l_k) (rigid body), the logged moment
    taken about the marker, M_ik = M_i + (R_i l_k) x F_i, so that every effect's regressor,
    which works from T, J and the joint frames, acts on the marker. Its measured position is
    marker k. With y_ik = p_i + R_i l_k + e_ik and sum_k l_k = 0,
    sum_k |e_ik|^2 = k |e_centroid|^2 + sum_k |dw x R_i l_k|^2: the position rows of the
    centroid plus rotation rows weighted by the layout's spread.

    Rows are marker-major (all poses of marker 0, then of marker 1...), each marker's samples
    keeping the file's order (the approach directions and load changes of the file are kept),
    and the time of marker k shifted by k times the recording's span plus 1 s, so that the
    repeats of a pose (consecutive samples of one marker) are never pooled across markers. The
    joint values are those of the pose: folds by pose group keep a pose's markers together.
    Data without markers is returned as it is.
    """
    if data.markers is None:
        return data, batch
    layout = marker_layout(model, data)
    k, m = layout.shape[0], len(data)
    R = batch.T[:, :3, :3]
    arms = np.einsum("mab,kb->kma", R, layout)  # (k, m, 3): R_i l_k [m]
    T = np.repeat(batch.T[None], k, axis=0)
    T[:, :, :3, 3] += arms
    J = np.repeat(batch.J[None], k, axis=0)
    J[:, :, :3, :] += np.cross(np.moveaxis(batch.J[:, 3:, :], 2, 1)[None],
                               arms[:, :, None, :]).transpose(0, 1, 3, 2)
    wrench = np.repeat(data.wrench[None], k, axis=0)
    wrench[:, :, 3:] += np.cross(arms, data.wrench[None, :, :3])

    def tile(a: Any) -> Any:
        return None if a is None else np.concatenate([a] * k)

    t = None if data.t is None else np.concatenate(
        [data.t + j * (float(np.ptp(data.t)) + 1.0) for j in range(k)])
    approach, changes = data.approach_directions(), data.load_changes()
    out = replace(
        data, q=tile(data.q), wrench=wrench.reshape(k * m, 6),
        position=np.moveaxis(data.markers, 1, 0).reshape(k * m, 3), t=t,
        pose_id=tile(data.pose_id), sigma=tile(data.sigma),
        extra={key: tile(v) for key, v in data.extra.items()}, rotation=None,
        load_step=tile(data.load_step), approach=tile(approach), load_change=tile(changes),
        markers=None)
    xb = PoseBatch(batch.robot, tile(batch.q), T.reshape(k * m, 4, 4),
                   J.reshape(k * m, *batch.J.shape[1:]), tile(batch.frames),
                   tile(batch.approach), batch.force_noise, tile(batch.load_change))
    return out, xb


def choose_effects(model: ElastostaticModel, data: MeasurementSet, setup: DeviceSetup | None,
                   request: CalibrationRequest, labels: Sequence[str] | None = None
                   ) -> tuple[Choice, list[str], list[SelectionStep]]:
    """The geometry, then the workbench's forward selection, on the training data only.

    The geometry (``request.geometry``, or ``labels`` when given) is added as ``validate
    --add`` adds it (what the data cannot identify is left out, with why). Then the
    workbench's :func:`~rfsw_plan.validation.engine.diagnosis.forward_select` adds effects
    (held-out F test on folds by pose group, Bonferroni over the candidates, the simplest of
    those the data cannot tell apart) until the held-out residual is at the noise floor,
    nothing significant is left, or ``request.max_effects`` are added. With markers the fit
    and the selection work on every marker (:func:`marker_rows`): the same quantity as the
    held-out score. With ``labels`` given nothing is selected: the form is refitted.
    """
    from rfsw_plan.validation.engine.diagnosis import forward_select
    from rfsw_plan.validation.engine.residuals import residual_features
    from rfsw_plan.validation.workbench import _add_effects
    from rfsw_plan.validation.workbench import _registered as registered_form

    form, d = registered_form(model, data, setup)
    if data.markers is not None and d.markers is None:  # registered with the set-up too
        shape = data.markers.shape
        d = replace(d, markers=data.markers if setup is None else setup.frame.to_base(
            data.markers.reshape(-1, 3)).reshape(shape))
    wanted = list(request.geometry if labels is None else labels)
    wanted = check_effect_labels(form, [g for g in wanted if not model.has(g)])
    d, batch = marker_rows(form, d, form.batch_of(d))
    pred = predicted_positions(form, batch, d.wrench)
    residual0 = np.where(d.measured, d.position - pred, np.nan)
    r0 = residual0[np.isfinite(residual0)]
    rms0 = float(np.sqrt(np.mean(r0**2))) if r0.size else math.nan
    fold = make_folds(d, request.folds, request.seed)
    before = cross_validate(form, d, fold, batch)
    if wanted:
        add = _add_effects(form, d, fold, batch, wanted, before, rms0)
        cv, added, not_added = add.after, list(add.added), add.not_added
    else:
        cv, added, not_added = before, [], ()
    steps = [SelectionStep(" + ".join(["registration", *added]) if setup else " + ".join(added),
                           cv.heldout_rms, cv.fit.rms_after)]
    if labels is not None or request.max_effects == 0:
        return Choice(cv.fit, cv, not_added, setup), added, steps
    noise = estimate_noise_floor(d, residual0, model=form, batch=batch)
    tau = np.einsum("mak,ma->mk", batch.J, d.wrench)
    feats = residual_features(d, batch.T[:, :3, 3], tau)
    sel = _single_thread(forward_select)(cv.fit.model, d, fold, cv, noise, feats, batch,
                                         max_steps=request.max_effects,
                                         fit_steps=SELECTION_STEPS)
    if sel.steps:
        # The selection's fits take SELECTION_STEPS Gauss-Newton steps from the model before
        # them; the chosen form is fitted to convergence from its own.
        linear = all(e.pose_linear_in_params() for e in sel.model.effects)
        cv = sel.cv if linear else _single_thread(cross_validate)(sel.model, d, fold, batch)
        for s in sel.steps:
            added.append(s.label)
            steps.append(SelectionStep(s.label, s.rms_after, None))
        steps[-1] = replace(steps[-1], fit_rms=cv.fit.rms_after)
    return Choice(cv.fit, cv, not_added, setup), added, steps


def _form(model: ElastostaticModel, labels: Sequence[str], setup: DeviceSetup | None
          ) -> ElastostaticModel:
    for label in labels:
        model = model.with_effect(label)
    return model if setup is None else setup.model(model)


def _tool_poses(model: ElastostaticModel, data: MeasurementSet) -> tuple[FloatArray, FloatArray]:
    """Predicted tracked point [m] (m, 3) and tool rotation (m, 3, 3), base frame."""
    batch = model.batch_of(data)
    d = model.deflection_batch(batch, data.wrench)
    from scipy.spatial.transform import Rotation

    dR = Rotation.from_rotvec(d[:, 3:]).as_matrix()
    return batch.T[:, :3, 3] + d[:, :3], np.einsum("mab,mbc->mac", dR, batch.T[:, :3, :3])


def marker_errors(model: ElastostaticModel, train: MeasurementSet, test: MeasurementSet
                  ) -> FloatArray:
    """3-D errors of every marker of ``test`` [m], shape (m, k, 3) (k = 1 without markers):
    the markers' positions on the tool are the mean, over ``train``, of the measured markers
    seen from the predicted tool pose (the model's tracked point is their centroid)."""
    p_test, R_test = _tool_poses(model, test)
    if test.markers is None or train.markers is None:
        return (test.position - p_test)[:, None, :]
    p_train, R_train = _tool_poses(model, train)
    local = np.einsum("mba,mkb->mka", R_train, train.markers - p_train[:, None, :]).mean(axis=0)
    pred = p_test[:, None, :] + np.einsum("mab,kb->mka", R_test, local)
    out: FloatArray = test.markers - pred
    return out


def _heldout_folds(groups: NDArray[np.int_], request: CalibrationRequest
                   ) -> tuple[NDArray[np.int_], str]:
    n = int(groups.max()) + 1
    if request.heldout_folds is None and n <= MAX_LOGO_GROUPS:
        return groups, "leave-one-pose-group-out"
    k = min(request.heldout_folds or HELDOUT_FOLDS, n)
    order = np.random.default_rng(request.seed).permutation(n)
    fold_of_group = np.empty(n, dtype=np.int_)
    fold_of_group[order] = np.arange(n) % k
    return fold_of_group[groups], f"{k}-fold by pose group"


def _start(form: ElastostaticModel, fit: IdentificationResult | None) -> FloatArray | None:
    """The parameters of ``fit`` in the order of ``form``'s (None if it lacks one)."""
    if fit is None:
        return None
    got = {(e.effect, e.name): e.value for e in fit.estimates}
    names = [(e.label, n) for e in form.effects for n in e.param_names()]
    return np.array([got[n] for n in names]) if all(n in got for n in names) else None


def heldout_errors(form: ElastostaticModel, data: MeasurementSet, folds: NDArray[np.int_],
                   start: IdentificationResult | None = None) -> FloatArray:
    """Marker errors of every sample when its fold is left out of the fit (the registration
    and every effect of ``form`` refitted on the other folds), shape (m, k, 3) [m].

    ``start``: the fit of all samples. A model nonlinear in its parameters then takes
    :data:`HELDOUT_STEPS` Gauss-Newton steps from it on each fold's training samples, its
    decisions (what is identifiable, positive, plausible) taken again there (a linearisation
    at the fit of all samples, exact to first order in what one fold changes); the priors stay
    ``form``'s, and a linear model does not depend on it. Without it each fold's fit
    converges from the priors."""
    from rfsw_plan.files import check_interrupt
    from rfsw_plan.progress import progress

    theta0 = _start(form, start)
    k_markers = 1 if data.markers is None else data.markers.shape[1]
    out = np.full((len(data), k_markers, 3), np.nan)
    names = np.unique(folds)
    for f in progress(names, desc="calibrate: held out", total=len(names), unit="fold"):
        check_interrupt()
        test = folds == f
        train = data.subset(~test)
        rows, batch = marker_rows(form, train, form.batch_of(train))
        fit = _single_thread(identify_blocks)(form, rows, batch,
                                              np.zeros(len(rows), dtype=np.int_),
                                              max_iter=30 if theta0 is None else HELDOUT_STEPS,
                                              start=theta0).result
        out[test] = marker_errors(fit.model, train, data.subset(test))
    return out


def _rms3d(err: FloatArray) -> float:
    n2 = np.sum(err**2, axis=-1)
    n2 = n2[np.isfinite(n2)]
    return float(np.sqrt(np.mean(n2))) if n2.size else math.nan


def iso9283(measured: FloatArray, err: FloatArray, groups: NDArray[np.int_]) -> Iso9283:
    """ISO 9283-style AP and RP (see :class:`Iso9283`) from measured markers (m, k, 3) and
    their held-out errors (m, k, 3), by pose group."""
    ap: list[float] = []
    rp: list[float] = []
    dev: list[FloatArray] = []
    repeated = 0
    for g in np.unique(groups):
        sel = groups == g
        e = err[sel]
        ap += list(np.linalg.norm(e.mean(axis=0), axis=-1))
        if sel.sum() >= 2:
            repeated += 1
            m = measured[sel]
            d = m - m.mean(axis=0)
            dev.append(d.reshape(-1, 3))
            if sel.sum() >= 3:
                lengths = np.linalg.norm(d, axis=-1)  # (n, k)
                rp += list(lengths.mean(axis=0) + 3.0 * lengths.std(axis=0, ddof=1))
    rep = np.concatenate(dev) if dev else None
    return Iso9283(
        ap_mean=float(np.mean(ap)), ap_max=float(np.max(ap)),
        rp_mean=float(np.mean(rp)) if rp else None, rp_max=float(np.max(rp)) if rp else None,
        groups=int(np.unique(groups).size), repeated_groups=repeated,
        repeat_rms_3d=None if rep is None else float(np.sqrt(np.mean(np.sum(rep**2, axis=1)))),
    )


def _parameters(res: Choice) -> tuple[list[dict[str, Any]], list[dict[str, str]]]:
    """Identified robot parameters (engineering units) and what could not be identified."""
    effects = {e.label: e for e in res.identification.model.effects}
    params: list[dict[str, Any]] = []
    missing: list[dict[str, str]] = []
    for e in res.identification.estimates:
        eff = effects[e.effect]
        if eff.setup:
            continue
        unit = eff.param_unit(e.name)
        scale, shown = {"rad": (1e3, "mrad"), "m": (1e3, "mm")}.get(unit, (1.0, unit or "SI"))
        if not e.identified:
            missing.append({"label": f"{e.effect}.{e.name}", "reason": e.note or "not identified"})
            continue
        std = None if not np.isfinite(e.std_error) else e.std_error * scale
        params.append({"effect": e.effect, "name": e.name, "value": e.value * scale,
                       "std_error": std, "unit": shown, "note": e.note})
    missing += [{"label": s.label, "reason": s.reason} for s in res.not_added]
    return params, missing


def _fit_rounds(model: ElastostaticModel, sets: list[MeasurementSet],
                frames: list[DeviceFrame | None], labels: list[str] | None,
                request: CalibrationRequest
                ) -> tuple[Choice, list[str], list[SelectionStep],
                           MeasurementSet, DeviceSetup | None]:
    """Choose (``labels`` None) or refit the model on the files registered with ``frames``."""
    device = frames[0] is not None
    marker = np.mean([f.marker for f in frames if f is not None], axis=0) if device else None
    setup = _common_setup(model, marker) if marker is not None else None
    data = _concat([_registered(d, f) for d, f in zip(sets, frames, strict=True)],
                   ", ".join(request.data))
    res, chosen, steps = choose_effects(model, data, setup, request, labels)
    return res, chosen, steps, data, setup


def run(request: CalibrationRequest) -> CalibrationResult:
    """Calibrate (see module doc).

    Raises:
        InputError: Bad options or data (one line).
        IdentificationError: Too few poses for what is fitted (says how many).
    """
    from rfsw_plan.robot.kinematics import load_robot

    t0 = time.perf_counter()
    request.check()
    model = ElastostaticModel(load_robot(request.robot))
    sets = read_training(request, model)
    device = sets[0].frame == "device"
    frames: list[DeviceFrame | None] = [
        estimate_device_frame(model, d) if device else None for d in sets]
    nominal = _nominal_rms(model, sets, frames)
    geometry = [g for g in request.geometry if not model.has(g)]
    frames = converge_frames(model, geometry, sets, frames, request)
    res, chosen, steps, data, setup = _fit_rounds(model, sets, frames, None, request)
    if len(sets) > 1 and device and chosen != geometry:
        frames = converge_frames(model, chosen, sets, frames, request)
        res, _, _, data, setup = _fit_rounds(model, sets, frames, chosen, request)
    fitted, frames = _refold(res, setup, frames)
    form = _form(model, chosen, setup)
    groups = pose_groups(data.q)
    folds, scheme = _heldout_folds(groups, request)
    err = heldout_errors(form, data, folds, res.identification)
    measured = data.position[:, None, :] if data.markers is None else data.markers
    fit_err = marker_errors(res.identification.model, data, data)
    params, missing = _parameters(res)
    files = _file_scores(sets, frames, err, fit_err)
    saved = None
    if request.save_robot is not None:
        saved = _save(request, res, fitted, frames[0], model)
    held = frames[0] if request.keep_registration else None
    marker = None if frames[0] is None else frames[0].marker
    scores = tuple(score_file(fitted, path, request, marker, held) for path in request.score)
    return CalibrationResult(
        request=request, model=fitted, frames=tuple(frames), effects=tuple(chosen),
        steps=tuple(steps), heldout_rms=_rms3d(err), heldout_groups=int(groups.max()) + 1,
        heldout_scheme=scheme, fit_rms=_rms3d(fit_err), nominal_rms=nominal,
        iso=iso9283(measured, err, groups), files=files, parameters=tuple(params),
        not_identifiable=tuple(missing), saved=saved, seconds=time.perf_counter() - t0,
        markers=measured.shape[1], samples=len(data), scores=scores,
    )


def score_file(model: ElastostaticModel, path: str, request: CalibrationRequest,
               marker: FloatArray | None, held: DeviceFrame | None
               ) -> tuple[str, float, int]:
    """3-D RMS [m] of the tracked point of another file with ``model`` held: only its device
    frame registered (closed form, ``marker`` held), or nothing refitted when ``held`` is
    given; what ``validate --json`` reports as ``rms_3d_mm`` for the saved robot file."""
    from rfsw_plan.io.measurements import read_measurements

    data = read_measurements(path, model.robot.nq, prismatic=list(model.robot.prismatic),
                             columns=request.columns, frame=request.frame)
    check_data(model, data)
    if data.frame == "device" and marker is not None:
        frame = held if held is not None else _register(model, data, marker)
        at_marker = DeviceSetup(frame, False, False, model.robot).model(model)
        data = _registered(data, frame)
        return path, _rms3d(marker_errors(at_marker, data, replace(data, markers=None))), len(data)
    return path, _rms3d(marker_errors(model, data, replace(data, markers=None))), len(data)


def converge_frames(model: ElastostaticModel, labels: Sequence[str],
                    sets: list[MeasurementSet], frames: list[DeviceFrame | None],
                    request: CalibrationRequest) -> list[DeviceFrame | None]:
    """Each file's registration for the model form ``labels``, when there are several files.

    Alternates (at most :data:`REGISTRATION_ROUNDS` times): identify the form with one common
    registration correction on the files registered with ``frames``, fold the correction in,
    and register each file again (closed form) with the fitted model and the common marker,
    until no frame moves by more than :data:`FRAME_TOL_M` (a rotation counted at 1 m). A
    single file needs none of it: its registration is fitted jointly with everything else.
    """
    from rfsw_plan.files import check_interrupt

    if len(sets) < 2 or frames[0] is None:
        return frames
    for _ in range(REGISTRATION_ROUNDS):
        check_interrupt()
        marker = np.mean([f.marker for f in frames if f is not None], axis=0)
        setup = _common_setup(model, marker)
        data = _concat([_registered(d, f) for d, f in zip(sets, frames, strict=True)], "")
        form = _form(model, labels, setup)
        rows, batch = marker_rows(form, data, form.batch_of(data))
        fit = _single_thread(identify_blocks)(form, rows, batch,
                                              np.zeros(len(rows), dtype=np.int_)).result
        fitted, correction = setup.fold(fit.model, fit.estimates)
        new = [_register(fitted, d, correction.marker) for d in sets]
        moved = max(_frame_change(f, g) for f, g in zip(frames, new, strict=True)
                    if f is not None)
        frames = list(new)
        if moved < FRAME_TOL_M:
            break
    return frames


def _register(model: ElastostaticModel, data: MeasurementSet, marker: FloatArray
              ) -> DeviceFrame:
    """A file's registration (closed form) with ``model`` and the marker held: the model's
    TCP moved to the marker first, so that its rotations move the marker too."""
    held = DeviceFrame(np.eye(3), np.zeros(3), np.asarray(marker, dtype=float))
    at_marker = DeviceSetup(held, False, False, model.robot).model(model)
    frame = estimate_device_frame(at_marker, data, np.zeros(3))
    return replace(frame, marker=held.marker)


def _frame_change(a: DeviceFrame, b: DeviceFrame) -> float:
    """How far a registration moved [m]: translation, and rotation angle times 1 m."""
    from scipy.spatial.transform import Rotation

    angle = float(np.linalg.norm(Rotation.from_matrix(a.rotation.T @ b.rotation).as_rotvec()))
    return max(float(np.linalg.norm(a.translation - b.translation)), angle)


def _nominal_rms(model: ElastostaticModel, sets: list[MeasurementSet],
                 frames: list[DeviceFrame | None]) -> float:
    """3-D RMS over markers of the robot file's model, each file registered (closed form)."""
    errs = []
    for d, f in zip(sets, frames, strict=True):
        reg = _registered(d, f)
        m = model if f is None else DeviceSetup(f, False, False, model.robot).model(model)
        errs.append(marker_errors(m, reg, reg).reshape(-1, 3))
    return _rms3d(np.concatenate(errs))


def _refold(res: Choice, setup: DeviceSetup | None,
            frames: list[DeviceFrame | None]
            ) -> tuple[ElastostaticModel, list[DeviceFrame | None]]:
    """The fitted robot model and each file's registration (the common correction folded
    into each file's frame)."""
    if setup is None:
        return res.identification.model, frames
    fitted, correction = setup.fold(res.identification.model, res.identification.estimates)
    return fitted, [None if f is None else _compose(f, correction) for f in frames]


def _file_scores(sets: list[MeasurementSet], frames: list[DeviceFrame | None],
                 err: FloatArray, fit_err: FloatArray) -> tuple[FileScore, ...]:
    out = []
    start = 0
    for d, f in zip(sets, frames, strict=True):
        sl = slice(start, start + len(d))
        start += len(d)
        out.append(FileScore(d.source, len(d), int(pose_groups(d.q).max()) + 1, f,
                             _rms3d(fit_err[sl]), _rms3d(err[sl])))
    return tuple(out)


def _save(request: CalibrationRequest, res: Choice, fitted: ElastostaticModel,
          frame: DeviceFrame | None, parent: ElastostaticModel) -> Path:
    from rfsw_plan.validation.derived_robot import save_derived_robot

    assert request.save_robot is not None
    fit = res.identification
    note = (f"calibrated by rfsw-plan calibrate from {', '.join(request.data)} "
            f"({fit.n_samples} samples, effects: {', '.join(fitted.labels)})")
    if frame is not None:
        frame = replace(frame, each_file=not request.keep_registration)
    return save_derived_robot(
        fitted, request.save_robot, parent=parent.robot.description, note=note,
        data=request.data[0], command="rfsw-plan calibrate", name=request.name,
        device_frame=frame,
        device_note=(f"registration of {request.data[0]} and marker identified by rfsw-plan "
                     "calibrate; " + ("held for every file" if request.keep_registration
                                      else "registered again for each file")))


__all__ = [
    "GEOMETRY",
    "CalibrationRequest",
    "CalibrationResult",
    "Choice",
    "FileScore",
    "Iso9283",
    "choose_effects",
    "heldout_errors",
    "iso9283",
    "marker_errors",
    "pose_groups",
    "run",
]
