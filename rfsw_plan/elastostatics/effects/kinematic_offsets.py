"""Joint zero offsets and a tool offset: a load-independent geometric error."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray, GeometricEffect, PoseBatch


class KinematicOffsets(GeometricEffect):
    """First-order pose error of wrong joint zeros dq0 and a wrong tool centre point dt.

        dX = J dq0 + [R_tool dt; 0]   (base frame [m, rad]),

    dq0 [rad] shape (n,) on the controller joints (q_true = q_encoder + dq0), dt [m] shape (3,)
    in the tool frame (true TCP = nominal TCP + dt). Linear in (dq0, dt). A joint whose axis
    passes through the TCP (usually joint 6) has no position signature; identification keeps
    its prior and says so.
    """

    name = "kinematic_offsets"
    description = (
        "The joint zeros and the tool length are slightly wrong, which shifts the TCP by a "
        "pose-dependent amount whether or not the robot is loaded."
    )

    #: Joint zero offsets [rad] at most 0.5 rad; TCP offsets [m] at most 1 m.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = (
        {"dq": (-0.5, 0.5), "dt_x": (-1.0, 1.0), "dt_y": (-1.0, 1.0), "dt_z": (-1.0, 1.0)})
    param_units: ClassVar[Mapping[str, str]] = {"dq": "rad", "dt_x": "m", "dt_y": "m", "dt_z": "m"}
    #: A joint zero off by more than 0.2 rad (11 deg) is a wrong mastering, not an offset.
    plausible_limits: ClassVar[Mapping[str, float]] = {"dq": 0.2}

    def param_names(self) -> tuple[str, ...]:
        return (*(f"dq{j + 1}" for j in range(self.robot.nq)), "dt_x", "dt_y", "dt_z")

    def prior(self) -> FloatArray:
        return np.zeros(self.robot.nq + 3)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Joint zeros off by ~0.01 deg and the TCP by ~0.3 mm per axis (1-sigma: a robot
        after mastering, a tool measured on a presetter)."""
        v = np.concatenate([rng.normal(0, np.radians(0.01), self.robot.nq),
                            rng.normal(0, 3e-4, 3)])
        return dict(zip(self.param_names(), v.tolist(), strict=True))

    def offset_regressor(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        n = self.robot.nq
        out = np.zeros((len(batch), 6, n + 3))
        out[:, :, :n] = batch.J
        out[:, :3, n:] = batch.T[:, :3, :3]
        return out

    def offset(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        return np.einsum("map,p->ma", self.offset_regressor(batch, theta), theta)
