"""Translational compliance of the stack between the robot's last joint and the TCP.

Seed 001's ZK-500 carries a 150 kg electric spindle on an SRI M4347D1 six-axis force sensor
(§2.1); the joint stiffness of its Table 3 describes the joints only (§2.2.2: "the deformations
of the links are often disregarded"). The flange, the sensor, the spindle housing and its
bearings, the tool holder and the tool are one more elastic body between joint 6 and the pin.

Of that body's 6x6 Cartesian spring only the translational block is new: its rotational block is
rotational springs at the wrist, which the library already has (``tilting_compliance:j6`` about
the two axes normal to joint 6, the joint-6 compliance about its own axis; with a stiff stack
between them the rotations are indistinguishable in position data).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import ComplianceEffect, FloatArray, PoseBatch

#: ASSUMED translational stiffness of a stiff tool stack [N/m]: 1e8 N/m = 100 kN/mm, the order
#: of a 10-20 kN six-axis sensor and of a spindle's angular-contact bearing set (a real stack is
#: no stiffer than its softest member, so 2e7 N/m to 1e9 N/m spans real stacks).
STACK_TRANSLATIONAL_N_PER_M = 1e8


class FlangeCompliance(ComplianceEffect):
    """Translational springs along the TCP frame's axes between joint 6 and the TCP.

    The TCP frame's axes R e_i (i = x, y, z; R the TCP rotation, base frame) are the spring
    axes; a unit stretch of spring i moves the TCP by j_i = [R e_i; 0], and under the TCP
    wrench W = (F, M) (base frame) the spring carries the force j_i^T W = (R e_i) . F, so, in
    the form of seed 002's springs (eq. 2) and in series with seed 001 eq. 7:

        dX = sum_i c_i j_i (j_i^T W) = [R diag(c) R^T F; 0]

    Parameters c_x, c_y, c_z are compliances [m/N] along the TCP frame's x, y and z (the tool
    axis) axes.
    """

    name = "flange_compliance"
    description = (
        "The force sensor, spindle and tool between joint 6 and the pin give way in translation: "
        "three springs along the tool frame's axes, in series with the joints."
    )

    #: >= 0 (0 = rigid); 1e-5 m/N is 10 mm/kN.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {
        "c_x": (0.0, 1e-5), "c_y": (0.0, 1e-5), "c_z": (0.0, 1e-5)}
    param_units: ClassVar[Mapping[str, str]] = {"c_x": "m/N", "c_y": "m/N", "c_z": "m/N"}

    def param_names(self) -> tuple[str, ...]:
        return ("c_x", "c_y", "c_z")

    def prior(self) -> FloatArray:
        """A stiff stack: 1 / STACK_TRANSLATIONAL_N_PER_M along each axis."""
        return np.full(3, 1.0 / STACK_TRANSLATIONAL_N_PER_M)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Each compliance 2-10 times the stiff-stack prior (10-50 kN/mm: a softer sensor,
        adapter or tool holder)."""
        c = self.prior() * rng.uniform(2.0, 10.0, 3)
        return dict(zip(self.param_names(), c.tolist(), strict=True))

    def twists(self, batch: PoseBatch) -> FloatArray:
        """TCP twists of the three unit spring stretches, base frame, shape (m, 6, 3)."""
        out = np.zeros((len(batch), 6, 3))
        out[:, :3, :] = batch.T[:, :3, :3]  # columns: the TCP frame's axes in the base frame
        return out

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        j = self.twists(batch)
        load = np.matmul(wrench[:, None, :], j)  # spring forces [N], (m, 1, 3)
        return j * load

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.deflection_regressor(batch, wrench, theta) @ theta

    def cartesian_compliance(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        j = self.twists(batch)
        return np.matmul(j * theta, j.transpose(0, 2, 1))
