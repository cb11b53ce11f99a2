"""The weld window: where the pin may be relative to the joint line.

Seed 000 §3.1: butt welds of 3 mm AA5754 with a 3 mm pin are sound for pin offsets from
-1.25 mm (retreating side) to +0.7 mm (advancing side); outside, lack-of-penetration and
kissing-bond defects appear. The real-time compensation of seed 000 aimed at +-1 mm.
"""

from __future__ import annotations

from dataclasses import dataclass

from rfsw_plan.exceptions import InputError


@dataclass(frozen=True)
class WeldWindow:
    """Allowed lateral pin offset, positive toward the advancing side [m].

    Attributes:
        lower: Lower bound (retreating side) [m]; seed 000: -1.25e-3.
        upper: Upper bound (advancing side) [m]; seed 000: +0.7e-3.
        target: Half-width of the symmetric operating target [m]; seed 000: 1e-3.
    """

    lower: float = -1.25e-3
    upper: float = 0.7e-3
    target: float = 1.0e-3

    def __post_init__(self) -> None:
        if not self.lower < self.upper:
            raise InputError(
                "window", "lower_mm/upper_mm",
                f"lower {self.lower * 1e3:g} mm is not below upper {self.upper * 1e3:g} mm",
                "lower < upper",
            )
        if self.target <= 0:
            raise InputError("window", "target_mm", f"got {self.target * 1e3:g}", "> 0")

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
