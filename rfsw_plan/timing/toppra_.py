"""TOPPRA adapter: the largest limit-feasible path speed along a joint path q(s).

The only module that imports ``toppra``. TOPPRA (Pham & Pham, time-optimal path
parameterisation by reachability analysis) computes, at each grid point of the path, the set of
path velocities sdot that joint velocity and acceleration limits allow; the smallest upper bound
along the path is the highest speed the path can be driven at.

Like the rest of the library this module never configures logging (no handlers, no levels):
the application does (the CLI quietens the ``toppra`` logger in ``rfsw_plan.cli.main``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PathSpeedLimit:
    """Largest feasible path speed.

    Attributes:
        max_speed: min over the grid of the controllable sdot upper bound [m/s].
        s_at: Arc length where it is reached [m].
        sdot_max: Upper bound of sdot at each grid point [m/s], (N,).
        grid: Grid arc lengths [m], (N,).
    """

    max_speed: float
    s_at: float
    sdot_max: FloatArray
    grid: FloatArray


def max_path_speed(
    s: FloatArray, q: FloatArray, vel: FloatArray, acc: FloatArray, n_grid: int = 400
) -> PathSpeedLimit:
    """Largest path speed allowed by joint velocity and acceleration limits (TOPPRA).

    Args:
        s: Waypoint arc lengths [m], (k,), increasing.
        q: Joint values at the waypoints [rad], (k, n).
        vel: Joint velocity limits [rad/s], (n,).
        acc: Joint acceleration limits [rad/s^2], (n,).
        n_grid: Grid points of the reachability analysis.
    """
    import toppra as ta
    import toppra.algorithm as algo
    import toppra.constraint as constraint

    path = ta.SplineInterpolator(np.asarray(s, float), np.asarray(q, float))
    pc_vel = constraint.JointVelocityConstraint(np.column_stack([-vel, vel]))
    pc_acc = constraint.JointAccelerationConstraint(np.column_stack([-acc, acc]))
    grid = np.linspace(s[0], s[-1], max(n_grid, 3))
    inst = algo.TOPPRA([pc_vel, pc_acc], path, gridpoints=grid,
                       parametrizer="ParametrizeConstAccel")
    K = inst.compute_feasible_sets()
    if K is None or not np.all(np.isfinite(K)):
        return PathSpeedLimit(0.0, float(s[0]), np.zeros(len(grid)), grid)
    xmax = np.maximum(K[:, 1], 0.0)
    sd = np.sqrt(xmax)
    i = int(np.argmin(sd))
    return PathSpeedLimit(float(sd[i]), float(grid[i]), sd, grid)
