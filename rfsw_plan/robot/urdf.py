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
from typing import TYPE_CHECKING, Any

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


#: The xacro XML namespace (``xmlns:xacro="http://www.ros.org/wiki/xacro"``).
XACRO_NAMESPACE = "http://www.ros.org/wiki/xacro"


def _refuse_xacro_elements(root: Any, urdf: Path) -> None:
    """A ``.urdf`` that still holds xacro (``<xacro:include>``, ``<xacro:macro>``, a
    ``${...}`` or ``$(...)`` attribute) is an unexpanded macro file under another name: the
    URDF parser would drop those parts and read a different robot. One line naming the first
    such element."""
    hint = f"a URDF: expand it first with the xacro command (xacro FILE.xacro > {urdf.name})"
    for el in root.iter():
        tag = el.tag if isinstance(el.tag, str) else ""
        if tag.startswith(f"{{{XACRO_NAMESPACE}}}") or tag.startswith("xacro:"):
            name = tag.rsplit("}", 1)[-1]
            raise InputError(urdf, f"<xacro:{name}>", "an unexpanded xacro element", hint)
        for attr, value in el.attrib.items():
            if "${" in value or "$(" in value:
                raise InputError(urdf, f"<{tag} {attr}=\"{value[:40]}\">",
                                 "an unexpanded xacro expression", hint)


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
    check_urdf_numbers(urdf)
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


#: Largest |centre of mass| offset of a link [m] and link mass [kg] accepted.
MAX_URDF_COM_M = 100.0
MAX_URDF_MASS_KG = 1e5


def _vector(text: str | None, n: int, where: str, what: str, urdf: Path) -> list[float]:
    """``n`` finite numbers from a URDF attribute (``"0 0 1"``)."""
    parts = (text or "").split()
    try:
        vals = [float(x) for x in parts]
    except ValueError:
        vals = []
    if len(vals) != n or not all(np.isfinite(vals)):
        raise InputError(urdf, where, f"{what} is '{text}'", f"{n} finite numbers")
    return vals


def check_urdf_numbers(urdf: Path) -> None:
    """Check the numbers of a URDF before Pinocchio reads it (urdfdom accepts a zero axis,
    swapped limits, a NaN, a fourth coordinate or 1e308 without a word).

    Every joint: ``origin xyz/rpy`` three finite numbers, xyz within
    :data:`MAX_URDF_OFFSET_M`; ``axis xyz`` three finite numbers, not all zero; ``limit``
    lower <= upper, both finite. Every link: ``inertial/origin`` as a joint origin with the
    centre of mass within :data:`MAX_URDF_COM_M`, ``mass`` finite in [0, MAX_URDF_MASS_KG].

    Raises:
        InputError: One line naming the joint or link, the attribute and what was found.
    """
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(urdf).getroot()
    except (ET.ParseError, OSError, UnicodeDecodeError) as exc:
        raise InputError(urdf, "", f"cannot parse URDF: {exc}") from None
    _refuse_xacro_elements(root, urdf)
    for joint in root.iter("joint"):
        name = f"joint '{joint.get('name')}'"
        _check_origin(joint.find("origin"), name, MAX_URDF_OFFSET_M, urdf)
        axis = joint.find("axis")
        if axis is not None:
            a = _vector(axis.get("xyz"), 3, name, "axis xyz", urdf)
            if not np.linalg.norm(a) > 1e-9:
                raise InputError(urdf, name, f"axis xyz is '{axis.get('xyz')}' (zero)",
                                 "a non-zero axis, e.g. '0 0 1'")
        lim = joint.find("limit")
        if lim is not None and joint.get("type") in ("revolute", "prismatic"):
            lo, hi = (_vector(lim.get(k, "0"), 1, name, f"limit {k}", urdf)[0]
                      for k in ("lower", "upper"))
            if lo > hi:
                raise InputError(urdf, name, f"limit lower {lo:g} > upper {hi:g} (swapped?)",
                                 "lower <= upper")
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        name = f"link '{link.get('name')}'"
        _check_origin(inertial.find("origin"), f"{name} inertial", MAX_URDF_COM_M, urdf)
        mass = inertial.find("mass")
        if mass is not None:
            m = _vector(mass.get("value"), 1, name, "mass", urdf)[0]
            if not 0.0 <= m <= MAX_URDF_MASS_KG:
                raise InputError(urdf, name, f"mass {m:g} kg",
                                 f"a mass in [0, {MAX_URDF_MASS_KG:g}] kg")


def _check_origin(origin: object, name: str, max_offset: float, urdf: Path) -> None:
    if origin is None:
        return
    get = origin.get  # type: ignore[attr-defined]
    xyz = _vector(get("xyz", "0 0 0"), 3, name, "origin xyz", urdf)
    _vector(get("rpy", "0 0 0"), 3, name, "origin rpy", urdf)
    if max(abs(v) for v in xyz) > max_offset:
        raise InputError(urdf, name, f"origin xyz is '{get('xyz')}' m",
                         f"offsets within {max_offset:g} m")


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
