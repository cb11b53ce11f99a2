"""Full geometric calibration: a small pose error of every link."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray, GeometricEffect, PoseBatch, cross3

#: Key of the regressor in a batch's cache (it depends on the poses only).
_REGRESSOR_KEY = "link_errors_regressor"
#: Larger regressors are not kept (a whole 10^6-sample batch outside the fit's blocks).
_CACHE_MAX_BYTES = 32 * 2**20

#: Translation error of a link beyond this [m] is not a calibration (a wrong drawing or a
#: stand-in for another effect).
PLAUSIBLE_M = 5e-3
#: Rotation error of a link beyond this [rad] (3 deg) is not a calibration.
PLAUSIBLE_RAD = np.radians(3.0)


class LinkErrors(GeometricEffect):
    """A 6-parameter pose error of each link, in the frame of the joint before it.

    The placement of link j+1 relative to joint j's frame (after the joint's motion, its
    ``frames[:, j]``, rotation R_j, origin p_j) is off by a small translation d_j [m] and
    rotation r_j [rad], both in that frame. To first order the TCP moves by

        dX = sum_j [R_j d_j + (R_j r_j) x (p - p_j);  R_j r_j]   (base frame [m, rad]),

    p the TCP. Linear in (d, r), 6 n parameters: the full kinematic parameter set of a serial
    chain in the style of FIGAROH's ``full_params`` (6 per joint frame). Many are not
    identifiable together: the rotation about a revolute joint's axis is its zero offset, the
    last frame's translation is the tool's, the first frame's error moves the whole robot
    like a base registration. Identification names those (collinear, or absorbed by a free
    device registration or marker offset, not fitted) and fits the others with a Gaussian
    prior of zero mean and 1-sigma half their plausible size (:attr:`plausible_limits`: 5 mm
    and 3 deg, so 2.5 mm and 1.5 deg; :attr:`regularised`), which keeps the combinations the
    data does not see at zero instead of fitting noise into them. An estimate beyond the
    plausible size is reported as implausible, not as a calibration, and not kept.
    """

    name = "link_errors"
    uses_frames = True
    description = (
        "Every link is slightly off its drawing (length, twist, offsets): a full geometric "
        "calibration of the chain, which shifts the TCP by a pose-dependent amount."
    )

    param_ranges: ClassVar[Mapping[str, tuple[float, float]]] = {
        **{f"d{a}": (-0.1, 0.1) for a in "xyz"}, **{f"r{a}": (-0.5, 0.5) for a in "xyz"}}
    param_units: ClassVar[Mapping[str, str]] = {
        **{f"d{a}": "m" for a in "xyz"}, **{f"r{a}": "rad" for a in "xyz"}}
    plausible_limits: ClassVar[Mapping[str, float]] = {
        **{f"d{a}": PLAUSIBLE_M for a in "xyz"}, **{f"r{a}": float(PLAUSIBLE_RAD) for a in "xyz"}}
    regularised = True

    def param_names(self) -> tuple[str, ...]:
        return tuple(f"{k}{j + 1}" for j in range(self.robot.nq)
                     for k in ("dx", "dy", "dz", "rx", "ry", "rz"))

    def prior(self) -> FloatArray:
        return np.zeros(6 * self.robot.nq)

    def plausible_params(
        self, batch: PoseBatch, wrench: FloatArray, rng: np.random.Generator
    ) -> dict[str, float]:
        """Links off by ~0.1 mm and ~0.2 mrad per axis (1-sigma: a machined industrial arm)."""
        n = self.robot.nq
        v = np.stack([rng.normal(0, 1e-4, (n, 3)), rng.normal(0, 2e-4, (n, 3))], axis=1)
        return dict(zip(self.param_names(), v.reshape(-1).tolist(), strict=True))

    def offset_regressor(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        """d(offset)/d(theta), shape (m, 6, 6 n): the chain's frames only (the first-order
        model does not depend on theta), kept in ``batch.cache`` for the passes of one fit."""
        got: FloatArray | None = batch.cache.get(_REGRESSOR_KEY)
        if got is not None and got.shape == (len(batch), 6, 6 * self.robot.nq):
            return got
        out = self._regressor(batch)
        if out.nbytes <= _CACHE_MAX_BYTES:
            batch.cache[_REGRESSOR_KEY] = out
        return out

    def _regressor(self, batch: PoseBatch) -> FloatArray:
        m, n = len(batch), self.robot.nq
        R = batch.frames[:, :, :3, :3]  # (m, n, 3, 3)
        origin = batch.frames[:, :, :3, 3].copy()  # (m, n, 3)
        # The batch's frame of a prismatic joint sits before its travel; the link after it
        # moves with the travel q along the axis (the joint's translational Jacobian column).
        pri = np.asarray(self.robot.prismatic, dtype=bool)
        origin[:, pri] += np.moveaxis(batch.J[:, :3, pri], 1, 2) * batch.q[:, pri, None]
        arm = batch.T[:, None, :3, 3] - origin  # p - p_j, (m, n, 3)
        out = np.zeros((m, 6, n, 6))
        out[:, :3, :, :3] = np.moveaxis(R, 2, 1)  # R_j d_j
        axes = np.moveaxis(R, 3, 2)  # axes[:, j, k] = R_j e_k, (m, n, 3, 3)
        out[:, :3, :, 3:] = np.moveaxis(cross3(axes, arm[:, :, None, :]), 3, 1)
        out[:, 3:, :, 3:] = np.moveaxis(axes, 3, 1)
        return out.reshape(m, 6, 6 * n)

    def offset(self, batch: PoseBatch, theta: FloatArray) -> FloatArray:
        return np.einsum("map,p->ma", self.offset_regressor(batch, theta), theta)
