"""A constant wrench offset of the force sensor."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch, WrenchEffect


class ForceSensorBias(WrenchEffect):
    """The sensor reads a constant offset b on top of the true wrench, in its own frame.

    The sensor frame is taken as the tool frame at the TCP (the logged wrench is reported at
    the TCP). With F_logged = F_true + B b, B = blockdiag(R_tool, R_tool):

        dF = F_true - F_logged = -B b   (base frame, [N, N m]),

    b = (b_fx, b_fy, b_fz [N], b_mx, b_my, b_mz [N m]) in the tool frame; a positive b_fz is a
    sensor that over-reads the force along the tool z axis. Linear in b.
    """

    name = "force_sensor_bias"
    description = (
        "The force sensor has a zero offset (drift, bad tare) that it adds to every reading, "
        "fixed in the sensor frame, so the robot is loaded differently from what is logged."
    )
    sensor_only = True

    #: Offsets [N, N m]: at most 100 kN / 100 kN m (beyond any FSW force sensor).
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = (
        {k: (-1e5, 1e5) for k in ("b_fx", "b_fy", "b_fz", "b_mx", "b_my", "b_mz")})
    param_units: ClassVar[Mapping[str, str]] = (
        {"b_fx": "N", "b_fy": "N", "b_fz": "N", "b_mx": "N m", "b_my": "N m", "b_mz": "N m"})

    def param_names(self) -> tuple[str, ...]:
        return ("b_fx", "b_fy", "b_fz", "b_mx", "b_my", "b_mz")

    def prior(self) -> FloatArray:
        return np.zeros(6)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Offsets of ~150 N and ~15 N m per axis (1-sigma; a bad tare of a large sensor)."""
        b = np.concatenate([rng.normal(0, 150.0, 3), rng.normal(0, 15.0, 3)])
        return dict(zip(self.param_names(), b.tolist(), strict=True))

    def wrench_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        R = batch.T[:, :3, :3]
        out = np.zeros((len(batch), 6, 6))
        out[:, :3, :3] = -R
        out[:, 3:, 3:] = -R
        return out

    def delta_wrench(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        R = batch.T[:, :3, :3]
        th = np.asarray(theta, dtype=float)
        return -np.concatenate(
            [np.einsum("mab,b->ma", R, th[:3]), np.einsum("mab,b->ma", R, th[3:])], axis=1
        )
