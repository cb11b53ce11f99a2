"""Where the measuring device stands: a small rigid correction of the device registration."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray, GeometricEffect, PoseBatch


class DeviceRegistration(GeometricEffect):
    """Small rigid motion of the measured points: the device->base registration's error.

    Measured positions in a device frame (laser tracker, motion capture) are brought into the
    base frame with the current registration estimate; what remains of its error is a small
    rotation omega [rad] and translation tau [m] of all measured points (base frame):

        dX = [tau + omega x p; omega],   p the predicted tracked point [m],

    linear in (omega, tau). Identification fits it jointly with everything else;
    :func:`rfsw_plan.elastostatics.registration.fold_setup` folds it back into the
    registration. It is part of the measurement set-up, not of the robot: it is never suggested
    as a missing effect and never dropped in favour of a joint offset it is collinear with.
    """

    name = "device_registration"
    description = (
        "The measuring device's frame is not exactly where the registration puts it: every "
        "measured point is off by the same small rotation and translation."
    )
    setup = True
    param_units: ClassVar[Mapping[str, str]] = (
        {"wx": "rad", "wy": "rad", "wz": "rad", "tx": "m", "ty": "m", "tz": "m"})

    def param_names(self) -> tuple[str, ...]:
        return ("wx", "wy", "wz", "tx", "ty", "tz")

    def prior(self) -> FloatArray:
        return np.zeros(6)

    def offset_regressor(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        p = batch.T[:, :3, 3]
        out = np.zeros((len(batch), 6, 6))
        # omega x p = -[p]x omega
        out[:, 0, 1], out[:, 0, 2] = p[:, 2], -p[:, 1]
        out[:, 1, 0], out[:, 1, 2] = -p[:, 2], p[:, 0]
        out[:, 2, 0], out[:, 2, 1] = p[:, 1], -p[:, 0]
        out[:, 3:, :3] = np.eye(3)
        out[:, :3, 3:] = np.eye(3)
        return out

    def offset(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        return np.einsum("map,p->ma", self.offset_regressor(batch, theta), theta)


class MarkerOffset(GeometricEffect):
    """The tracked marker's offset from the TCP, in the tool frame: dX = [R dc; 0] [m].

    Linear in dc. Part of the measurement set-up like :class:`DeviceRegistration`.
    """

    name = "marker_offset"
    description = (
        "The tracked point (reflector, rigid-body marker) sits at an offset from the TCP, "
        "fixed in the tool frame."
    )
    setup = True

    param_units: ClassVar[Mapping[str, str]] = {"dx": "m", "dy": "m", "dz": "m"}

    def param_names(self) -> tuple[str, ...]:
        return ("dx", "dy", "dz")

    def prior(self) -> FloatArray:
        return np.zeros(3)

    def offset_regressor(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        out = np.zeros((len(batch), 6, 3))
        out[:, :3, :] = batch.T[:, :3, :3]
        return out

    def offset(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        return np.einsum("map,p->ma", self.offset_regressor(batch, theta), theta)
