"""Robot description files: kinematics, limits, coupling, stiffness and elastostatic effects.

A description is a human-readable TOML file (see ``robots/*.toml`` and
docs/formats/robot-files.md). Lengths are in mm and angles in degrees in the file (the unit is
in every key name); everything inside the code is SI (m, rad, N m/rad).

Kinematics are either a modified Denavit-Hartenberg table (Craig convention,
``T_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(q_i + theta0_i) Tz(d_i)``, seed 001 eq. 1) or a URDF file
plus the names of its base and tip links.

Joint values ``q`` everywhere in rfsw_plan are the *controller* joint values (what the robot's
teach pendant shows and its programs use: KUKA A1..A6, FANUC J1..J6). The description's optional
``[controller]`` table says how they relate to the kinematic chain's joint angles ``theta``
(the MDH variable ``theta_i`` before ``theta0_i``, or the URDF joint value), in one place:

    theta = diag(sign) C q + offset

with ``C`` the ``[joints] coupling`` matrix (identity for a plain serial arm; FANUC's
parallelogram makes the chain's elbow angle depend on J2 + J3, seed 000 eq. 2 and 4) and
``sign``/``offset_deg`` per joint. :class:`ControllerConvention` holds it; the signed coupling
``G = diag(sign) C`` is :attr:`RobotDescription.coupling` and the offsets are folded into the
kinematic model (:func:`rfsw_plan.robot.kinematics.build_pinocchio_model`). A file without
``[controller]`` uses the chain's own joint values (``q`` = ``theta``) and says so
(:attr:`ControllerConvention.kind` ``"chain"``). Joint stiffness is on the controller/motor
side, so the joint-space compliance seen by the chain is ``G K^-1 G^T``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from datetime import UTC
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.bundled import bundled_names, resolve_bundled
from rfsw_plan.robot.urdf import UrdfSerialChain, check_not_xacro, load_urdf_chain
from rfsw_plan.tomlreader import Table, read_toml
from rfsw_plan.tomlwriter import dumps_toml

FloatArray = NDArray[np.float64]

#: Folder with the bundled robot descriptions (``robots/`` at the top of the checkout).
BUNDLED_ROBOTS_DIR = Path(__file__).resolve().parents[2] / "robots"

#: Maker Euler conventions understood by the waypoint writer.
EULER_CONVENTIONS = ("none", "kuka_abc", "fanuc_wpr")


@dataclass(frozen=True)
class ModifiedDH:
    """Modified DH table (Craig), one entry per joint.

    Attributes:
        a: a_{i-1} [m], shape (n,).
        d: d_i [m], shape (n,).
        alpha: alpha_{i-1} [rad], shape (n,).
        theta0: Joint zero offset theta0_i [rad], shape (n,).
        mass: Mass of link i, the body that joint i moves [kg], shape (n,), or None (the
            links carry no mass: their weight loads no joint).
        com: Centre of mass of link i in joint i's frame (the MDH frame i, on joint i's axis)
            [m], shape (n, 3), or None.
    """

    a: FloatArray
    d: FloatArray
    alpha: FloatArray
    theta0: FloatArray
    mass: FloatArray | None = None
    com: FloatArray | None = None


@dataclass(frozen=True)
class UrdfChain:
    """A serial chain taken from a URDF file.

    Attributes:
        path: URDF file.
        tip_link: Link whose frame carries the flange; the tool transform is applied after it.
    """

    path: Path
    tip_link: str


@dataclass(frozen=True)
class ControllerConvention:
    """How the controller's joint values relate to the chain and its frames.

    ``theta = sign * (C q) + offset`` (see the module docstring), plus the controller's own
    base and flange frames, used by the program writers (:mod:`rfsw_plan.export`).

    Attributes:
        kind: ``"controller"`` (the file states the controller convention) or ``"chain"``
            (joint values are the chain's own, e.g. a user's DH file).
        axes: Controller axis names (``A1``.. for KUKA, ``J1``.. for FANUC), length n.
        sign: Per-joint sign, shape (n,), entries +1 or -1.
        offset: Per-joint offset [rad], shape (n,).
        base: Controller base (KUKA ROBROOT, FANUC world, ABB base) frame in the description's
            base frame, shape (4, 4) [m].
        flange: Controller flange frame (KUKA FLANGE, FANUC faceplate, ABB tool0) in the
            chain's flange frame (before the tool), shape (4, 4) [m].
        source: Where the convention comes from.
        maker: The robot maker whose controller runs this convention (``KUKA``, ``FANUC``,
            ``ABB``), or ``""`` (a program in a maker's language for another robot carries a
            warning line).
    """

    kind: str
    axes: tuple[str, ...]
    sign: FloatArray
    offset: FloatArray
    base: FloatArray
    flange: FloatArray
    source: str = "not stated"
    maker: str = ""

    @staticmethod
    def chain(n: int) -> ControllerConvention:
        """The identity convention: ``q`` are the chain's own joint values ``q1..qn``."""
        return ControllerConvention("chain", tuple(f"q{i + 1}" for i in range(n)), np.ones(n),
                                    np.zeros(n), np.eye(4), np.eye(4),
                                    "no [controller] table: chain joint values")

    def column_names(self, unit: str = "deg") -> list[str]:
        """Joint column names for files, e.g. ``A1_deg`` (KUKA) or ``q1_deg`` (chain)."""
        return [f"{a}_{unit}" for a in self.axes]


@dataclass(frozen=True)
class EffectSpec:
    """An elastostatic effect stored in a robot description.

    Attributes:
        name: Effect name, with ``:jN`` (1-based) for single-joint effects.
        params: Parameter values in SI units, keyed by parameter name.
    """

    name: str
    params: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class PluginSpec:
    """A user's effect file or package entry point that a robot description needs.

    Attributes:
        kind: ``file`` (a Python file, loaded with ``--effects FILE.py``) or ``entry_point``
            (group ``rfsw_plan.effects`` of an installed package).
        ref: The file's absolute path, or the entry point as ``name = module:attr``.
        sha256: SHA-256 of the file (of the entry point's module file) when it was saved.
        effects: Names of the effects it provides that the description uses.
    """

    kind: str
    ref: str
    sha256: str
    effects: tuple[str, ...] = ()


@dataclass(frozen=True)
class DeviceFrame:
    """Where a measuring device sees the robot: its frame in the base frame, and the marker.

    A laser tracker or motion-capture system measures a marker (SMR, rigid body) at an offset
    from the TCP, in its own frame: ``p_device = R (FK(q) + R_tcp marker) + t`` with the
    device-to-base transform inverted, i.e. the base frame seen from the device.

    Attributes:
        rotation: Rotation of the base frame in the device frame, shape (3, 3).
        translation: Base origin in the device frame [m], shape (3,).
        marker: Tracked point in the tool (TCP) frame [m], shape (3,).
        std: 1-sigma standard errors, keyed by parameter (``rx_mrad``, ``x_mm``...), as
            identified; empty if given, not identified.
        each_file: The device is set up anew for every recording (``registration =
            "each_file"``: a laser tracker moved between series): every command registers
            each file's device frame again, holding the marker; False (``"held"``): the
            registration holds for every file (a fixed motion-capture body).
    """

    rotation: FloatArray
    translation: FloatArray
    marker: FloatArray
    std: dict[str, float] = field(default_factory=dict)
    each_file: bool = False

    def to_base(self, p_device: FloatArray) -> FloatArray:
        """Device-frame points (m, 3) [m] in the base frame."""
        return (np.asarray(p_device, dtype=float) - self.translation) @ self.rotation


@dataclass(frozen=True)
class Payload:
    """The tool's load (spindle and FSW tool) a controller needs for its dynamics and collision
    detection: the ``[payload]`` table of a robot file, or the ``payload_gravity`` effect.

    Attributes:
        mass: Mass [kg].
        com: Centre of mass in the chain's flange frame (before the tool) [m], shape (3,).
        inertia: Principal moments of inertia about the centre of mass, axes of the flange
            frame [kg m^2], shape (3,), or None when not known.
        source: Where the numbers come from (``ASSUMED`` marks assumptions).
    """

    mass: float
    com: FloatArray
    inertia: FloatArray | None
    source: str


@dataclass(frozen=True)
class RobotDescription:
    """Everything rfsw_plan knows about one robot.

    Attributes:
        name: Short identifier (``zk500``).
        title: Human-readable description.
        chain: Kinematic chain, MDH table or URDF.
        tool: Flange-to-TCP transform [m], shape (4, 4).
        coupling: Signed coupling ``G = diag(sign) C`` with ``theta = G q + offset``
            (controller to chain joints), shape (n, n).
        stiffness: Joint stiffness on the controller/motor side [N m/rad], shape (n,).
        lower: Lower joint limits [rad], shape (n,).
        upper: Upper joint limits [rad], shape (n,).
        velocity: Joint velocity limits [rad/s], shape (n,).
        acceleration: Joint acceleration limits [rad/s^2], shape (n,).
        jerk: Joint jerk limits [rad/s^3], shape (n,).
        euler: Maker Euler convention for waypoint files (``none``, ``kuka_abc``, ``fanuc_wpr``).
        effects: Extra elastostatic effects beyond joint compliance.
        sources: Where each group of numbers comes from, keyed by section name.
        path: File the description was read from, if any.
        controller: Controller joint convention and frames (:class:`ControllerConvention`).
        prismatic: Per joint, True for a prismatic joint (its q, limits and stiffness are in
            m, m/s, ..., N/m), shape (n,); None = all revolute.
        device_frame: Registration of a measuring device (laser tracker, motion capture) and
            the tracked marker's offset, identified by ``validate --frame device``, or None.
        provenance: Where a derived (re-identified) description came from: ``parent`` (robot
            file), ``data`` and ``data_sha256`` (the measurement file), ``created`` (UTC date)
            and ``command``; empty for a hand-written file. The ``[provenance]`` table.
        payload: The ``[payload]`` table (:class:`Payload`), or None. Programs prefer the
            ``payload_gravity`` effect's identified values
            (:meth:`~rfsw_plan.elastostatics.model.ElastostaticModel.tool_payload`).
    """

    name: str
    title: str
    chain: ModifiedDH | UrdfChain
    tool: FloatArray
    coupling: FloatArray
    stiffness: FloatArray
    lower: FloatArray
    upper: FloatArray
    velocity: FloatArray
    acceleration: FloatArray
    jerk: FloatArray
    euler: str = "none"
    effects: tuple[EffectSpec, ...] = ()
    sources: dict[str, str] = field(default_factory=dict)
    path: Path | None = None
    controller: ControllerConvention | None = None
    prismatic: NDArray[np.bool_] | None = None
    device_frame: DeviceFrame | None = None
    provenance: dict[str, str] = field(default_factory=dict)
    plugins: tuple[PluginSpec, ...] = ()
    payload: Payload | None = None

    @property
    def convention(self) -> ControllerConvention:
        """The controller convention (the chain's own values when the file gives none)."""
        return self.controller or ControllerConvention.chain(self.n_joints)

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return int(self.stiffness.shape[0])

    def with_stiffness(self, stiffness: FloatArray, source: str) -> RobotDescription:
        """Return a copy with new joint stiffness [N m/rad] and its source note."""
        sources = dict(self.sources)
        sources["stiffness"] = source
        return replace(self, stiffness=np.asarray(stiffness, dtype=float), sources=sources)


# --------------------------------------------------------------------------------------------
# Reading


def bundled_robot_names() -> list[str]:
    """Names of the robots shipped in ``robots/``."""
    return bundled_names(BUNDLED_ROBOTS_DIR)


def resolve_robot_path(name_or_path: str | Path) -> Path:
    """Turn a bundled robot name or a file path into an existing file path.

    Raises:
        UnknownNameError: Neither a bundled name nor an existing file; lists the bundled robots.
    """
    return resolve_bundled("robot", BUNDLED_ROBOTS_DIR, name_or_path)


def load_robot_description(name_or_path: str | Path) -> RobotDescription:
    """Load a robot description from a bundled name or a TOML file.

    Args:
        name_or_path: Bundled robot name (see ``rfsw-plan robots``) or path to a ``.toml`` file.

    Raises:
        UnknownNameError: Unknown robot name.
        InputError: Malformed file, unknown key or impossible value; the message names the
            file and key.
    """
    path = resolve_robot_path(name_or_path)
    check_not_xacro(path, path)
    if path.suffix == ".urdf":
        raise InputError(
            path, "", "a URDF needs a stiffness file", "a .toml with [kinematics] urdf = '...'"
        )
    return parse_robot_description(read_toml(path), path)


# Keys of every table of a robot file. A new key is declared here and read below.
TOP_KEYS = ("name", "title", "euler", "kinematics", "tool", "controller", "joints", "stiffness",
            "effects", "device_frame", "provenance", "effect_plugins", "payload")
PLUGIN_KEYS = ("file", "entry_point", "sha256", "effects")
PAYLOAD_KEYS = ("mass_kg", "com_mm", "frame", "inertia_kgm2", "source")
#: Frames a ``[payload]`` centre of mass may be given in.
PAYLOAD_FRAMES = ("flange", "tool")
MAX_PAYLOAD_KG = 1e4
#: Largest mass of one link of an MDH table [kg] (``link_mass_kg``).
MAX_LINK_MASS_KG = 1e5
PROVENANCE_KEYS = ("parent", "data", "data_sha256", "forces", "forces_sha256", "created",
                   "command")
DH_KEYS = ("convention", "a_mm", "d_mm", "alpha_deg", "theta0_deg", "link_mass_kg",
           "link_com_mm", "source")
URDF_KEYS = ("urdf", "tip_link", "source")
KINEMATICS_KEYS = tuple(dict.fromkeys(DH_KEYS + URDF_KEYS))
TOOL_KEYS = ("xyz_mm", "rpy_deg", "source")
JOINT_KEYS = ("lower_deg", "upper_deg", "velocity_deg_s", "acceleration_deg_s2", "jerk_deg_s3",
              "lower_mm", "upper_mm", "velocity_mm_s", "acceleration_mm_s2", "jerk_mm_s3",
              "coupling", "source")
STIFFNESS_KEYS = ("k_Nm_per_rad", "k_N_per_m", "source")
DEVICE_FRAME_KEYS = ("base_in_device_xyz_mm", "base_in_device_rpy_deg", "marker_xyz_mm", "std",
                     "registration", "source")
#: ``[device_frame] registration``: held for every file, or registered again for each file.
REGISTRATIONS = ("held", "each_file")
EFFECT_KEYS = ("name", "params", "source")
CONTROLLER_KEYS = ("maker", "axes", "sign", "offset_deg", "base_xyz_mm", "base_rpy_deg",
                   "flange_xyz_mm", "flange_rpy_deg", "source")

#: Valid ranges of robot-file numbers, in file units (mm, deg, N m/rad). Wider than any real
#: arm; they catch typos and values that would overflow the model (1e300 mm, 1e-320 N m/rad).
MAX_LENGTH_MM = 1e5          # a link or DH offset of at most 100 m
MAX_TOOL_MM = 1e4            # flange to TCP at most 10 m
MIN_TOOL_MM = 1.0            # a TCP off the flange is at least 1 mm away (less: metres?)
MAX_ANGLE_DEG = 360.0        # DH twist and zero offset, tool rpy
MAX_JOINT_DEG = 720.0        # joint limits: at most two turns either way
MAX_TRAVEL_MM = 1e5          # prismatic joint limits: at most 100 m
MAX_VELOCITY_DEG_S = 1e4
MIN_RATE = 0.01              # smallest velocity/acceleration/jerk limit (deg or mm per s^k)
MAX_ACCELERATION_DEG_S2 = 1e6
MAX_JERK_DEG_S3 = 1e8
STIFFNESS_RANGE_NM_PER_RAD = (1.0, 1e12)  # prismatic joints: the same range in N/m
MAX_COUPLING = 100.0         # |G_ij|: gear and parallelogram ratios are O(1)
MAX_COUPLING_CONDITION = 1e8
MAX_EFFECT_PARAM = 1e9       # |theta| of any effect parameter [SI]; each effect narrows it

_EFFECT_LABEL = re.compile(r"^([a-z_]+)(?::j([0-9]+))?$")


def parse_robot_description(data: dict[str, Any], path: Path | str) -> RobotDescription:
    """Build a :class:`RobotDescription` from parsed TOML data (see module docstring).

    Every table rejects unknown keys (with a "did you mean"), every number must be finite and
    inside the ranges above, and the joint limits must hold lower < upper.

    Raises:
        InputError: The first problem found, naming the file and the dotted key.
    """
    r = Table(path, data, TOP_KEYS)
    name = r.str_("name")
    if not name.strip():
        raise r.error("name", "is empty", "a robot name")
    title = r.str_("title", name)
    euler = r.str_("euler", "none", choices=EULER_CONVENTIONS)
    sources: dict[str, str] = {}

    kin = r.table("kinematics", KINEMATICS_KEYS, required=True)
    assert kin is not None
    chain, urdf_chain = _chain(kin, path)
    n = urdf_chain.n_joints if urdf_chain is not None else len(chain.a)  # type: ignore[union-attr]
    prismatic = (urdf_chain.prismatic if urdf_chain is not None
                 else np.zeros(n, dtype=bool))
    sources["kinematics"] = kin.str_("source", "not stated")

    tool = np.eye(4)
    tool_t = r.table("tool", TOOL_KEYS)
    if tool_t is not None:
        xyz_mm = tool_t.vec("xyz_mm", 3, [0.0, 0.0, 0.0], ge=-MAX_TOOL_MM, le=MAX_TOOL_MM)
        length = float(np.linalg.norm(xyz_mm))
        if 0.0 < length < MIN_TOOL_MM:  # [0, 0, 0.39]: a 390 mm tool written in metres
            raise tool_t.error("xyz_mm", f"the TCP is {length:.3g} mm from the flange: metres "
                               "instead of mm?", f"mm (x1000: {_r(xyz_mm * 1e3)}), or 0 for a "
                               f"TCP on the flange; a tool is at least {MIN_TOOL_MM:g} mm long")
        tool[:3, 3] = xyz_mm / 1000.0
        tool[:3, :3] = _rpy_to_matrix(np.radians(tool_t.vec(
            "rpy_deg", 3, [0.0, 0.0, 0.0], ge=-MAX_ANGLE_DEG, le=MAX_ANGLE_DEG)))
        sources["tool"] = tool_t.str_("source", "not stated")

    controller = _controller(r, n)
    sources["controller"] = controller.source
    joints = r.table("joints", JOINT_KEYS, required=True)
    assert joints is not None
    limits = _joint_limits(path, joints, prismatic, controller, urdf_chain)
    sources["joints"] = joints.str_("source", "not stated")

    stiff = r.table("stiffness", STIFFNESS_KEYS, required=True)
    assert stiff is not None
    lo_k, hi_k = STIFFNESS_RANGE_NM_PER_RAD
    k = _per_joint(stiff, prismatic, ("k_Nm_per_rad", 1.0, lo_k, hi_k),
                   ("k_N_per_m", 1.0, lo_k, hi_k), ge_inclusive=True)
    sources["stiffness"] = stiff.str_("source", "not stated")

    effects: list[EffectSpec] = []
    for e in r.tables("effects", EFFECT_KEYS):
        label = _effect_label(e, n)
        if any(x.name == label for x in effects):
            raise e.error("name", f"'{label}' appears twice", "each effect once")
        params = e.mapping("params", ge=-MAX_EFFECT_PARAM, le=MAX_EFFECT_PARAM)
        effects.append(EffectSpec(label, params))
        if e.has("source"):
            sources[f"effects.{label}"] = e.str_("source")

    return RobotDescription(
        name=name,
        title=title,
        chain=chain,
        tool=tool,
        coupling=limits["coupling"],
        stiffness=k,
        lower=limits["lower"],
        upper=limits["upper"],
        velocity=limits["velocity"],
        acceleration=limits["acceleration"],
        jerk=limits["jerk"],
        euler=euler,
        effects=tuple(effects),
        sources=sources,
        path=Path(path),
        controller=controller,
        prismatic=prismatic if prismatic.any() else None,
        device_frame=_device_frame(r, sources),
        provenance=_provenance(r),
        plugins=_plugins(r, Path(path)),
        payload=_payload(r, tool),
    )


def _plugins(r: Table, path: Path) -> tuple[PluginSpec, ...]:
    """The ``[[effect_plugins]]`` entries: ``file`` (relative to the robot file) or
    ``entry_point``, their ``sha256`` and the ``effects`` they provide. Loading and checking
    the hash is the elastostatic model's job (:mod:`rfsw_plan.elastostatics.plugins`)."""
    out: list[PluginSpec] = []
    for t in r.tables("effect_plugins", PLUGIN_KEYS):
        if t.has("file") == t.has("entry_point"):
            raise t.error("file", "give either 'file' or 'entry_point'", "exactly one of them")
        digest = t.str_("sha256")
        if not re.fullmatch(r"[0-9a-f]{64}", digest):
            raise t.error("sha256", f"got '{digest[:20]}'", "64 lower-case hex digits")
        names = t.data.get("effects", [])
        if not isinstance(names, list) or not all(isinstance(x, str) for x in names):
            raise t.error("effects", f"got {names!r}"[:80], "a list of effect names")
        if t.has("file"):
            ref = Path(t.str_("file"))
            ref = ref if ref.is_absolute() else path.parent / ref
            out.append(PluginSpec("file", str(ref), digest, tuple(names)))
        else:
            out.append(PluginSpec("entry_point", t.str_("entry_point"), digest, tuple(names)))
    return tuple(out)


def _payload(r: Table, tool: FloatArray) -> Payload | None:
    """Parse the optional ``[payload]`` table: ``mass_kg``, ``com_mm`` in ``frame`` (``flange``:
    the chain's flange frame; ``tool``: the TCP frame of ``[tool]``), optional
    ``inertia_kgm2`` (principal moments about the centre of mass, flange axes), ``source``."""
    t = r.table("payload", PAYLOAD_KEYS)
    if t is None:
        return None
    mass = t.num("mass_kg", ge=0.0, le=MAX_PAYLOAD_KG)
    com = t.vec("com_mm", 3, [0.0, 0.0, 0.0], ge=-MAX_TOOL_MM, le=MAX_TOOL_MM) / 1000.0
    frame = t.str_("frame", "flange", choices=PAYLOAD_FRAMES)
    if frame == "tool":
        com = tool[:3, :3] @ com + tool[:3, 3]
    inertia = (t.vec("inertia_kgm2", 3, ge=0.0, le=1e4) if t.has("inertia_kgm2") else None)
    return Payload(float(mass), com, inertia, t.str_("source", "not stated"))


def _provenance(r: Table) -> dict[str, str]:
    """The optional ``[provenance]`` table (strings only)."""
    t = r.table("provenance", PROVENANCE_KEYS)
    if t is None:
        return {}
    return {k: t.str_(k) for k in PROVENANCE_KEYS if t.has(k)}


def derived_name(parent: str, added: tuple[str, ...] | list[str] = ()) -> str:
    """The default name of a re-identified robot: ``<parent>+<added labels>``.

    ``zk500`` + (``payload_gravity``,) -> ``zk500+payload_gravity``; a parent that is already
    derived keeps its labels (``zk500+payload_gravity`` + (``tilting_compliance:j2``,) ->
    ``zk500+payload_gravity+tilting_compliance:j2``); nothing added -> ``<base>+identified``.
    """
    base, *old = parent.split("+")
    new = [a for a in added if a not in old]
    return "+".join([base, *old, *new]) if added else f"{base}+identified"


def derived_file(name: str) -> str:
    """Where a proposed next command saves the robot ``name``: under ``out/robots/`` (never the
    repository's own ``robots/`` or the folder the command runs in), with the ``:`` of a
    joint label written ``-`` (``zk500+joint_compliance:j1`` ->
    ``out/robots/zk500+joint_compliance-j1.toml``), a file name every file system takes."""
    return f"out/robots/{name.replace(':', '-').replace('/', '_')}.toml"


def derived_description(desc: RobotDescription, *, name: str | None, parent: Path | None,
                        data: str | Path | None, command: str,
                        added: tuple[str, ...] = (),
                        forces: str | Path | None = None) -> RobotDescription:
    """A re-identified description with a new name and its provenance.

    Args:
        desc: The re-identified description.
        name: The new robot name; None makes :func:`derived_name` (e.g.
            ``zk500+payload_gravity``, or ``zk500+identified`` when nothing was added).
        parent: The robot file it was derived from.
        data: The measurement file it was identified on (its SHA-256 is recorded).
        command: The command that made it (``rfsw-plan validate``).
        added: Effect labels new in this description.
        forces: The force log the data was measured under, when it is a file of its own
            (``validate-weld``: the weld's force log; its SHA-256 is recorded).
    """
    from datetime import datetime

    from rfsw_plan.files import sha256_file

    if name is None:
        name = derived_name(desc.name, added)
    if not name.strip():
        raise InputError("name", "", "is empty", "a robot name")
    prov = {"created": datetime.now(UTC).strftime("%Y-%m-%d %H:%M:%S UTC"),
            "command": command}
    if parent is not None:
        prov["parent"] = str(parent)
    if data is not None:
        prov["data"] = str(data)
        if Path(data).is_file():
            prov["data_sha256"] = sha256_file(data)
    if forces is not None:
        prov["forces"] = str(forces)
        if Path(forces).is_file():
            prov["forces_sha256"] = sha256_file(forces)
    return replace(desc, name=name, title=f"{desc.title} (re-identified)"
                   if "re-identified" not in desc.title else desc.title, provenance=prov)


def _chain(kin: Table, path: Path | str) -> tuple[ModifiedDH | UrdfChain, UrdfSerialChain | None]:
    """The kinematic chain of ``[kinematics]`` (and the reduced URDF chain for a URDF)."""
    if kin.has("urdf"):
        extra = [k for k in DH_KEYS if k != "source" and kin.has(k)]
        if extra:
            raise kin.error(extra[0], "given together with urdf", "a URDF or a DH table")
        urdf = Path(kin.str_("urdf"))
        if not urdf.is_absolute():
            urdf = Path(path).parent / urdf
        check_not_xacro(urdf, path, kin.key("urdf"))
        if not urdf.is_file():
            raise kin.error("urdf", f"file {urdf} does not exist")
        chain = UrdfChain(urdf, kin.str_("tip_link"))
        return chain, load_urdf_chain(urdf, chain.tip_link, path)
    if kin.has("tip_link"):
        raise kin.error("tip_link", "given without urdf", "urdf = 'file.urdf' with it")
    kin.str_("convention", "modified_dh", choices=("modified_dh",))
    a = kin.vec("a_mm", None, ge=-MAX_LENGTH_MM, le=MAX_LENGTH_MM)
    n = a.size
    dh = ModifiedDH(
        a=a / 1000.0,
        d=kin.vec("d_mm", n, ge=-MAX_LENGTH_MM, le=MAX_LENGTH_MM) / 1000.0,
        alpha=np.radians(kin.vec("alpha_deg", n, ge=-MAX_ANGLE_DEG, le=MAX_ANGLE_DEG)),
        theta0=np.radians(kin.vec("theta0_deg", n, [0.0] * n,
                                  ge=-MAX_ANGLE_DEG, le=MAX_ANGLE_DEG)),
    )
    if kin.has("link_mass_kg") or kin.has("link_com_mm"):
        if not (kin.has("link_mass_kg") and kin.has("link_com_mm")):
            given = "link_mass_kg" if kin.has("link_mass_kg") else "link_com_mm"
            raise kin.error(given, "given alone", "link_mass_kg and link_com_mm together")
        dh = replace(dh, mass=kin.vec("link_mass_kg", n, ge=0.0, le=MAX_LINK_MASS_KG),
                     com=kin.matrix("link_com_mm", n, 3, ge=-MAX_LENGTH_MM,
                                    le=MAX_LENGTH_MM) / 1000.0)
    return dh, None


def _joint_limits(path: Path | str, joints: Table, prismatic: NDArray[np.bool_],
                  controller: ControllerConvention,
                  urdf_chain: UrdfSerialChain | None) -> dict[str, FloatArray]:
    """Limits [rad or m, /s, /s^2, /s^3] and the signed coupling ``G`` of ``[joints]``.

    Revolute joints are listed under ``*_deg*`` keys, prismatic ones under ``*_mm*`` keys
    (each in joint order). With a URDF chain, absent limits default to the URDF's (mapped to
    controller values), and given ones must lie inside them.
    """
    n = prismatic.size
    coupling = np.eye(n)
    if joints.has("coupling"):
        coupling = joints.matrix("coupling", n, n, ge=-MAX_COUPLING, le=MAX_COUPLING)
        cond = np.linalg.cond(coupling)
        if not np.isfinite(cond) or cond > MAX_COUPLING_CONDITION:
            raise joints.error("coupling", "is singular", "an invertible matrix")
    G = controller.sign[:, None] * coupling
    urdf_lo = urdf_hi = None
    if urdf_chain is not None:
        urdf_lo, urdf_hi = controller_box(G, controller.offset, urdf_chain.lower,
                                          urdf_chain.upper)
    deg, mm = math.pi / 180.0, 1e-3

    def per_joint(key: str, hi_deg: float, hi_mm: float, default: FloatArray | None = None,
                  positive: bool = True) -> FloatArray:
        rev, pri = key.replace("*", "deg"), key.replace("*", "mm")
        # Rates: at least MIN_RATE (1e-320 deg/s would make every motion last forever).
        lo_d, lo_m = (MIN_RATE, MIN_RATE) if positive else (-hi_deg, -hi_mm)
        return _per_joint(joints, prismatic, (rev, deg, lo_d, hi_deg), (pri, mm, lo_m, hi_mm),
                          default=default, ge_inclusive=True)

    lower = per_joint("lower_*", MAX_JOINT_DEG, MAX_TRAVEL_MM, _finite_or_none(urdf_lo), False)
    upper = per_joint("upper_*", MAX_JOINT_DEG, MAX_TRAVEL_MM, _finite_or_none(urdf_hi), False)
    bad = np.flatnonzero(lower >= upper)
    if bad.size:
        j = int(bad[0])
        unit, f = ("mm", 1e3) if prismatic[j] else ("deg", 180.0 / math.pi)
        raise joints.error(f"lower_{unit}", f"joint {j + 1}: lower {lower[j] * f:g} >= upper "
                           f"{upper[j] * f:g}", "lower < upper")
    if urdf_lo is not None and urdf_hi is not None:
        _check_inside_urdf(path, joints, lower, upper, urdf_lo, urdf_hi)
    urdf_v = None
    if urdf_chain is not None and np.all(np.isfinite(urdf_chain.velocity)) \
            and _is_signed_permutation(G):
        urdf_v = np.abs(np.linalg.inv(G)) @ urdf_chain.velocity
    velocity = per_joint("velocity_*_s", MAX_VELOCITY_DEG_S, 10 * MAX_VELOCITY_DEG_S, urdf_v)
    acceleration = per_joint("acceleration_*_s2", MAX_ACCELERATION_DEG_S2,
                             10 * MAX_ACCELERATION_DEG_S2)
    jerk = per_joint("jerk_*_s3", MAX_JERK_DEG_S3, 10 * MAX_JERK_DEG_S3,
                     np.minimum(acceleration * 10.0, np.where(prismatic, 10 * mm, deg)
                                * MAX_JERK_DEG_S3))
    return {"lower": lower, "upper": upper, "velocity": velocity,
            "acceleration": acceleration, "jerk": jerk, "coupling": G}


def _finite_or_none(x: FloatArray | None) -> FloatArray | None:
    return None if x is None or not np.all(np.isfinite(x)) else x


def _per_joint(t: Table, prismatic: NDArray[np.bool_], rev: tuple[str, float, float, float],
               pri: tuple[str, float, float, float], default: FloatArray | None = None,
               ge_inclusive: bool = False) -> FloatArray:
    """Join a revolute-joint list and a prismatic-joint list (joint order each) in SI.

    ``rev`` and ``pri`` are (key, file-to-SI factor, lower bound, upper bound) with the bounds
    in file units; the lower bound is exclusive unless ``ge_inclusive``. ``default`` is SI.
    """
    n = prismatic.size
    n_pri = int(prismatic.sum())
    out = np.empty(n)
    if n_pri and isinstance(t.data.get(rev[0]), list) and len(t.data[rev[0]]) == n:
        raise t.error(rev[0], f"has {n} values but {n_pri} joint(s) are prismatic",
                      f"{n - n_pri} revolute values, and {pri[0]}")
    for mask, (key, scale, lo, hi) in ((~prismatic, rev), (prismatic, pri)):
        count = int(mask.sum())
        if count == 0:
            if t.has(key):
                raise t.error(key, "the robot has no such joint",
                              f"{rev[0]} for revolute, {pri[0]} for prismatic joints")
            continue
        dflt = None if default is None else list(default[mask] / scale)
        vals = t.vec(key, count, dflt, ge=lo if ge_inclusive else None,
                     gt=None if ge_inclusive else lo, le=hi,
                     item="joint" if n_pri == 0 else "value")
        out[mask] = vals * scale
    return out


def read_device_frame(path: Path) -> DeviceFrame:
    """The ``[device_frame]`` table of a TOML file (a robot file or one with only that table).

    Raises:
        InputError: Unreadable file, unknown key, bad value, or no ``[device_frame]`` table.
    """
    frame = _device_frame(Table.load(path, TOP_KEYS), {})
    if frame is None:
        raise InputError(path, "device_frame", "missing table",
                         "base_in_device_xyz_mm, base_in_device_rpy_deg[, marker_xyz_mm]")
    return frame


def _device_frame(r: Table, sources: dict[str, str]) -> DeviceFrame | None:
    """The optional ``[device_frame]`` table (see :class:`DeviceFrame`)."""
    t = r.table("device_frame", DEVICE_FRAME_KEYS)
    if t is None:
        return None
    std = t.mapping("std", ge=0.0, le=1e9)
    sources["device_frame"] = t.str_("source", "not stated")
    registration = t.str_("registration", "held")
    if registration not in REGISTRATIONS:
        raise t.error("registration", f"got '{registration}'", " | ".join(REGISTRATIONS))
    return DeviceFrame(
        rotation=_rpy_to_matrix(np.radians(t.vec("base_in_device_rpy_deg", 3,
                                                 ge=-MAX_ANGLE_DEG, le=MAX_ANGLE_DEG))),
        translation=t.vec("base_in_device_xyz_mm", 3, ge=-MAX_LENGTH_MM,
                          le=MAX_LENGTH_MM) / 1000.0,
        marker=t.vec("marker_xyz_mm", 3, [0.0, 0.0, 0.0], ge=-MAX_TOOL_MM,
                     le=MAX_TOOL_MM) / 1000.0,
        std=std,
        each_file=registration == "each_file",
    )


def _effect_label(e: Table, n: int) -> str:
    """The effect label ``name[:jN]`` of an ``[[effects]]`` entry, with N in 1..n."""
    label = e.str_("name")
    m = _EFFECT_LABEL.match(label)
    if m is None:
        raise e.error("name", f"got '{label}'", "'effect_name' or 'effect_name:jN'")
    if m.group(2) is not None and not 1 <= int(m.group(2)) <= n:
        raise e.error("name", f"joint {m.group(2)} in '{label}' does not exist",
                      f"a joint 1..{n}")
    return label


def _controller(r: Table, n: int) -> ControllerConvention:
    """Parse the optional ``[controller]`` table (see :class:`ControllerConvention`)."""
    t = r.table("controller", CONTROLLER_KEYS)
    if t is None:
        return ControllerConvention.chain(n)
    axes = t.data.get("axes", [f"J{i + 1}" for i in range(n)])
    if (not isinstance(axes, list) or len(axes) != n
            or not all(isinstance(a, str) and a.isidentifier() for a in axes)
            or len(set(axes)) != n):
        raise t.error("axes", f"got {axes!r}"[:80], f"{n} distinct names like 'A1'")
    sign = t.vec("sign", n, [1.0] * n, ge=-1.0, le=1.0, item="joint")
    if not np.all(np.abs(sign) == 1.0):
        raise t.error("sign", f"got {sign.tolist()}", "each +1 or -1")
    offset = np.radians(t.vec("offset_deg", n, [0.0] * n, ge=-MAX_ANGLE_DEG, le=MAX_ANGLE_DEG,
                              item="joint"))

    def frame(prefix: str) -> FloatArray:
        T = np.eye(4)
        T[:3, 3] = t.vec(f"{prefix}_xyz_mm", 3, [0.0, 0.0, 0.0],
                         ge=-MAX_LENGTH_MM, le=MAX_LENGTH_MM) / 1000.0
        T[:3, :3] = _rpy_to_matrix(np.radians(t.vec(f"{prefix}_rpy_deg", 3, [0.0, 0.0, 0.0],
                                                    ge=-MAX_ANGLE_DEG, le=MAX_ANGLE_DEG)))
        return T

    return ControllerConvention("controller", tuple(axes), sign, offset, frame("base"),
                                frame("flange"), t.str_("source", "not stated"),
                                t.str_("maker", ""))


def _is_signed_permutation(G: FloatArray) -> bool:
    return bool(np.all(np.isin(G, (-1.0, 0.0, 1.0))) and np.all(np.abs(G).sum(axis=1) == 1)
                and np.all(np.abs(G).sum(axis=0) == 1))


def controller_box(
    G: FloatArray, offset: FloatArray, lo: FloatArray, hi: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Controller-value box [rad] equivalent to a chain box ``lo <= G q + offset <= hi``.

    Exact for a signed permutation ``G``; for a coupled joint (a row of G with more than one
    entry, e.g. FANUC's J2/J3 interaction) the chain limit is not a box in controller values
    and that joint's bounds are returned as -inf/+inf (not checked).
    """
    n = G.shape[0]
    qlo = np.full(n, -np.inf)
    qhi = np.full(n, np.inf)
    for i in range(n):
        cols = np.flatnonzero(G[i])
        if cols.size != 1:
            continue
        j = int(cols[0])
        a, b = (lo[i] - offset[i]) / G[i, j], (hi[i] - offset[i]) / G[i, j]
        qlo[j], qhi[j] = min(a, b), max(a, b)
    return qlo, qhi


def _check_inside_urdf(path: Path | str, joints: Table, lower: FloatArray, upper: FloatArray,
                       urdf_lo: FloatArray, urdf_hi: FloatArray) -> None:
    """A TOML joint limit outside the URDF's is an error naming joint and both values.

    Vendor URDFs round radians to 4 decimals (3.1415 for 180 deg), hence the 1e-4 rad slack.
    """
    tol = 1e-4
    for key, arr, ref, outside in (("lower_deg", lower, urdf_lo, lower < urdf_lo - tol),
                                   ("upper_deg", upper, urdf_hi, upper > urdf_hi + tol)):
        if np.any(outside):
            j = int(np.flatnonzero(outside)[0])
            raise InputError(path, joints.key(key),
                             f"joint {j + 1} is {np.degrees(arr[j]):g} deg, outside the URDF's "
                             f"limit {np.degrees(ref[j]):g} deg",
                             "a limit within the URDF's")


def check_stiffness(k: FloatArray, source: str | Path, where: str) -> None:
    """Raise :class:`InputError` unless every joint stiffness is finite and > 0 [N m/rad]."""
    bad = np.nonzero(~np.isfinite(k) | (k <= 0))[0]
    if bad.size:
        j = int(bad[0])
        raise InputError(source, where, f"joint {j + 1} stiffness is {k[j]:g}", "> 0 N m/rad")


def _rpy_to_matrix(rpy: FloatArray) -> FloatArray:
    """Roll-pitch-yaw (fixed X, then Y, then Z) [rad] to a rotation matrix."""
    r, p, y = rpy
    cr, sr = math.cos(r), math.sin(r)
    cp, sp = math.cos(p), math.sin(p)
    cy, sy = math.cos(y), math.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def _matrix_to_rpy(R: FloatArray) -> FloatArray:
    """Inverse of :func:`_rpy_to_matrix` [rad]."""
    p = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    r = math.atan2(R[2, 1], R[2, 2])
    y = math.atan2(R[1, 0], R[0, 0])
    return np.array([r, p, y])


# --------------------------------------------------------------------------------------------
# Writing


def _kinematics_toml(desc: RobotDescription) -> dict[str, Any]:
    """The ``[kinematics]`` table of a description (modified DH or URDF), file units."""
    if isinstance(desc.chain, ModifiedDH):
        c = desc.chain
        return {
            "convention": "modified_dh",
            "a_mm": _r(c.a * 1000.0),
            "d_mm": _r(c.d * 1000.0),
            "alpha_deg": _r(np.degrees(c.alpha)),
            "theta0_deg": _r(np.degrees(c.theta0)),
            **({} if c.mass is None or c.com is None else {
                "link_mass_kg": _r(c.mass), "link_com_mm": [_r(x * 1000.0) for x in c.com]}),
            "source": desc.sources.get("kinematics", "not stated"),
        }
    return {
        "urdf": str(desc.chain.path.resolve()),
        "tip_link": desc.chain.tip_link,
        "source": desc.sources.get("kinematics", "not stated"),
    }


def _controller_toml(conv: ControllerConvention) -> dict[str, Any]:
    """The ``[controller]`` table of a controller joint convention, file units."""
    return {
        **({"maker": conv.maker} if conv.maker else {}),
        "axes": list(conv.axes),
        "sign": _r(conv.sign),
        "offset_deg": _r(np.degrees(conv.offset)),
        "base_xyz_mm": _r(conv.base[:3, 3] * 1000.0),
        "base_rpy_deg": _r(np.degrees(_matrix_to_rpy(conv.base[:3, :3]))),
        "flange_xyz_mm": _r(conv.flange[:3, 3] * 1000.0),
        "flange_rpy_deg": _r(np.degrees(_matrix_to_rpy(conv.flange[:3, :3]))),
        "source": conv.source,
    }


def robot_description_to_toml_dict(desc: RobotDescription) -> dict[str, Any]:
    """Serialise a description to a TOML-ready dict (file units: mm, deg)."""
    out: dict[str, Any] = {"name": desc.name, "title": desc.title, "euler": desc.euler,
                           "kinematics": _kinematics_toml(desc)}
    out["tool"] = {
        "xyz_mm": _r(desc.tool[:3, 3] * 1000.0),
        "rpy_deg": _r(np.degrees(_matrix_to_rpy(desc.tool[:3, :3]))),
        "source": desc.sources.get("tool", "not stated"),
    }
    pri = np.zeros(desc.n_joints, dtype=bool) if desc.prismatic is None else desc.prismatic
    rev = ~pri

    def split(arr: FloatArray, rev_key: str, pri_key: str, scale_r: float,
              scale_p: float) -> dict[str, list[float]]:
        out_: dict[str, list[float]] = {rev_key: _r(arr[rev] / scale_r)}
        if pri.any():
            out_[pri_key] = _r(arr[pri] / scale_p)
        return out_

    deg, mm = math.pi / 180.0, 1e-3
    out["joints"] = {
        **split(desc.lower, "lower_deg", "lower_mm", deg, mm),
        **split(desc.upper, "upper_deg", "upper_mm", deg, mm),
        **split(desc.velocity, "velocity_deg_s", "velocity_mm_s", deg, mm),
        **split(desc.acceleration, "acceleration_deg_s2", "acceleration_mm_s2", deg, mm),
        **split(desc.jerk, "jerk_deg_s3", "jerk_mm_s3", deg, mm),
        "coupling": [_r(row) for row in desc.convention.sign[:, None] * desc.coupling],
        "source": desc.sources.get("joints", "not stated"),
    }
    conv = desc.convention
    if conv.kind == "controller":
        out["controller"] = _controller_toml(conv)
    stiff: dict[str, Any] = {"k_Nm_per_rad": [float(f"{k:.6g}") for k in desc.stiffness[rev]]}
    if pri.any():
        stiff["k_N_per_m"] = [float(f"{k:.6g}") for k in desc.stiffness[pri]]
    stiff["source"] = desc.sources.get("stiffness", "not stated")
    out["stiffness"] = stiff
    if desc.device_frame is not None:
        dfr = desc.device_frame
        out["device_frame"] = {
            "base_in_device_xyz_mm": _r(dfr.translation * 1000.0),
            "base_in_device_rpy_deg": _r(np.degrees(_matrix_to_rpy(dfr.rotation))),
            "marker_xyz_mm": _r(dfr.marker * 1000.0),
            "std": {k: float(f"{v:.6g}") for k, v in dfr.std.items()},
            **({"registration": "each_file"} if dfr.each_file else {}),
            "source": desc.sources.get("device_frame", "not stated"),
        }
    if desc.provenance:
        out["provenance"] = dict(desc.provenance)
    if desc.plugins:
        out["effect_plugins"] = [
            {("file" if x.kind == "file" else "entry_point"): x.ref, "sha256": x.sha256,
             "effects": list(x.effects)} for x in desc.plugins]
    if desc.payload is not None:
        pl = desc.payload
        out["payload"] = {"mass_kg": float(f"{pl.mass:.6g}"), "com_mm": _r(pl.com * 1000.0),
                          "frame": "flange",
                          **({"inertia_kgm2": _r(pl.inertia)} if pl.inertia is not None else {}),
                          "source": pl.source}
    if desc.effects:
        out["effects"] = []
        for e in desc.effects:
            entry: dict[str, Any] = {"name": e.name, "params": dict(e.params)}
            src = desc.sources.get(f"effects.{e.name}")
            if src:
                entry["source"] = src
            out["effects"].append(entry)
    return out


def save_robot_description(desc: RobotDescription, path: str | Path) -> Path:
    """Write a description as compact TOML (atomically); returns the path written.

    One line per key: lists on one line, the joint coupling matrix as one row per line, effect
    parameters as an inline table. Before the file exists, the text is parsed back and compared
    with what was meant, and read by the strict reader (:func:`parse_robot_description`), so a
    file that the tool would refuse to load (an identified parameter outside its effect's
    physical range) is never written.

    Raises:
        InputError: The description would not load (one line naming the key and its range).
    """
    import tomllib

    from rfsw_plan.files import write_text

    d = robot_description_to_toml_dict(desc)
    text = dumps_toml(d)
    if tomllib.loads(text) != d:  # pragma: no cover - a bug in the emitter, never a user error
        raise RuntimeError("robot TOML emitter does not round-trip")
    p = Path(path)
    try:
        parse_robot_description(tomllib.loads(text), p)
    except InputError as exc:
        raise InputError(p, exc.where, f"not written: the robot file would not load: "
                         f"{exc.problem}", exc.expected) from None
    p.parent.mkdir(parents=True, exist_ok=True)
    return write_text(p, text)


def _r(arr: FloatArray) -> list[float]:
    return [float(round(x, 9)) for x in np.asarray(arr, dtype=float)]
