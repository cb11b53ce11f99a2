"""A user-defined effect: the link after joint N bends like a cantilever beam.

Load it with ``rfsw-plan validate --effects examples/effects/link_bending.py ...`` and name it
``link_bending:jN`` (N = 2: the upper arm of a six-axis robot). The link runs from joint N's
origin p_a to joint N+1's origin p_b (length L, unit axis e); the force f at the TCP (base
frame [N]) reaches the link's free end, and its part across the link bends it (Euler-Bernoulli
cantilever, end load): tip deflection f_perp L^3 / (3 EI), tip rotation e x f_perp L^2 / (2 EI).
The TCP moves with the tip: dX = [delta + theta x (p_tcp - p_b); theta]. Linear in c = 1/EI
[1/(N m^2)]; moments at the TCP are left out.
"""

from typing import ClassVar

import numpy as np

from rfsw_plan.elastostatics.effects.base import ComplianceEffect, PoseBatch, cross3


class LinkBending(ComplianceEffect):
    name = "link_bending"
    description = "The link after joint N bends like a beam under the force it carries."
    per_joint = True
    param_ranges: ClassVar = {"c": (0.0, 1e-3)}  # 1/EI >= 0 [1/(N m^2)]
    param_units: ClassVar = {"c": "1/(N m^2)"}

    def param_names(self) -> tuple[str, ...]:
        return ("c",)

    def prior(self) -> np.ndarray:
        return np.zeros(1)

    def plausible_params(self, batch: PoseBatch, wrench: np.ndarray, rng) -> dict[str, float]:
        return {"c": 1.0 / rng.uniform(3e5, 3e6)}  # EI of a cast arm [N m^2]

    def deflection_regressor(self, batch: PoseBatch, wrench, theta) -> np.ndarray:
        j = self.joint
        p_a = batch.frames[:, j, :3, 3]
        p_b = batch.frames[:, j + 1, :3, 3] if j + 1 < batch.q.shape[1] else batch.T[:, :3, 3]
        L = np.maximum(np.linalg.norm(p_b - p_a, axis=1, keepdims=True), 1e-9)  # [m]
        e = (p_b - p_a) / L
        f = np.broadcast_to(wrench, (len(batch), 6))[:, :3]
        f_perp = f - np.sum(f * e, axis=1, keepdims=True) * e
        theta_tip = cross3(e, f_perp) * L**2 / 2
        out = np.zeros((len(batch), 6, 1))
        out[:, :3, 0] = f_perp * L**3 / 3 + cross3(theta_tip, batch.T[:, :3, 3] - p_b)
        out[:, 3:, 0] = theta_tip
        return out

    def deflection(self, batch: PoseBatch, wrench, theta) -> np.ndarray:
        return self.deflection_regressor(batch, wrench, theta)[:, :, 0] * theta[0]


if __name__ == "__main__":  # a plug-in module: running it only explains how to load it
    import argparse

    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    print("link_bending.py is an effect plug-in: load it with rfsw-plan validate --effects "
          "examples/effects/link_bending.py")
