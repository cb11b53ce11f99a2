"""The history of a sample: the direction each joint last moved in (what lost motion needs)
and the direction the load last changed in at the same pose (what hysteresis needs).

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

import itertools

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


def load_changes(q: FloatArray, wrench: FloatArray, t: FloatArray | None = None,
                 tol_n: float = 0.0) -> FloatArray:
    """The last change of the logged wrench at the same pose before each sample [N, N m].

    For sample i (in time order) at the same joint values as the sample before it (within
    MOVE_TOL), dF_i = F_i - F_{i-1} when the force changed by more than ``tol_n``, else
    dF_{i-1} (the load last went that way). A new pose starts with dF = 0: its history is
    the joints' motion (:func:`approach_directions`), not the load's.

    Args:
        q: Joint values, shape (m, n), rows in file order.
        wrench: Logged wrench, base frame [N, N m], shape (m, 6).
        t: Time of each sample [s], shape (m,), or None (row order).
        tol_n: Force change [N] below which the load counts as unchanged (the noise of a
            difference of two readings).

    Returns:
        dF per sample, base frame [N, N m], shape (m, 6), in the rows' order.
    """
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    F = np.asarray(wrench, dtype=float).reshape(-1, 6)
    order = np.arange(Q.shape[0]) if t is None else np.argsort(np.asarray(t), kind="stable")
    out = np.zeros_like(F)
    for prev, i in itertools.pairwise(order):
        if np.any(np.abs(Q[i] - Q[prev]) > MOVE_TOL):
            continue  # a new pose: no load history yet
        d = F[i] - F[prev]
        out[i] = d if np.linalg.norm(d[:3]) > tol_n else out[prev]
    return out


#: Earlier loads at the same pose kept per sample (:func:`load_history`).
HISTORY_DEPTH = 24


def load_history(q: FloatArray, wrench: FloatArray, t: FloatArray | None = None,
                 depth: int = HISTORY_DEPTH) -> FloatArray:
    """The loads logged before each sample at the same pose, most recent first [N, N m].

    For sample i (in time order) at the same joint values as the samples before it (within
    MOVE_TOL), the wrenches of those earlier samples back to the arrival at the pose, at most
    ``depth``, zero-padded (a new pose has none). What friction in a joint with play holds
    after the load is taken off: the flank the last load clear enough to move it pushed it to.

    Args:
        q: Joint values, shape (m, n), rows in file order.
        wrench: Logged wrench, base frame [N, N m], shape (m, 6).
        t: Time of each sample [s], shape (m,), or None (row order).
        depth: Loads kept per sample.

    Returns:
        Earlier loads per sample, shape (m, depth, 6), in the rows' order.
    """
    Q = np.atleast_2d(np.asarray(q, dtype=float))
    F = np.asarray(wrench, dtype=float).reshape(-1, 6)
    order = np.arange(Q.shape[0]) if t is None else np.argsort(np.asarray(t), kind="stable")
    out = np.zeros((Q.shape[0], depth, 6))
    hist: list[FloatArray] = []
    for prev, i in itertools.pairwise(order):
        if np.any(np.abs(Q[i] - Q[prev]) > MOVE_TOL):
            hist = []  # a new pose: no load history yet
            continue
        hist = [F[prev], *hist[:depth - 1]]
        out[i, :len(hist)] = hist
    return out


def change_tolerance(force_noise: float | None) -> float:
    """Force change [N] that counts as a load change: 3 sigma of the difference of two
    readings, 3 sqrt(2) sigma_F (0 when the noise is unknown)."""
    return 0.0 if force_noise is None or not np.isfinite(force_noise) else (
        3.0 * np.sqrt(2.0) * force_noise)
