"""The contract of a real-time compensation strategy, and what it sees each controller cycle.

A strategy runs inside (or beside) the robot controller. Once per controller cycle it reads
what a real controller can read, the force sensor's delayed, noisy wrench and the robot's own
joint values, and returns the correction offset the robot adds to its commanded TCP
position. The simulator (:mod:`rfsw_plan.realtime.simulator`) applies that offset one cycle
later and works out where the pin really goes.

For speed the simulator hands a strategy the whole weld at once as a
:class:`ControllerInputs` (one row per cycle). Rows are causal: row k holds only what the
controller knows at cycle k (the sensor delay is already in ``force_measured``), so a strategy
that reads row k in :meth:`Strategy.step` is a real-time controller. A strategy may override
:meth:`Strategy.run` with a vectorised version; the tests check that it equals the loop of
:meth:`Strategy.step`.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class ControllerInputs:
    """What the controller knows at each cycle of one weld (row k = cycle k).

    Model quantities are evaluated at the robot's reported joint values along the nominal
    path (the taught or planned path). The correction changes the pose by a few mm, which
    changes the model compliance only to second order (first-order linearisation, see
    :mod:`rfsw_plan.realtime.simulator`).

    Attributes:
        t: Cycle times [s], shape (K,).
        dt: Controller cycle [s].
        phase: Process phase per cycle, shape (K,).
        active: True where the compensation may act (by default from the weld start on),
            shape (K,).
        s: Nominal arc length of the tool along the seam [m], shape (K,).
        lateral: Lateral seam direction l (advancing side), base frame, shape (K, 3).
        q: Reported joint values of the nominal path [rad], shape (K, n).
        jacobian: TCP Jacobian at ``q``, base frame [v; w], shape (K, 6, n).
        force_measured: Delayed noisy wrench from the force sensor, at the TCP, base frame
            [N, N m], shape (K, 6).
        force_planned: Wrench the nominal path was planned for, base frame [N, N m],
            shape (K, 6) (zero for a taught path, which was planned for no load).
        model_deflection: Model TCP deflection under ``force_measured`` at ``q``, base frame
            [m, rad], shape (K, 6): the ``X_delta`` of seed 002 eq. 3, and the output of the
            elastostatic model block of seed 000 Fig. 14.
        model_deflection_planned: Model TCP deflection under ``force_planned`` [m, rad],
            shape (K, 6).
    """

    t: FloatArray
    dt: float
    phase: NDArray[np.str_]
    active: BoolArray
    s: FloatArray
    lateral: FloatArray
    q: FloatArray
    jacobian: FloatArray
    force_measured: FloatArray
    force_planned: FloatArray
    model_deflection: FloatArray
    model_deflection_planned: FloatArray

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def weld_duration(self) -> float:
        """Duration of the active part of the weld [s]."""
        if not np.any(self.active):
            return 0.0
        ta = self.t[self.active]
        return float(ta[-1] - ta[0] + self.dt)


class Strategy(abc.ABC):
    """A real-time compensation strategy (a controller with internal state).

    Subclasses implement :meth:`reset` and :meth:`step`; :meth:`run` loops over the cycles.
    """

    #: Registry name, e.g. ``"realtime_seed000"``.
    name: ClassVar[str]
    #: One-line description.
    description: ClassVar[str]

    @abc.abstractmethod
    def reset(self, inputs: ControllerInputs) -> None:
        """Clear the internal state before a weld; may validate the inputs.

        Raises:
            InputError: The strategy's parameters do not fit this weld (e.g. a filter
                longer than the weld).
        """

    @abc.abstractmethod
    def step(self, k: int, inputs: ControllerInputs) -> FloatArray:
        """One controller cycle.

        Args:
            k: Cycle index; only rows ``<= k`` of ``inputs`` may be read.
            inputs: The weld's controller inputs.

        Returns:
            Commanded correction offset of the TCP position, base frame [m], shape (3,).
        """

    def run(self, inputs: ControllerInputs) -> FloatArray:
        """All cycles of a weld: correction offsets, base frame [m], shape (K, 3)."""
        self.reset(inputs)
        out = np.zeros((len(inputs), 3))
        for k in range(len(inputs)):
            out[k] = self.step(k, inputs)
        return out


class NoCompensation(Strategy):
    """No real-time correction: the robot runs its nominal path open loop."""

    name = "none"
    description = "no real-time correction (open loop)"

    def reset(self, inputs: ControllerInputs) -> None:
        return None

    def step(self, k: int, inputs: ControllerInputs) -> FloatArray:
        return np.zeros(3)

    def run(self, inputs: ControllerInputs) -> FloatArray:
        return np.zeros((len(inputs), 3))
