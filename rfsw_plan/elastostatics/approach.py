"""The direction each joint last moved in: the history a lost-motion effect needs.

A position-controlled joint with play in its gears, and too little load to push the output
against one flank, stays on the flank its last motion drove it to: the output lags the motor
by half the play in the direction of motion. Which flank is set by the *approach direction*,
which a static sample does not show but the order of the samples does. For joint j at sample
i (in time order),

    a[i, j] = sign(q[i, j] - q[k, j]),  k the last earlier sample where joint j stood more
              than MOVE_TOL away from q[i, j] (and 0 before any motion),

i.e. a joint that did not move between two samples keeps its approach direction. Readers
compute it once on the whole recording (so that subsets and cross-validation folds keep each
sample's real history) from the time column, or the row order, or take it from explicit
``dir_qN`` columns.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: A joint moved between two samples when its value changed by more than this [rad or m]:
#: above the scatter of the averaged encoder readings of one static posture (~1e-5 rad),
#: below any commanded move between postures. Same scale as the repeat tolerance of the
#: noise-floor estimate.
MOVE_TOL = 1e-4


def approach_directions(q: FloatArray, t: FloatArray | None = None) -> FloatArray:
    """Approach direction of every joint at every sample (see the module docstring).

    Args:
        q: Encoder joint values [rad or m], shape (m, n), in the file's row order.
        t: Time of each sample [s], shape (m,), or None: the row order is the time order.

    Returns:
        +1, -1 or 0 per sample and joint, shape (m, n), in the rows' order.
    """
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    order = np.arange(Q.shape[0]) if t is None else np.argsort(np.asarray(t), kind="stable")
    out = np.zeros_like(Q)
    if Q.shape[0] == 0:
        return out
    last = np.zeros(Q.shape[1])  # direction of the last motion
    anchor = Q[order[0]].copy()  # where each joint last stood still
    for i in order[1:]:
        d = Q[i] - anchor
        moved = np.abs(d) > MOVE_TOL
        last = np.where(moved, np.sign(d), last)
        anchor = np.where(moved, Q[i], anchor)
        out[i] = last
    return out


def check_directions(values: FloatArray) -> NDArray[np.bool_]:
    """Mask of entries that are not a valid approach direction (-1, 0 or +1)."""
    v = np.asarray(values, dtype=float)
    bad: NDArray[np.bool_] = ~np.isin(v, (-1.0, 0.0, 1.0))
    return bad
