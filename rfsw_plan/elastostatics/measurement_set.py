"""The measurement data type that identification and validation work on.

A :class:`MeasurementSet` holds the samples of a load campaign, a weld log or a metrology
session in SI units: joint values, the wrench at the TCP in the robot base frame, and the
measured position (and optionally orientation) of the tracked point, in the base frame or in
the frame of the measuring device. Files are read and written in ``rfsw_plan.io.measurements``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

#: Frames measured positions may be expressed in: the robot base frame, or the frame of the
#: measuring device (laser tracker, motion capture), whose pose in the base frame is unknown.
MeasurementFrame = Literal["base", "device"]
MEASUREMENT_FRAMES: tuple[str, ...] = ("base", "device")
#: A logged force below this [N] counts as a zero-load reading for the sensor-noise estimate
#: (when the file has no ``load_step``).
ZERO_LOAD_N = 50.0


@dataclass(frozen=True)
class MeasurementSet:
    """Samples of a load campaign or a weld log (SI units inside).

    Attributes:
        q: Encoder joint values, shape (m, n): [rad] for revolute joints, [m] for prismatic ones.
        wrench: Wrench the environment applies to the tool at the TCP, robot base frame
            [N, N m], shape (m, 6) (converted at the reader from a tool or sensor frame).
        position: Measured position of the tracked point (the TCP, or a marker at an offset
            from it), in ``frame`` [m], shape (m, 3); NaN = not measured.
        t: Time stamps [s], shape (m,), or None.
        pose_id: Pose labels, shape (m,), or None.
        sigma: Per-row 1-sigma position noise [m], shape (m,), or None.
        extra: Other numeric columns by name, each shape (m,).
        source: File the data came from.
        frame: ``base`` (robot base frame) or ``device`` (the measuring device's own frame).
        rotation: Measured orientation of the tool frame as a rotation vector in ``frame``
            [rad], shape (m, 3), or None (positions only).
        load_step: Commanded load step of each row (an integer label), shape (m,), or None.
        dialect: What the reader detected (delimiter, decimal separator), for the report.
        columns: File column read for each quantity (``q1`` -> ``q1_deg``, ``x`` -> ``x1``),
            so that messages can name what the user wrote.
        approach: Direction each joint last moved in before the sample, shape (m, n), +1,
            -1 or 0 (unknown), computed on the whole recording by the reader (from ``dir_qN``
            columns, the time column or the row order) or None: :meth:`approach_directions`
            then derives it from ``t`` or the row order.
        load_change: The last change of the logged wrench at the same pose before the sample
            [N, N m], base frame, shape (m, 6) (:func:`rfsw_plan.elastostatics.approach.
            load_changes`), computed on the whole recording like ``approach``, or None.
        load_history: The loads logged before the sample at the same pose, most recent first
            [N, N m], shape (m, HISTORY_DEPTH, 6) (:func:`rfsw_plan.elastostatics.approach.
            load_history`), computed on the whole recording like ``approach``, or None.
        markers: Every marker of a sample measured with several (a laser tracker's three
            reflectors), in ``frame`` [m], shape (m, k, 3), or None; ``position`` is then
            their centroid.
    """

    q: FloatArray
    wrench: FloatArray
    position: FloatArray
    t: FloatArray | None = None
    pose_id: NDArray[np.str_] | None = None
    sigma: FloatArray | None = None
    extra: dict[str, FloatArray] = field(default_factory=dict)
    source: str = "<memory>"
    frame: str = "base"
    rotation: FloatArray | None = None
    load_step: NDArray[np.int_] | None = None
    dialect: str = ""
    columns: dict[str, str] = field(default_factory=dict)
    approach: FloatArray | None = None
    load_change: FloatArray | None = None
    load_history: FloatArray | None = None
    markers: FloatArray | None = None

    def __len__(self) -> int:
        return int(self.q.shape[0])

    @property
    def n_joints(self) -> int:
        """Number of joint columns."""
        return int(self.q.shape[1])

    @property
    def measured(self) -> NDArray[np.bool_]:
        """Mask of measured position axes, shape (m, 3)."""
        return np.isfinite(self.position)

    def subset(self, idx: NDArray[np.int_] | NDArray[np.bool_]) -> MeasurementSet:
        """Rows ``idx`` as a new set."""
        return MeasurementSet(
            q=self.q[idx],
            wrench=self.wrench[idx],
            position=self.position[idx],
            t=None if self.t is None else self.t[idx],
            pose_id=None if self.pose_id is None else self.pose_id[idx],
            sigma=None if self.sigma is None else self.sigma[idx],
            extra={k: v[idx] for k, v in self.extra.items()},
            source=self.source,
            frame=self.frame,
            rotation=None if self.rotation is None else self.rotation[idx],
            load_step=None if self.load_step is None else self.load_step[idx],
            dialect=self.dialect,
            columns=self.columns,
            approach=None if self.approach is None else self.approach[idx],
            load_change=None if self.load_change is None else self.load_change[idx],
            load_history=None if self.load_history is None else self.load_history[idx],
            markers=None if self.markers is None else self.markers[idx],
        )

    def load_changes(self) -> FloatArray:
        """The last load change at the same pose of every sample [N, N m], shape (m, 6): the
        stored one, else from ``t`` or the row order of these samples."""
        from rfsw_plan.elastostatics.approach import change_tolerance, load_changes

        if self.load_change is not None:
            return self.load_change
        tol = change_tolerance(self.zero_load_force_noise())
        return load_changes(self.q, self.wrench, self.t, tol)

    def load_histories(self) -> FloatArray:
        """The earlier loads at the same pose of every sample [N, N m], shape
        (m, HISTORY_DEPTH, 6): the stored ones, else from ``t`` or the row order of these
        samples; shape (m, 0, 6) when no sample logs a force (no load to remember, and
        HISTORY_DEPTH x 48 bytes a sample saved on large position-only sets)."""
        from rfsw_plan.elastostatics.approach import load_history

        if self.load_history is not None:
            return self.load_history
        if not np.any(self.wrench):
            return np.zeros((len(self), 0, 6))
        return load_history(self.q, self.wrench, self.t)

    def approach_directions(self) -> FloatArray:
        """The approach direction of every joint at every sample, shape (m, n) (see
        :mod:`rfsw_plan.elastostatics.approach`): the stored one, else from ``t`` or the
        row order of these samples."""
        from rfsw_plan.elastostatics.approach import approach_directions

        if self.approach is not None:
            return self.approach
        return approach_directions(self.q, self.t)

    def zero_load_force_noise(self) -> float | None:
        """Force sensor noise per axis [N] from the spread of the zero-load readings.

        Zero-load rows are ``load_step == 0`` when the file has load steps, else rows whose
        logged force is below :data:`ZERO_LOAD_N`. Their per-axis standard deviation about
        the mean (a bias is not noise), pooled over the three axes, needs at least 3 such
        rows. None when it cannot be estimated (no such rows, or no force readings at all).
        """
        F = self.wrench[:, :3]
        if not np.any(F):
            return None
        zero = (self.load_step == 0) if self.load_step is not None else (
            np.linalg.norm(F, axis=1) < ZERO_LOAD_N)
        Fz = F[zero]
        if Fz.shape[0] < 3 or not np.any(Fz):
            return None
        return float(np.sqrt(np.mean(np.var(Fz, axis=0, ddof=1))))

    def with_position(self, position: FloatArray, frame: str) -> MeasurementSet:
        """The same samples with positions (m, 3) [m] expressed in another frame (the
        individual markers, kept in the old frame, are dropped)."""
        from dataclasses import replace

        return replace(self, position=np.asarray(position, dtype=float), frame=frame,
                       markers=None)
