"""TOPPRA adapter: the largest limit-feasible path speed along a joint path q(s).

The only module that imports ``toppra``. TOPPRA (Pham & Pham, time-optimal path
parameterisation by reachability analysis) computes, at each grid point of the path, the set of
path velocities sdot that joint velocity and acceleration limits allow; the smallest upper bound
along the path is the highest speed the path can be driven at.

Like the rest of the library this module never configures logging (no handlers, no levels):
the application does (the CLI quietens the ``toppra`` logger in ``rfsw_plan.cli.main``).

``toppra`` imports ``matplotlib.pyplot`` at module level (``toppra.algorithm.algorithm`` and
``toppra.parametrizer``, for its debugging plots), about a second of every start that times a
path; :func:`_import_toppra` keeps it out (issue 41).
"""

from __future__ import annotations

import sys
import types
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

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
    ta = _import_toppra()
    algo, constraint = ta.algorithm, ta.constraint

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


class _PyplotOnFirstUse(types.ModuleType):
    """What ``toppra`` binds as ``plt``: the real ``matplotlib.pyplot``, imported when one of
    toppra's debugging plots first uses it (never, in this package)."""

    def __getattr__(self, name: str) -> Any:
        import matplotlib.pyplot

        return getattr(matplotlib.pyplot, name)


@contextmanager
def _pyplot_deferred() -> Iterator[None]:
    """While it lasts, ``import matplotlib.pyplot`` binds a :class:`_PyplotOnFirstUse` (and,
    if ``matplotlib`` is not imported yet, a stand-in parent that holds it); afterwards
    ``sys.modules`` is as before, so every other import of matplotlib gets the real one."""
    if "matplotlib.pyplot" in sys.modules:
        yield
        return
    stand_ins: dict[str, types.ModuleType] = {
        "matplotlib.pyplot": _PyplotOnFirstUse("matplotlib.pyplot")}
    if "matplotlib" not in sys.modules:
        parent = types.ModuleType("matplotlib")
        parent.pyplot = stand_ins["matplotlib.pyplot"]  # type: ignore[attr-defined]
        stand_ins["matplotlib"] = parent
    sys.modules.update(stand_ins)
    try:
        yield
    finally:
        for name, module in stand_ins.items():
            if sys.modules.get(name) is module:
                del sys.modules[name]


def _import_toppra() -> Any:
    """The ``toppra`` package with ``algorithm`` and ``constraint``, imported without
    ``matplotlib.pyplot`` (see :func:`_pyplot_deferred`)."""
    with _pyplot_deferred():
        import toppra
        import toppra.algorithm
        import toppra.constraint
    return toppra
