"""Seam frames and the load schedule: the data contract between process, planner and simulator.

Frames (all unit vectors in the robot base frame, one row per sample):

* ``t``: travel direction (seam tangent, start -> end).
* ``l``: lateral direction, pointing to the **advancing side** of the tool. For a spindle
  turning clockwise seen from above (looking down the tool axis toward the workpiece),
  l = n_surface x t; counter-clockwise flips it.
* ``n``: tool axis, pointing from the workpiece up into the spindle, tilted by the trailing
  tilt angle about ``l`` (the top of the tool leans back, against travel). The commanded TCP
  z axis is ``-n`` (pointing into the workpiece).

The lateral pin error is ``e = (p_pin - p_seam) . l`` [m], positive toward the advancing side,
and must lie in the :class:`~rfsw_plan.process.window.WeldWindow`.

Forces are the wrench the workpiece applies to the tool, at the TCP. In the seam frame its
components are ``f_t`` (along t; the traverse force resisting travel is negative), ``f_l``
(along l) and ``f_n`` (along n; the axial force pushing the tool back up is positive).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError

FloatArray = NDArray[np.float64]

#: Most time samples one schedule or simulation allocates (a 100 s weld at 0.1 ms).
MAX_SAMPLES = 1_000_000


@dataclass(frozen=True)
class SeamFrames:
    """Seam waypoints with their frames.

    Attributes:
        s: Arc length from the seam start [m], shape (k,), strictly increasing.
        p: Seam points (joint line at the pin tip depth), base frame [m], shape (k, 3).
        t: Travel direction, shape (k, 3).
        l: Lateral direction toward the advancing side, shape (k, 3).
        n: Tool axis (workpiece -> spindle, tilted), shape (k, 3).
    """

    s: FloatArray
    p: FloatArray
    t: FloatArray
    l: FloatArray
    n: FloatArray

    def __len__(self) -> int:
        return int(self.s.shape[0])

    def rotation(self) -> FloatArray:
        """Rotation matrices [t l n] (columns) seam -> base, shape (k, 3, 3)."""
        return np.stack([self.t, self.l, self.n], axis=-1)

    def to_base(self, f_seam: FloatArray) -> FloatArray:
        """Seam-frame vectors (k, 3) as (f_t, f_l, f_n) -> base frame (k, 3)."""
        return np.einsum("kij,kj->ki", self.rotation(), f_seam)

    def to_seam(self, v_base: FloatArray) -> FloatArray:
        """Base-frame vectors (k, 3) -> seam-frame components (t, l, n), shape (k, 3)."""
        return np.einsum("kji,kj->ki", self.rotation(), v_base)


#: Phase names of the FSW process, in order.
PHASES = ("approach", "plunge", "dwell", "weld", "stop", "retract")


@dataclass(frozen=True)
class LoadSchedule:
    """The process over time: where the tool is and which wrench acts on it.

    One row per time sample. Stationary phases (plunge, dwell) sit at the seam start with
    ``s = 0``, the end stop at the seam end; during ``weld`` the tool moves along the seam at
    the travel speed.

    Attributes:
        t: Time [s], shape (N,), non-decreasing.
        phase: Phase name per sample (one of :data:`PHASES`), shape (N,).
        s: Arc length of the tool position along the seam [m], shape (N,).
        depth: Commanded plunge depth below the workpiece surface [m], shape (N,).
        frames: Seam frames at each sample's tool position (N rows).
        force_seam: Force on the tool in the seam frame (f_t, f_l, f_n) [N], shape (N, 3).
        moment_base: Moment on the tool at the TCP, base frame [N m], shape (N, 3).
    """

    t: FloatArray
    phase: NDArray[np.str_]
    s: FloatArray
    depth: FloatArray
    frames: SeamFrames
    force_seam: FloatArray
    moment_base: FloatArray

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def wrench_base(self) -> FloatArray:
        """Wrench on the tool at the TCP, base frame [N, N m], shape (N, 6)."""
        return np.hstack([self.frames.to_base(self.force_seam), self.moment_base])

    def mask(self, phase: str) -> NDArray[np.bool_]:
        """Boolean mask of the samples in one phase."""
        return self.phase == phase


def tcp_orientation(frames: SeamFrames, rotation: FloatArray | float = 0.0) -> FloatArray:
    """Commanded TCP orientation along the seam, base frame, shape (k, 3, 3).

    The TCP z axis is ``-n`` (into the workpiece). At ``rotation = 0`` the TCP x axis is the
    travel direction projected normal to z; ``rotation`` [rad] turns the tool about its own
    axis (the free rotation of an axisymmetric FSW tool), positive about +z (right hand).

    Args:
        frames: Seam frames (k rows).
        rotation: Rotation about the tool axis [rad], scalar or shape (k,).
    """
    z = -frames.n
    x0 = frames.t - z * np.einsum("ki,ki->k", frames.t, z)[:, None]
    x0 /= np.linalg.norm(x0, axis=1, keepdims=True)
    y0 = np.cross(z, x0)
    th = np.broadcast_to(np.asarray(rotation, dtype=float), (len(frames),))
    c, s = np.cos(th)[:, None], np.sin(th)[:, None]
    x = c * x0 + s * y0
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)


def check_samples(parameter: str, step: float, duration: float, unit_scale: float = 1.0,
                  unit: str = "s", max_samples: int = MAX_SAMPLES) -> int:
    """Refuse a time step that does not fit the process it samples (before allocating).

    Args:
        parameter: The parameter (``dt``, ``cycle``), for the message.
        step: The step [s].
        duration: The duration it samples [s].
        unit_scale: Factor from seconds to the parameter's unit (1e3 for ms), for the message.
        unit: The parameter's unit.

    Returns:
        The number of samples, ``ceil(duration / step) + 1``.

    Raises:
        InputError: The step is longer than the duration, or gives more than
            ``max_samples`` samples (one line naming the smallest step that fits).
    """
    if duration > 0 and step > duration:
        raise InputError(parameter, "", f"{step * unit_scale:g} {unit} is longer than the "
                         f"process it samples ({duration * unit_scale:g} {unit})",
                         f"a step of at most {duration * unit_scale:g} {unit}")
    n = math.ceil(duration / step) + 1 if duration > 0 else 1
    if n > max_samples:
        smallest = duration / (max_samples - 1)
        raise InputError(parameter, "", f"{step * unit_scale:g} {unit} gives {n:.3g} samples over "
                         f"{duration:g} s (at most {max_samples:g})",
                         f"a step of at least {smallest * unit_scale:.3g} {unit}")
    return n
