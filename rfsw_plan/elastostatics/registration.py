"""Measurements in a device frame: registration of the device and the tracked marker.

A laser tracker or a motion-capture system measures a marker at an offset ``c`` from the TCP
(tool frame) in its own frame. With the base frame seen from the device as ``(R, t)``:

    y_device = R (X(q, F) + R_tcp(q) c) + t,

X the model's loaded TCP position in the base frame. The registration ``(R, t)`` (6 DoF) and
the marker offset ``c`` (3) are estimated jointly with every other parameter:

1. :func:`estimate_device_frame`: a closed-form start (Kabsch/Umeyama on the nominal model's
   points, alternating with a linear least-squares fit of the marker offset);
2. :class:`DeviceSetup` moves the marker into the tool (the model's TCP *is* the marker, so
   joint-offset Jacobians act on the right point), brings the data into the base frame with
   the current registration, and adds two linear *set-up* effects (a small rigid motion
   :class:`~rfsw_plan.elastostatics.effects.DeviceRegistration` and
   :class:`~rfsw_plan.elastostatics.effects.MarkerOffset`) that identification fits with the
   robot's own parameters, with standard errors;
3. :meth:`DeviceSetup.fold` folds the fitted corrections back into ``(R, t, c)``.

A free registration makes some joint offsets unidentifiable (a joint whose axis is vertical
at the base turns everything like the registration does; the last joint's offset turns the
marker about the tool axis like the marker offset does): identification names them and
does not fit them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rfsw_plan.elastostatics.effects import DeviceRegistration, MarkerOffset, make_effect
from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.identification import ParameterEstimate
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import IdentificationError
from rfsw_plan.robot.description import DeviceFrame
from rfsw_plan.robot.kinematics import Robot

#: Poses measured in x, y and z needed to register a device frame and a marker offset
#: (9 unknowns, 3 values per pose, plus one pose of redundancy to see the residual).
MIN_POSES = 4
#: Alternating iterations of the closed-form start.
START_ITERATIONS = 200


def _kabsch(a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Rotation R and translation t minimising ||b - (R a + t)|| over rows (k, 3)."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    H = (a - ca).T @ (b - cb)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return R, cb - R @ ca


def rotation_from_vector(w: FloatArray) -> FloatArray:
    """Rotation matrix of a rotation vector [rad] (Rodrigues), shape (3, 3)."""
    th = float(np.linalg.norm(w))
    if th == 0.0:
        return np.eye(3)
    k = np.asarray(w, dtype=float) / th
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(th) * K + (1.0 - np.cos(th)) * (K @ K)


def _cross_matrices(w: FloatArray) -> FloatArray:
    """Cross-product matrices [w]x (m, 3, 3) of vectors w (m, 3)."""
    out = np.zeros((w.shape[0], 3, 3))
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    return out - out.transpose(0, 2, 1)


def _distinct_poses(data: MeasurementSet, rows: np.ndarray) -> int:
    if data.pose_id is not None:
        return len(set(data.pose_id[rows]))
    return len(np.unique(np.round(data.q[rows] / 1e-6), axis=0))


def estimate_device_frame(
    model: ElastostaticModel, data: MeasurementSet, marker: FloatArray | None = None
) -> DeviceFrame:
    """Closed-form start of the registration (and marker offset unless given).

    Args:
        model: The model whose predicted TCP positions are registered.
        data: Device-frame samples.
        marker: Known marker offset in the tool frame [m], or None to estimate it.

    Raises:
        IdentificationError: Fewer than :data:`MIN_POSES` poses measured in all three axes,
            or poses that do not span space (says how many are needed).
    """
    full = np.all(data.measured, axis=1)
    n_poses = _distinct_poses(data, full)
    if n_poses < MIN_POSES:
        raise IdentificationError(
            f"{data.source}: {n_poses} pose(s) measured in x, y and z cannot register the "
            f"device frame and the marker offset; need at least {MIN_POSES} distinct poses "
            "(6 registration + 3 marker parameters, 3 values per pose, and one to spare)"
        )
    batch = model.batch_of(data.subset(full))
    d = model.deflection_batch(batch, data.wrench[full])
    p = batch.T[:, :3, 3] + d[:, :3]
    # The marker turns with the tool's predicted rotation (a joint offset, a link error or a
    # compliance turns the tool), to first order as the model with its TCP at the marker
    # predicts it: R_tool c = R_fk c + d_rot x (R_fk c) = (I + [d_rot]x) R_fk c.
    Rt = np.einsum("mab,mbc->mac", np.eye(3) + _cross_matrices(d[:, 3:]), batch.T[:, :3, :3])
    y = data.position[full]
    if np.linalg.matrix_rank(p - p.mean(axis=0), tol=1e-6) < 2:
        raise IdentificationError(
            f"{data.source}: the measured poses lie on a line; registration needs poses that "
            f"span a plane or space (at least {MIN_POSES} poses not on one line)"
        )
    c = np.zeros(3) if marker is None else np.asarray(marker, dtype=float)
    R, t = np.eye(3), np.zeros(3)
    A = Rt.reshape(-1, 3)
    for _ in range(START_ITERATIONS):
        R, t = _kabsch(p + Rt @ c, y)
        if marker is not None:
            break
        c_new, *_ = np.linalg.lstsq(A, ((y - t) @ R - p).reshape(-1), rcond=None)
        if np.linalg.norm(c_new - c) < 1e-10:
            c = c_new
            break
        c = c_new
    R, t = _kabsch(p + Rt @ c, y)
    return DeviceFrame(rotation=R, translation=t, marker=c)


def with_tool_point(robot: Robot, marker: FloatArray) -> Robot:
    """The robot with its TCP moved to the marker (``marker`` in the tool frame [m])."""
    desc = robot.description
    tool = desc.tool.copy()
    tool[:3, 3] = tool[:3, 3] + tool[:3, :3] @ np.asarray(marker, dtype=float)
    return Robot(replace(desc, tool=tool))


@dataclass(frozen=True)
class DeviceSetup:
    """How device-frame data enters identification.

    Attributes:
        frame: Current registration and marker offset.
        fit_registration: Estimate the registration (else it is held as given).
        fit_marker: Estimate the marker offset (else it is held).
        robot: The robot as described (TCP without the marker).
    """

    frame: DeviceFrame
    fit_registration: bool
    fit_marker: bool
    robot: Robot

    @property
    def effect_labels(self) -> list[str]:
        """The set-up effects this set-up adds to a model."""
        return ([DeviceRegistration.name] if self.fit_registration else []) + (
            [MarkerOffset.name] if self.fit_marker else [])

    def model(self, model: ElastostaticModel) -> ElastostaticModel:
        """``model`` on the robot whose TCP is the marker, plus the free set-up effects."""
        robot = with_tool_point(self.robot, self.frame.marker)
        effects = [make_effect(robot, e.label, e.param_dict()) for e in model.effects
                   if not e.setup]
        effects += [make_effect(robot, label) for label in self.effect_labels]
        return ElastostaticModel(robot, effects)

    def data(self, data: MeasurementSet) -> MeasurementSet:
        """The samples with positions (and orientations) in the base frame (current
        registration): p_b = R^T (p_d - t), R_tool,b = R^T R_tool,d."""
        out = data.with_position(self.frame.to_base(data.position), "base")
        if data.rotation is None:
            return out
        from scipy.spatial.transform import Rotation

        Rd = Rotation.from_rotvec(data.rotation).as_matrix()
        Rb = np.einsum("ba,mbc->mac", self.frame.rotation, Rd)
        return replace(out, rotation=np.asarray(Rotation.from_matrix(Rb).as_rotvec()))

    def fold(
        self, fitted: ElastostaticModel, estimates: tuple[ParameterEstimate, ...] = ()
    ) -> tuple[ElastostaticModel, DeviceFrame]:
        """Fold the fitted set-up effects into the registration and marker offset.

        With omega, tau the fitted small motion (base frame) and dc the marker correction:
        R' = R exp(omega), t' = t + R tau, c' = c + dc.

        Returns:
            The model on the robot as described (its effects without the set-up ones) and
            the new device frame, with the standard errors of the fitted set-up parameters
            (``rx_mrad``.. ``x_mm``.. ``marker_x_mm``..) from ``estimates``.
        """
        R, t, c = self.frame.rotation, self.frame.translation, self.frame.marker.copy()
        if fitted.has(DeviceRegistration.name):
            th = next(e for e in fitted.effects if e.label == DeviceRegistration.name).params
            R, t = R @ rotation_from_vector(th[:3]), t + R @ th[3:]
        if fitted.has(MarkerOffset.name):
            c = c + next(e for e in fitted.effects if e.label == MarkerOffset.name).params
        std: dict[str, float] = dict(self.frame.std)
        names = {"wx": "rx_mrad", "wy": "ry_mrad", "wz": "rz_mrad", "tx": "x_mm", "ty": "y_mm",
                 "tz": "z_mm", "dx": "marker_x_mm", "dy": "marker_y_mm", "dz": "marker_z_mm"}
        for e in estimates:
            if e.effect in (DeviceRegistration.name, MarkerOffset.name) and np.isfinite(
                    e.std_error):
                std[names[e.name]] = float(e.std_error * 1e3)
        effects = [make_effect(self.robot, e.label, e.param_dict()) for e in fitted.effects
                   if not e.setup]
        return ElastostaticModel(self.robot, effects), DeviceFrame(R, t, c, std)


def prepare_device_setup(
    model: ElastostaticModel,
    data: MeasurementSet,
    held: DeviceFrame | None = None,
    marker: FloatArray | None = None,
) -> DeviceSetup:
    """Decide what is held and what is fitted, and compute the starting registration.

    Args:
        model: The model of the robot file.
        data: Device-frame samples.
        held: A known registration (``--device-to-base FILE`` or the robot file's
            ``[device_frame]``): held as given, with its marker offset unless ``marker``.
        marker: A known marker offset in the tool frame [m].

    Raises:
        IdentificationError: Too few poses to register (says how many are needed).
    """
    if held is not None:
        frame = held if marker is None else replace(held, marker=np.asarray(marker, float))
        return DeviceSetup(frame, False, False, model.robot)
    frame = estimate_device_frame(model, data, marker)
    return DeviceSetup(frame, True, marker is None, model.robot)
