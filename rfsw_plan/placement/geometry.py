"""Where the part goes: placements of a seam in the robot cell.

A placement moves the whole part (seam, surface normals, process wrench) rigidly: a rotation
``yaw`` about the vertical (the robot base's +z axis; the robot stands on the floor) through
the seam's *anchor* (the seam point at half its arc length), then a translation that puts the
anchor at ``(x, y, z)`` in the robot base frame. The given placement of a problem is
``(anchor, yaw = 0)``. Raising the robot on a pedestal by h is the same as lowering the part by
h: ``z = z_anchor - h``.

Seam-frame quantities (the force (f_t, f_l, f_n), the window, the tool tilt and rotation sense)
move with the part; base-frame vectors (points, frame axes, the moment) are rotated.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.process.frames import SeamFrames
from rfsw_plan.process.task import PlanTask

FloatArray = NDArray[np.float64]


def rot_z(yaw: FloatArray | float) -> FloatArray:
    """Rotations about +z by yaw [rad]; shape (3, 3) for a scalar, (P, 3, 3) for (P,)."""
    a = np.asarray(yaw, dtype=float)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros((*a.shape, 3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1] = c, -s, s, c
    R[..., 2, 2] = 1.0
    return R


@dataclass(frozen=True)
class Placement:
    """One placement of the part.

    Attributes:
        x, y, z: Position of the seam anchor in the robot base frame [m].
        yaw: Rotation of the part about the vertical relative to the given placement [rad].
    """

    x: float
    y: float
    z: float
    yaw: float

    def as_array(self) -> FloatArray:
        """(x, y, z, yaw) [m, m, m, rad], shape (4,)."""
        return np.array([self.x, self.y, self.z, self.yaw])

    def to_dict(self, anchor: FloatArray | None = None) -> dict[str, float]:
        """File units (mm, deg); with the given anchor also the shift from the given placement
        and the robot base height change that gives the same relative height."""
        d = {"x_mm": self.x * 1e3, "y_mm": self.y * 1e3, "z_mm": self.z * 1e3,
             "yaw_deg": float(np.rad2deg(self.yaw))}
        if anchor is not None:
            d["dx_mm"] = (self.x - anchor[0]) * 1e3
            d["dy_mm"] = (self.y - anchor[1]) * 1e3
            d["robot_base_height_mm"] = (anchor[2] - self.z) * 1e3
        return d


def seam_anchor(frames: SeamFrames) -> FloatArray:
    """The seam point at half the arc length of the weld waypoints [m], shape (3,)."""
    s = frames.s
    half = 0.5 * (s[0] + s[-1])
    return np.array([np.interp(half, s, frames.p[:, i]) for i in range(3)])


@dataclass(frozen=True)
class PlacedArrays:
    """A task's waypoint geometry at P placements, base frame.

    Attributes:
        p: Seam points [m], (P, K, 3).
        target: Nominal TCP targets [m], (P, K, 3).
        t, l, n: Seam frame axes, (P, K, 3).
        R_tcp: Commanded TCP rotations, (P, K, 3, 3).
        wrench: Process wrench on the tool at the TCP [N, N m], (P, K, 6).
    """

    p: FloatArray
    target: FloatArray
    t: FloatArray
    l: FloatArray
    n: FloatArray
    R_tcp: FloatArray
    wrench: FloatArray


def place_arrays(task: PlanTask, anchor: FloatArray, placements: FloatArray,
                 R_tcp: FloatArray) -> PlacedArrays:
    """The task's waypoints moved to every placement.

    Args:
        task: The task at the given placement.
        anchor: Seam anchor of the given placement [m], (3,).
        placements: (x, y, z, yaw) per placement [m, rad], (P, 4).
        R_tcp: Commanded TCP rotations at the given placement, (K, 3, 3).
    """
    R = rot_z(placements[:, 3])  # (P, 3, 3)
    shift = placements[:, None, :3]

    def pts(a: FloatArray) -> FloatArray:
        return np.einsum("pij,kj->pki", R, a - anchor) + shift

    def vec(a: FloatArray) -> FloatArray:
        return np.einsum("pij,kj->pki", R, a)

    fr = task.frames
    W = task.wrench_base
    return PlacedArrays(
        p=pts(fr.p), target=pts(task.target), t=vec(fr.t), l=vec(fr.l), n=vec(fr.n),
        R_tcp=np.einsum("pij,kjl->pkil", R, R_tcp),
        wrench=np.concatenate([vec(W[:, :3]), vec(W[:, 3:])], axis=2),
    )


def place_task(task: PlanTask, anchor: FloatArray, placement: Placement) -> PlanTask:
    """The task moved to one placement (same waypoints, loads and schedule)."""
    R = rot_z(placement.yaw)
    pos = np.array([placement.x, placement.y, placement.z])
    fr = task.frames
    frames = SeamFrames(fr.s.copy(), (fr.p - anchor) @ R.T + pos, fr.t @ R.T, fr.l @ R.T,
                        fr.n @ R.T)
    return replace(task, frames=frames, target=(task.target - anchor) @ R.T + pos,
                   moment_base=task.moment_base @ R.T)


@dataclass(frozen=True)
class PlacementGrid:
    """A regular grid of placements (C order over x, y, yaw, z).

    Attributes:
        x, y: Anchor positions in the table plane [m], (nx,), (ny,).
        yaw: Yaw about the vertical relative to the given placement [rad], (nyaw,).
        z: Anchor heights in the robot base frame [m], (nz,).
    """

    x: FloatArray
    y: FloatArray
    yaw: FloatArray
    z: FloatArray

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """(nx, ny, nyaw, nz)."""
        return (len(self.x), len(self.y), len(self.yaw), len(self.z))

    @property
    def size(self) -> int:
        """Number of placements."""
        return int(np.prod(self.shape))

    def placements(self) -> FloatArray:
        """(x, y, z, yaw) of every placement [m, rad], (P, 4), C order over :attr:`shape`."""
        X, Y, A, Z = np.meshgrid(self.x, self.y, self.yaw, self.z, indexing="ij")
        return np.stack([X.ravel(), Y.ravel(), Z.ravel(), A.ravel()], axis=1)


def parse_range(text: str, option: str, count: tuple[int, ...], unit: str) -> list[float]:
    """Comma-separated numbers of an option such as ``--region`` [file units].

    Raises:
        InputError: Wrong count, not a number, not finite, or an empty interval (upper below
            lower); one line naming the option.
    """
    parts = [p.strip() for p in text.split(",")]
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise InputError(option, "", f"got '{text}'",
                         f"{' or '.join(str(c) for c in count)} comma-separated numbers "
                         f"[{unit}]") from None
    if len(vals) not in count:
        raise InputError(option, "", f"got {len(vals)} value(s) '{text}'",
                         f"{' or '.join(str(c) for c in count)} comma-separated numbers [{unit}]")
    if not all(np.isfinite(vals)):
        raise InputError(option, "", f"got '{text}'", "finite numbers")
    for i in range(0, len(vals), 2):
        if vals[i + 1] < vals[i]:
            raise InputError(option, "", f"empty range {vals[i]:g}..{vals[i + 1]:g} {unit}",
                             "lower <= upper")
    return vals
