"""Compliance of the stack between the robot's last joint and the TCP: a 6x6 Cartesian spring.

Seed 001's ZK-500 carries a 150 kg electric spindle on an SRI M4347D1 six-axis force sensor
(§2.1); the joint stiffness of its Table 3 describes the joints only (§2.2.2: "the deformations
of the links are often disregarded"). The flange, the sensor, the spindle housing and its
bearings, the tool holder and the tool are one more elastic body between joint 6 and the pin.
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
#: ASSUMED rotational stiffness of the same stack [N m/rad] (order of a large sensor's bending
#: stiffness: 1e7 N m/rad turns 1 kN m into 0.1 mrad).
STACK_ROTATIONAL_NM_PER_RAD = 1e7


class FlangeCompliance(ComplianceEffect):
    """A 6x6 diagonal spring between the last chain joint and the TCP (sensor, spindle, tool).

    The spring sits at the origin o of the last chain joint's frame with its axes along the TCP
    frame (rotation R). Its six unit displacements move the TCP by the twists (base frame)

        translation along R e_i:  j_i = [R e_i; 0]                    (i = x, y, z)
        rotation about R e_i:     j_i = [(R e_i) x (p - o); R e_i]    (i = rx, ry, rz)

    and under the TCP wrench W = (F, M) (base frame) each spring carries j_i^T W (the force
    along its axis, or the moment M + (p - o) x F about it), so, as for seed 002's springs
    (eq. 2) and seed 001 eq. 7 with a Cartesian compliance added in series:

        dX = sum_i c_i j_i (j_i^T W)

    Parameters c_x, c_y, c_z are translational compliances [m/N] and c_rx, c_ry, c_rz
    rotational ones [rad/(N m)], along/about the TCP frame's axes (c_z along the tool axis).
    """

    name = "flange_compliance"
    description = (
        "The force sensor, spindle and tool between joint 6 and the pin are not rigid: a 6x6 "
        "Cartesian spring in series with the joints, axes along the tool frame."
    )

    #: >= 0 (0 = rigid); 1e-5 m/N is 10 mm/kN, 1e-4 rad/(N m) is 0.1 rad per kN m.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {
        "c_x": (0.0, 1e-5), "c_y": (0.0, 1e-5), "c_z": (0.0, 1e-5),
        "c_rx": (0.0, 1e-4), "c_ry": (0.0, 1e-4), "c_rz": (0.0, 1e-4),
    }
    param_units: ClassVar[Mapping[str, str]] = {
        "c_x": "m/N", "c_y": "m/N", "c_z": "m/N",
        "c_rx": "rad/(N m)", "c_ry": "rad/(N m)", "c_rz": "rad/(N m)",
    }

    def param_names(self) -> tuple[str, ...]:
        return ("c_x", "c_y", "c_z", "c_rx", "c_ry", "c_rz")

    def prior(self) -> FloatArray:
        """A stiff stack: 1 / STACK_TRANSLATIONAL_N_PER_M and 1 / STACK_ROTATIONAL_NM_PER_RAD."""
        return np.array([1.0 / STACK_TRANSLATIONAL_N_PER_M] * 3
                        + [1.0 / STACK_ROTATIONAL_NM_PER_RAD] * 3)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Each compliance 0.5-5 times the stiff-stack prior (a softer sensor or holder)."""
        c = self.prior() * rng.uniform(0.5, 5.0, 6)
        return dict(zip(self.param_names(), c.tolist(), strict=True))

    def twists(self, batch: PoseBatch) -> FloatArray:
        """TCP twists of the six unit spring displacements, base frame, shape (m, 6, 6)."""
        R = batch.T[:, :3, :3]  # columns: the TCP frame's axes in the base frame
        r = batch.T[:, :3, 3] - batch.frames[:, -1, :3, 3]  # (m, 3) [m], o -> TCP
        out = np.zeros((len(batch), 6, 6))
        out[:, :3, :3] = R
        # (R e_i) x r for each column i, written out as in tilting_compliance.
        out[:, 0, 3:] = R[:, 1, :] * r[:, 2, None] - R[:, 2, :] * r[:, 1, None]
        out[:, 1, 3:] = R[:, 2, :] * r[:, 0, None] - R[:, 0, :] * r[:, 2, None]
        out[:, 2, 3:] = R[:, 0, :] * r[:, 1, None] - R[:, 1, :] * r[:, 0, None]
        out[:, 3:, 3:] = R
        return out

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        j = self.twists(batch)
        load = np.matmul(wrench[:, None, :], j)  # spring forces/moments [N, N m], (m, 1, 6)
        return j * load

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return self.deflection_regressor(batch, wrench, theta) @ theta

    def cartesian_compliance(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        j = self.twists(batch)
        return np.matmul(j * theta, j.transpose(0, 2, 1))
