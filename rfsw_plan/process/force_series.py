"""The measured process-force data type that the force fit works on.

A :class:`ForceSeries` is the force (and optionally moment) a weld logged over time, in SI
units, in the base, seam or tool frame. Files are read and written in
``rfsw_plan.io.force_series``; :func:`rfsw_plan.process.force_fit.fit_process_forces` fits the
process model to it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: Frames a force series may be given in.
FORCE_FRAMES = ("base", "seam", "tool")


@dataclass(frozen=True)
class ForceSeries:
    """A measured force series (SI units).

    Attributes:
        t: Time [s], shape (N,), strictly increasing.
        force: Force on the tool at the TCP, in ``frame`` [N], shape (N, 3).
        moment: Moment on the tool at the TCP, in ``frame`` [N m], shape (N, 3), or None.
        frame: 'base', 'seam' or 'tool'.
        source: File the series came from.
    """

    t: FloatArray
    force: FloatArray
    moment: FloatArray | None
    frame: str
    source: str = "<memory>"

    def __len__(self) -> int:
        return int(self.t.shape[0])
