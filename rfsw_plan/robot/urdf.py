"""Load the actuated serial chain of a URDF, through Pinocchio.

Vendor URDFs are rarely a bare serial chain: the ROS-Industrial FANUC M-900iB/700 has
``mimic`` joints for its parallelogram bar and balancers (18 joint values for 6 axes), and
KUKA's descriptions hang ``flange`` and ``tool0`` frames off the last link. rfsw_plan needs the
chain from the root to the chosen tip link only: every joint off that path (mimic branches,
balancers, links beyond the tip) is locked at zero with Pinocchio's ``buildReducedModel``, so a
tip that is not the end of the URDF is accepted and the chain simply ends there. The joint count
is the chain's, never the URDF's ``nq``.

An unexpanded ``.xacro`` is refused with one line: expand it first with the ``xacro`` command.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError

if TYPE_CHECKING:
    import pinocchio as pin

FloatArray = NDArray[np.float64]

#: File name endings that mark an unexpanded xacro macro file.
XACRO_SUFFIXES = (".xacro",)


@dataclass(frozen=True)
class UrdfSerialChain:
    """The actuated chain of a URDF from its root to a tip link.

    Attributes:
        model: Pinocchio model of the chain only (one revolute joint per axis).
        joint_names: URDF names of the chain joints, root to tip, length n.
        tip_frame: Index of the tip link's frame in ``model``.
        lower: URDF lower position limits [rad], shape (n,) (-inf where the URDF has none).
        upper: URDF upper position limits [rad], shape (n,) (+inf where the URDF has none).
        velocity: URDF velocity limits [rad/s], shape (n,) (nan where the URDF has none).
    """

    model: pin.Model
    joint_names: tuple[str, ...]
    tip_frame: int
    lower: FloatArray
    upper: FloatArray
    velocity: FloatArray

    @property
    def n_joints(self) -> int:
        """Number of chain joints."""
        return len(self.joint_names)

    @property
    def prismatic(self) -> NDArray[np.bool_]:
        """True for each prismatic chain joint (limits in m, velocity in m/s), shape (n,)."""
        return np.array([self.model.joints[j].shortname().startswith("JointModelP")
                         for j in range(1, self.model.njoints)], dtype=bool)


@contextlib.contextmanager
def _captured_stderr() -> Iterator[list[str]]:
    """Collect what C++ code writes on file descriptor 2 (urdfdom's parse errors).

    Yields a list that holds the captured lines once the block ends; nothing reaches the
    terminal, so an error stays one line.
    """
    lines: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            lines.extend(tmp.read().decode("utf-8", "replace").splitlines())


def check_not_xacro(path: Path, where: Path | str, key: str = "") -> None:
    """Raise a one-line :class:`InputError` if ``path`` is an unexpanded xacro file."""
    if path.name.endswith(XACRO_SUFFIXES):
        raise InputError(where, key, f"{path.name} is a xacro macro file",
                         f"a URDF: expand it first with the xacro command "
                         f"(xacro {path.name} > {path.name.removesuffix('.xacro')}"
                         f"{'' if path.name.endswith('.urdf.xacro') else '.urdf'})")


def load_urdf_chain(urdf: Path, tip_link: str, where: Path | str = "") -> UrdfSerialChain:
    """Read a URDF and reduce it to the revolute chain from its root to ``tip_link``.

    Args:
        urdf: URDF file (already expanded).
        tip_link: Link that carries the flange; the chain ends at its parent joint.
        where: File to name in errors (the robot description), defaults to ``urdf``.

    Raises:
        InputError: Not parseable, unknown tip link (the message lists the link names), or a
            chain joint that is not revolute.
    """
    import pinocchio as pin

    where = where or urdf
    check_not_xacro(urdf, where, "kinematics.urdf")
    with _captured_stderr() as said:
        try:
            full = pin.buildModelFromUrdf(str(urdf))
        except Exception as exc:  # pinocchio raises plain RuntimeError/ValueError
            full = None
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    if full is None:
        # urdfdom prints its reason ("Unable to parse component [nan]...") on the C stderr.
        detail = next((ln.split("Error:", 1)[1].strip() for ln in said
                       if ln.strip().startswith("Error:")), "")
        raise InputError(urdf, "", f"cannot parse URDF: {detail or first}")
    links = [f.name for f in full.frames if f.type == pin.FrameType.BODY]
    if tip_link not in links:
        raise InputError(where, "kinematics.tip_link", f"no link '{tip_link}' in {urdf.name}",
                         "one of " + ", ".join(links))
    tip = full.frames[full.getFrameId(tip_link, pin.FrameType.BODY)]
    path: list[int] = []
    j = tip.parentJoint
    while j > 0:
        path.append(j)
        j = full.parents[j]
    path.reverse()
    lock = [j for j in range(1, full.njoints) if j not in path]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    names = tuple(full.names[j] for j in path)
    for jid in range(1, model.njoints):
        short = model.joints[jid].shortname()
        if not short.startswith(("JointModelR", "JointModelRevoluteUnaligned", "JointModelP")) \
                or "Unbounded" in short:
            raise InputError(where, "kinematics.urdf",
                             f"chain joint '{model.names[jid]}' is {short}",
                             "revolute or prismatic joints")
    _check_urdf_numbers(model, where)
    lower = np.array(model.lowerPositionLimit, dtype=float)
    upper = np.array(model.upperPositionLimit, dtype=float)
    velocity = np.array(model.velocityLimit, dtype=float)
    # urdfdom reports a joint without <limit> as zero range / zero speed.
    none = lower >= upper
    lower[none], upper[none] = -np.inf, np.inf
    velocity[velocity <= 0] = np.nan
    return UrdfSerialChain(model, names, model.getFrameId(tip_link, pin.FrameType.BODY),
                           lower, upper, velocity)


def axis_of(model: pin.Model, jid: int) -> FloatArray:
    """Unit rotation axis of revolute joint ``jid`` in its own frame, shape (3,)."""
    short = model.joints[jid].shortname()
    if short == "JointModelRevoluteUnaligned":
        a = np.asarray(model.joints[jid].extract().axis, dtype=float).ravel()
        return a / np.linalg.norm(a)
    axis = np.zeros(3)
    axis["XYZ".index(short[-1])] = 1.0
    return axis


#: Largest |origin offset| of a URDF joint [m] and |limit| [rad or m] accepted.
MAX_URDF_OFFSET_M = 100.0
MAX_URDF_LIMIT = 1e4


def _check_urdf_numbers(model: pin.Model, where: Path | str) -> None:
    """Reject URDF numbers the model cannot use (NaN, 1e300 in an origin or a limit).

    Raises:
        InputError: Names the URDF joint and the value.
    """
    for jid in range(1, model.njoints):
        name = model.names[jid]
        xyz = np.asarray(model.jointPlacements[jid].translation, dtype=float)
        R = np.asarray(model.jointPlacements[jid].rotation, dtype=float)
        if not (np.all(np.isfinite(xyz)) and np.all(np.isfinite(R))
                and float(np.max(np.abs(xyz))) <= MAX_URDF_OFFSET_M):
            raise InputError(where, "kinematics.urdf",
                             f"joint '{name}' origin xyz {xyz.tolist()} m",
                             f"finite offsets within {MAX_URDF_OFFSET_M:g} m")
    for label, arr in (("lower limit", model.lowerPositionLimit),
                       ("upper limit", model.upperPositionLimit),
                       ("velocity limit", model.velocityLimit)):
        a = np.asarray(arr, dtype=float)
        bad = np.flatnonzero(np.isnan(a) | (np.isfinite(a) & (np.abs(a) > MAX_URDF_LIMIT)))
        if bad.size:
            raise InputError(where, "kinematics.urdf",
                             f"joint {int(bad[0]) + 1} {label} is {a[bad[0]]:g}",
                             f"a finite limit within {MAX_URDF_LIMIT:g}")
