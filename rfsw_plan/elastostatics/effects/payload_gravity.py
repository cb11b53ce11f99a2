"""The weight of the spindle and tool, loading the joints in every pose."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch, WrenchEffect

#: Standard gravity [m/s^2], acting along -Z of the robot base frame (floor-mounted robot).
GRAVITY = 9.80665
#: Prior spindle mass [kg]: seed 001's FSW spindle.
PRIOR_MASS_KG = 150.0
#: Prior centre of mass in the tool frame [m]: on the tool axis, 0.25 m behind the TCP
#: (towards the flange; the tool frame's z points out of the spindle towards the workpiece).
PRIOR_COM_M = (0.0, 0.0, -0.25)


class PayloadGravity(WrenchEffect):
    """Gravity wrench of the spindle and tool, added to the logged wrench.

    Assumption: the force sensor sits between flange and spindle and is tared (or load-
    compensated by the controller) with the spindle mounted, so the logged wrench is the
    process wrench only; the joints still carry the spindle's weight, which the base model
    does not see. The correction, wrench on the tool at the TCP in the base frame [N, N m]:

        dF = [f; (R s) x f],   f = -m g e_z,   s = m r_c,

    with R the TCP orientation, m [kg] the mass and r_c [m] the centre of mass in the tool
    frame. The parameters are m and the first moment s = m r_c = (m_rx, m_ry, m_rz) [kg m],
    so dF is linear in them (one least-squares step; with the joint compliance also free the
    model is bilinear and Gauss-Newton iterates). r_c = s / m.
    """

    name = "payload_gravity"
    description = (
        "The spindle and tool weigh as much as a person or more: their weight and its lever "
        "arm load every joint in every pose, also when there is no process force."
    )

    #: Mass [kg] >= 0 up to 10 t; first moments m r [kg m] of at most 10 t at 1 m.
    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = (
        {"m": (0.0, 1e4), "m_rx": (-1e4, 1e4), "m_ry": (-1e4, 1e4), "m_rz": (-1e4, 1e4)})
    param_units: ClassVar[Mapping[str, str]] = (
        {"m": "kg", "m_rx": "kg m", "m_ry": "kg m", "m_rz": "kg m"})

    def param_names(self) -> tuple[str, ...]:
        return ("m", "m_rx", "m_ry", "m_rz")

    def prior(self) -> FloatArray:
        return np.array([PRIOR_MASS_KG, *(PRIOR_MASS_KG * np.asarray(PRIOR_COM_M))])

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """An FSW spindle of 80-200 kg, its centre of mass 0.15-0.35 m behind the TCP on the
        tool axis within ~2 cm (tool frame)."""
        m = rng.uniform(80.0, 200.0)
        r = np.array([rng.normal(0, 0.02), rng.normal(0, 0.02), -rng.uniform(0.15, 0.35)])
        return {"m": m, "m_rx": m * r[0], "m_ry": m * r[1], "m_rz": m * r[2]}

    def wrench_regressor(
        self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray
    ) -> FloatArray:
        R = batch.T[:, :3, :3]
        out = np.zeros((len(batch), 6, 4))
        out[:, 2, 0] = -GRAVITY  # force of unit mass along -Z
        # Moment (R s) x (-g e_z) = g (-(R s)_y, (R s)_x, 0), linear in s.
        out[:, 3, 1:] = -GRAVITY * R[:, 1, :]
        out[:, 4, 1:] = GRAVITY * R[:, 0, :]
        return out

    def delta_wrench(self, batch: PoseBatch, wrench: FloatArray, theta: FloatArray) -> FloatArray:
        return np.einsum("map,p->ma", self.wrench_regressor(batch, wrench, theta), theta)

    def tool_load(self) -> tuple[float, FloatArray] | None:
        """Mass m [kg] and centre of mass r_c = s / m in the TCP frame [m] (None if m = 0)."""
        m = float(self.params[0])
        return (m, self.centre_of_mass()) if m > 0 else None

    def centre_of_mass(self, theta: FloatArray | None = None) -> FloatArray:
        """Centre of mass r_c = s / m in the tool frame [m], shape (3,)."""
        th = self.params if theta is None else theta
        return np.asarray(th[1:4], dtype=float) / float(th[0])
