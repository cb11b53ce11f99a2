"""The base model: linear torsional springs in the joints (seed 000 eq. 11, seed 001 eq. 7)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import (
    ComplianceEffect,
    EffectGroups,
    FloatArray,
    PoseBatch,
)


class JointCompliance(ComplianceEffect):
    """dX = J diag(c) J^T F with c_k = 1/k_k the joint compliances [rad/(N m)].

    When the robot description gives link masses (a URDF with inertials), the links' own
    weight loads the springs too: dX = J diag(c) (J^T F + tau_g(q)),
    tau_g = -g(q) (:meth:`~rfsw_plan.robot.kinematics.Robot.gravity_torque`).

    The regressor is seed 000 eq. 14 (seed 001 eq. 9): column k is J_k (J_k^T F), so
    dX = W c and c is identified by least squares (eq. 15).
    """

    name = "joint_compliance"
    description = (
        "Each joint is a linear torsional spring about its own axis: the joint torque "
        "J^T F turns it by tau/k, which moves the TCP by J dq."
    )

    def join(self, groups: EffectGroups) -> None:
        """The base of the model: its joint stiffness (and a compliance effect like others)."""
        groups.joint = self
        super().join(groups)

    #: Compliance 1/k [rad/(N m)]: >= 0 (0 = rigid), at most that of a 1 N m/rad joint.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {"c": (0.0, 1.0)}
    param_units: ClassVar[Mapping[str, str]] = {"c": "rad/(N m)"}
    #: A joint softer than 100 N m/rad (1e-2 rad/(N m)) is ten times softer than the smallest
    #: harmonic drive (about 1e3 N m/rad): a fit that wants it stands in for another effect.
    plausible_limits: ClassVar[Mapping[str, float]] = {"c": 1e-2}

    def param_names(self) -> tuple[str, ...]:
        return tuple(f"c{j + 1}" for j in range(self.robot.nq))

    def prior(self) -> FloatArray:
        return 1.0 / np.asarray(self.robot.stiffness, dtype=float)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """The catalogue compliances, each off by a factor 0.5-2 (measured joint stiffnesses
        differ from the catalogue by tens of percent)."""
        lo, hi = self.param_ranges["c"]
        c = np.clip(self.prior() * rng.uniform(0.5, 2.0, self.robot.nq), lo, hi)
        return dict(zip(self.param_names(), c.tolist(), strict=True))

    @staticmethod
    def torques(batch: PoseBatch, wrench: FloatArray) -> FloatArray:
        """Joint torques J^T F plus the links' own weight (:meth:`Robot.gravity_torque`,
        zero without link masses) [N m], shape (m, n)."""
        tau = np.matmul(wrench[:, None, :], batch.J)[:, 0]
        if batch.robot.has_link_masses:
            if "link_gravity" not in batch.cache:
                batch.cache["link_gravity"] = batch.robot.gravity_torque(batch.q)
            tau = tau + batch.cache["link_gravity"]
        return tau

    def deflection_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        return batch.J * self.torques(batch, wrench)[:, None, :]

    def deflection(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        tau = self.torques(batch, wrench)
        return np.matmul(batch.J, (tau * theta)[:, :, None])[:, :, 0]  # J diag(c) (J^T F + g)

    def cartesian_compliance(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        return np.matmul(batch.J * theta, batch.J.transpose(0, 2, 1))
