"""Force sensor frame rotated against the tool frame: the logged wrench is rotated."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch, WrenchEffect


def skew(v: FloatArray) -> FloatArray:
    """Cross-product matrices [v]x, shape (..., 3, 3) for v shape (..., 3)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def rotation_and_right_jacobian(phi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """R = exp([phi]x) and the right Jacobian J_r of SO(3), both (3, 3).

    J_r = I - (1 - cos t)/t^2 [phi]x + (t - sin t)/t^3 [phi]x^2, t = |phi|, so that
    R(phi + d) = R(phi) exp([J_r d]x) to first order; series near t = 0.
    """
    phi = np.asarray(phi, dtype=float)
    t = float(np.linalg.norm(phi))
    K = skew(phi)
    K2 = K @ K
    if t < 1e-4:
        a, b, c = 1.0 - t**2 / 6.0, 0.5 - t**2 / 24.0, 1.0 / 6.0 - t**2 / 120.0
    else:
        a, b, c = np.sin(t) / t, (1.0 - np.cos(t)) / t**2, (t - np.sin(t)) / t**3
    R = np.eye(3) + a * K + b * K2
    Jr = np.eye(3) - b * K + c * K2
    return R, Jr


class SensorMisalignment(WrenchEffect):
    """The sensor frame is the tool frame turned by a small rotation vector phi (tool frame).

    The controller expresses the sensor reading in the base frame as if the sensor were aligned,
    F_logged = R_tool F_s; in truth F = R_tool R(phi) F_s, so for force and moment alike
    (base frame, [N, N m]):

        F_true = M F_logged,   M = R_tool R(phi) R_tool^T,   dF = (M - I) F_logged.

    phi = (phi_x, phi_y, phi_z) [rad]. Not linear in phi; the regressor is the exact derivative
    d(R(phi) v)/d(phi) = -R(phi) [v]x J_r(phi) at the current phi (Gauss-Newton iterates).
    """

    name = "sensor_misalignment"
    description = (
        "The force sensor is mounted turned against the tool frame, so the logged force and "
        "moment point in slightly wrong directions."
    )
    sensor_only = True
    linear_in_params = False

    #: Rotation vector [rad]: at most half a turn per component.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = (
        {"phi_x": (-math.pi, math.pi), "phi_y": (-math.pi, math.pi),
         "phi_z": (-math.pi, math.pi)})
    param_units: ClassVar[Mapping[str, str]] = {"phi_x": "rad", "phi_y": "rad", "phi_z": "rad"}

    def param_names(self) -> tuple[str, ...]:
        return ("phi_x", "phi_y", "phi_z")

    def prior(self) -> FloatArray:
        return np.zeros(3)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """A sensor turned by 1-3 deg about a random axis (a misindexed mounting flange)."""
        u = rng.normal(size=3)
        phi = u / np.linalg.norm(u) * np.radians(rng.uniform(1.0, 3.0))
        return dict(zip(self.param_names(), phi.tolist(), strict=True))

    def delta_wrench(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6))
        Rt = batch.T[:, :3, :3]
        Rp, _ = rotation_and_right_jacobian(theta)
        M = np.einsum("mab,bc,mdc->mad", Rt, Rp, Rt)  # R_tool R(phi) R_tool^T
        out = np.empty((len(batch), 6))
        out[:, :3] = np.einsum("mab,mb->ma", M, F[:, :3]) - F[:, :3]
        out[:, 3:] = np.einsum("mab,mb->ma", M, F[:, 3:]) - F[:, 3:]
        return out

    def wrench_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        F = np.broadcast_to(np.asarray(wrench, dtype=float), (len(batch), 6))
        Rt = batch.T[:, :3, :3]
        Rp, Jr = rotation_and_right_jacobian(theta)
        out = np.empty((len(batch), 6, 3))
        for blk in (slice(0, 3), slice(3, 6)):
            v = np.einsum("mba,mb->ma", Rt, F[:, blk])  # wrench part in the tool frame
            d = -np.einsum("ab,mbc,cd->mad", Rp, skew(v), Jr)  # d(R(phi) v)/d(phi)
            out[:, blk, :] = np.einsum("mab,mbc->mac", Rt, d)
        return out

    def identifiable(self, batch: PoseBatch, wrench: FloatArray) -> str | None:
        F = np.asarray(wrench, dtype=float)
        if F.size == 0 or not np.any(np.abs(F) > 1e-9):
            return "every logged wrench is zero, so a rotation of the sensor frame changes nothing"
        return None
