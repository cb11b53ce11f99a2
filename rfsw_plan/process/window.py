"""The weld window: where the pin may be relative to the joint line.

Seed 000 §3.1: butt welds of 3 mm AA5754 with a 3 mm pin are sound for pin offsets from
-1.25 mm (retreating side) to +0.7 mm (advancing side); outside, lack-of-penetration and
kissing-bond defects appear. The real-time compensation of seed 000 aimed at +-1 mm.

The weld envelope (issue 32) adds the other quantities that decide the weld, each around its
planned value:

* **depth**: the pin tip along the plate normal, relative to the planned depth. Seed 001
  §4, Fig. 10: with a 4.8 mm pin, 4.2 mm of penetration (0.6 mm shallow) was already a
  lack-of-penetration defect and more than 5 mm (0.2 mm deep) was excessive. The default
  window is 0.5 mm shallow (the seed's defective 0.6 mm less 0.1 mm; the seed gives no finer
  threshold) to 0.2 mm deep (the seed's excessive bound).
* **tilt**: work angle (about the travel direction) and travel angle (about the lateral
  direction) of the tool axis within ``tilt_tol`` of the planned tilt. No seed bounds it;
  the default 0.5 deg is ASSUMED (a quarter of seed 001's 2 deg tilt).
* **speed**: the pin's travel speed along the seam within ``speed_tol`` of the weld speed
  at constant-speed weld samples (heat input per mm ~ 1 / v). No seed bounds it; the
  default 5 % is ASSUMED.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rfsw_plan.exceptions import InputError


@dataclass(frozen=True)
class WeldWindow:
    """Allowed lateral pin offset, positive toward the advancing side [m].

    Attributes:
        lower: Lower bound (retreating side) [m]; seed 000: -1.25e-3.
        upper: Upper bound (advancing side) [m]; seed 000: +0.7e-3.
        target: Half-width of the symmetric operating target [m]; seed 000: 1e-3.
        depth_shallow: How far the pin tip may stay above the planned depth, along the plate
            normal [m]; seed 001 Fig. 10: 0.6 mm shallow was defective, default 0.5e-3.
        depth_deep: How far it may go below the planned depth [m]; seed 001 Fig. 10: more
            than 0.2 mm deep was excessive, default 0.2e-3.
        tilt_tol: Largest deviation of the work and travel angles from the planned tilt [rad]
            (ASSUMED 0.5 deg).
        speed_tol: Largest relative deviation of the pin's travel speed from the weld speed
            at constant-speed weld samples [1] (ASSUMED 0.05).
    """

    lower: float = -1.25e-3
    upper: float = 0.7e-3
    target: float = 1.0e-3
    depth_shallow: float = 0.5e-3
    depth_deep: float = 0.2e-3
    tilt_tol: float = float(np.deg2rad(0.5))
    speed_tol: float = 0.05

    def __post_init__(self) -> None:
        if not self.lower < self.upper:
            raise InputError(
                "window", "lower_mm/upper_mm",
                f"lower {self.lower * 1e3:g} mm is not below upper {self.upper * 1e3:g} mm",
                "lower < upper",
            )
        if self.target <= 0:
            raise InputError("window", "target_mm", f"got {self.target * 1e3:g}", "> 0")
        for key, v, scale in (("depth_shallow_mm", self.depth_shallow, 1e3),
                              ("depth_deep_mm", self.depth_deep, 1e3),
                              ("tilt_tol_deg", self.tilt_tol, float(np.rad2deg(1.0))),
                              ("speed_tol_pct", self.speed_tol, 100.0)):
            if not (np.isfinite(v) and v > 0):
                raise InputError("window", key, f"got {v * scale:g}", "> 0")

    def depth_margin(self, e: float) -> float:
        """Signed distance of a depth error e [m] (pin tip above the planned depth along the
        plate normal, positive shallow) to the nearest depth bound (>= 0 inside) [m]."""
        return min(e + self.depth_deep, self.depth_shallow - e)

    @property
    def centre(self) -> float:
        """Middle of the window [m]."""
        return 0.5 * (self.lower + self.upper)

    @property
    def half_width(self) -> float:
        """Half the window width [m]."""
        return 0.5 * (self.upper - self.lower)

    def margin(self, e: float) -> float:
        """Signed distance of a lateral error e [m] to the nearest bound (>= 0 inside) [m]."""
        return min(e - self.lower, self.upper - e)

    def contains(self, e: float) -> bool:
        """True if the lateral error e [m] is inside the window."""
        return self.lower <= e <= self.upper
