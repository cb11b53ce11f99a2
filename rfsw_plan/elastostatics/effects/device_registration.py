"""Where the measuring device stands: a small rigid correction of the device registration."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray, GeometricEffect, PoseBatch


def _random_direction(rng: np.random.Generator) -> FloatArray:
    """A unit vector in a uniformly random direction, shape (3,)."""
    u = rng.normal(size=3)
    out: FloatArray = u / np.linalg.norm(u)
    return out


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
    #: A small correction: rotations [rad] within +-0.5 rad (the first-order model omega x p
    #: holds only for small angles), translations [m] within +-1 m.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = (
        {"wx": (-0.5, 0.5), "wy": (-0.5, 0.5), "wz": (-0.5, 0.5),
         "tx": (-1.0, 1.0), "ty": (-1.0, 1.0), "tz": (-1.0, 1.0)})
    param_units: ClassVar[Mapping[str, str]] = (
        {"wx": "rad", "wy": "rad", "wz": "rad", "tx": "m", "ty": "m", "tz": "m"})

    def param_names(self) -> tuple[str, ...]:
        return ("wx", "wy", "wz", "tx", "ty", "tz")

    def prior(self) -> FloatArray:
        return np.zeros(6)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """A registration off by 0.005-0.02 deg about a random axis and 0.05-0.3 mm along a
        random direction (a laser tracker registered on a few reference nests)."""
        return dict(zip(self.param_names(), [
            *(_random_direction(rng) * np.radians(rng.uniform(0.005, 0.02))).tolist(),
            *(_random_direction(rng) * rng.uniform(0.05e-3, 0.3e-3)).tolist()], strict=True))

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

    #: Marker offset [m]: within +-1 m of the TCP.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = (
        {"dx": (-1.0, 1.0), "dy": (-1.0, 1.0), "dz": (-1.0, 1.0)})
    param_units: ClassVar[Mapping[str, str]] = {"dx": "m", "dy": "m", "dz": "m"}

    def param_names(self) -> tuple[str, ...]:
        return ("dx", "dy", "dz")

    def prior(self) -> FloatArray:
        return np.zeros(3)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """The marker 0.5-5 mm from where the set-up assumes it, in a random direction (a
        reflector nest fixed on the spindle by hand, not measured)."""
        dc = _random_direction(rng) * rng.uniform(0.5e-3, 5e-3)
        return dict(zip(self.param_names(), dc.tolist(), strict=True))

    def offset_regressor(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        out = np.zeros((len(batch), 6, 3))
        out[:, :3, :] = batch.T[:, :3, :3]
        return out

    def offset(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        return np.einsum("map,p->ma", self.offset_regressor(batch, theta), theta)
