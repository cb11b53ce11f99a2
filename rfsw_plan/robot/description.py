"""Robot description files: kinematics, limits, coupling, stiffness and elastostatic effects.

A description is a human-readable TOML file (see ``robots/*.toml`` and the README). Lengths are
in mm and angles in degrees in the file (the unit is in every key name); everything inside the
code is SI (m, rad, N m/rad).

Kinematics are either a modified Denavit-Hartenberg table (Craig convention,
``T_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(q_i + theta0_i) Tz(d_i)``, seed 001 eq. 1) or a URDF file
plus the names of its base and tip links.

Joint values ``q`` everywhere in rfsw_plan are the *controller* joint values (what the robot's
encoders report and its programs use). The kinematic chain uses ``q_chain = G q`` where ``G`` is
the motor<->joint coupling matrix (identity for a plain serial arm; FANUC's parallelogram couples
joint 3 to joint 2, seed 000 eq. 2 and 4). Joint stiffness is on the controller/motor side, so the
joint-space compliance seen by the chain is ``G K^-1 G^T``.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.bundled import bundled_names, resolve_bundled

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
    """

    a: FloatArray
    d: FloatArray
    alpha: FloatArray
    theta0: FloatArray


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
class EffectSpec:
    """An elastostatic effect stored in a robot description.

    Attributes:
        name: Effect name, with ``:jN`` (1-based) for single-joint effects.
        params: Parameter values in SI units, keyed by parameter name.
    """

    name: str
    params: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class RobotDescription:
    """Everything rfsw_plan knows about one robot.

    Attributes:
        name: Short identifier (``zk500``).
        title: Human-readable description.
        chain: Kinematic chain, MDH table or URDF.
        tool: Flange-to-TCP transform [m], shape (4, 4).
        coupling: Matrix G with ``q_chain = G q`` (controller to chain joints), shape (n, n).
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
        InputError: Malformed file; the message names the file and key.
    """
    path = resolve_robot_path(name_or_path)
    if path.suffix == ".urdf":
        raise InputError(
            path, "", "a URDF needs a stiffness file", "a .toml with [kinematics] urdf = '...'"
        )
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, "", f"cannot read file: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(path, "", f"not valid TOML: {exc}") from None
    return parse_robot_description(data, path)


class _Reader:
    """Typed access to a TOML table with errors that name the file and key."""

    def __init__(self, path: Path | str, data: dict[str, Any], prefix: str = "") -> None:
        self.path = path
        self.data = data
        self.prefix = prefix

    def key(self, k: str) -> str:
        return f"{self.prefix}{k}"

    def table(self, k: str, required: bool = True) -> _Reader | None:
        v = self.data.get(k)
        if v is None:
            if required:
                raise InputError(self.path, f"[{self.key(k)}]", "missing section")
            return None
        if not isinstance(v, dict):
            raise InputError(self.path, self.key(k), "is not a table")
        return _Reader(self.path, v, f"{self.key(k)}.")

    def str_(self, k: str, default: str | None = None) -> str:
        v = self.data.get(k, default)
        if v is None:
            raise InputError(self.path, self.key(k), "missing key", "a string")
        if not isinstance(v, str):
            raise InputError(self.path, self.key(k), f"got {v!r}", "a string")
        return v

    def vec(self, k: str, n: int | None, default: list[float] | None = None) -> FloatArray:
        v = self.data.get(k, default)
        if v is None:
            raise InputError(self.path, self.key(k), "missing key", "a list of numbers")
        if not isinstance(v, list) or not all(
            isinstance(x, int | float) and not isinstance(x, bool) for x in v
        ):
            raise InputError(self.path, self.key(k), f"got {v!r}", "a list of numbers")
        arr = np.asarray(v, dtype=float)
        if n is not None and arr.shape != (n,):
            raise InputError(self.path, self.key(k), f"has {arr.size} values", f"{n} values")
        if not np.all(np.isfinite(arr)):
            raise InputError(self.path, self.key(k), "contains NaN or infinity", "finite numbers")
        return arr

    def matrix(self, k: str, n: int) -> FloatArray | None:
        v = self.data.get(k)
        if v is None:
            return None
        try:
            arr = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            raise InputError(self.path, self.key(k), f"got {v!r}", f"{n}x{n} numbers") from None
        if arr.shape != (n, n):
            raise InputError(self.path, self.key(k), f"has shape {arr.shape}", f"({n}, {n})")
        return arr


def parse_robot_description(data: dict[str, Any], path: Path | str) -> RobotDescription:
    """Build a :class:`RobotDescription` from parsed TOML data (see module docstring)."""
    r = _Reader(path, data)
    name = r.str_("name")
    title = r.str_("title", name)
    euler = r.str_("euler", "none")
    if euler not in EULER_CONVENTIONS:
        raise InputError(path, "euler", f"got '{euler}'", " or ".join(EULER_CONVENTIONS))
    sources: dict[str, str] = {}

    kin = r.table("kinematics")
    assert kin is not None  # required=True raises otherwise
    chain: ModifiedDH | UrdfChain
    if "urdf" in kin.data:
        urdf = Path(kin.str_("urdf"))
        if not urdf.is_absolute():
            urdf = Path(path).parent / urdf
        if not urdf.is_file():
            raise InputError(path, kin.key("urdf"), f"file {urdf} does not exist")
        chain = UrdfChain(urdf, kin.str_("tip_link"))
        n = _urdf_dof(urdf, chain.tip_link, path)
    else:
        convention = kin.str_("convention", "modified_dh")
        if convention != "modified_dh":
            raise InputError(path, kin.key("convention"), f"got '{convention}'", "modified_dh")
        a = kin.vec("a_mm", None)
        n = a.size
        chain = ModifiedDH(
            a=a / 1000.0,
            d=kin.vec("d_mm", n) / 1000.0,
            alpha=np.radians(kin.vec("alpha_deg", n)),
            theta0=np.radians(kin.vec("theta0_deg", n, [0.0] * n)),
        )
    sources["kinematics"] = kin.str_("source", "not stated")

    tool_t = r.table("tool", required=False)
    tool = np.eye(4)
    if tool_t is not None:
        tool[:3, 3] = tool_t.vec("xyz_mm", 3, [0.0, 0.0, 0.0]) / 1000.0
        tool[:3, :3] = _rpy_to_matrix(np.radians(tool_t.vec("rpy_deg", 3, [0.0, 0.0, 0.0])))
        sources["tool"] = tool_t.str_("source", "not stated")

    joints = r.table("joints")
    assert joints is not None
    lower = np.radians(joints.vec("lower_deg", n))
    upper = np.radians(joints.vec("upper_deg", n))
    bad = np.nonzero(lower >= upper)[0]
    if bad.size:
        raise InputError(
            path, joints.key("lower_deg"), f"joint {bad[0] + 1} lower >= upper", "lower < upper"
        )
    velocity = np.radians(joints.vec("velocity_deg_s", n))
    acceleration = np.radians(joints.vec("acceleration_deg_s2", n))
    jerk = np.radians(joints.vec("jerk_deg_s3", n, list(np.degrees(acceleration * 10.0))))
    for key, arr in (
        ("velocity_deg_s", velocity),
        ("acceleration_deg_s2", acceleration),
        ("jerk_deg_s3", jerk),
    ):
        if np.any(arr <= 0):
            j = int(np.nonzero(arr <= 0)[0][0])
            raise InputError(path, joints.key(key), f"joint {j + 1} is {arr[j]:g}", "> 0")
    coupling = joints.matrix("coupling", n)
    if coupling is None:
        coupling = np.eye(n)
    elif abs(np.linalg.det(coupling)) < 1e-9:
        raise InputError(path, joints.key("coupling"), "is singular", "an invertible matrix")
    sources["joints"] = joints.str_("source", "not stated")

    stiff = r.table("stiffness")
    assert stiff is not None
    k = stiff.vec("k_Nm_per_rad", n)
    check_stiffness(k, path, stiff.key("k_Nm_per_rad"))
    sources["stiffness"] = stiff.str_("source", "not stated")

    effects: list[EffectSpec] = []
    raw_effects = data.get("effects", [])
    if not isinstance(raw_effects, list):
        raise InputError(path, "effects", "is not an array of tables", "[[effects]] entries")
    for i, e in enumerate(raw_effects):
        if not isinstance(e, dict) or not isinstance(e.get("name"), str):
            raise InputError(path, f"effects[{i}]", "missing 'name'", "name = 'effect[:jN]'")
        params = e.get("params", {})
        if not isinstance(params, dict) or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
            for v in params.values()
        ):
            raise InputError(path, f"effects[{i}].params", "must map names to finite numbers")
        effects.append(EffectSpec(e["name"], {str(kk): float(v) for kk, v in params.items()}))
        if "source" in e:
            sources[f"effects.{e['name']}"] = str(e["source"])

    return RobotDescription(
        name=name,
        title=title,
        chain=chain,
        tool=tool,
        coupling=coupling,
        stiffness=k,
        lower=lower,
        upper=upper,
        velocity=velocity,
        acceleration=acceleration,
        jerk=jerk,
        euler=euler,
        effects=tuple(effects),
        sources=sources,
        path=Path(path),
    )


def check_stiffness(k: FloatArray, source: str | Path, where: str) -> None:
    """Raise :class:`InputError` unless every joint stiffness is finite and > 0 [N m/rad]."""
    bad = np.nonzero(~np.isfinite(k) | (k <= 0))[0]
    if bad.size:
        j = int(bad[0])
        raise InputError(source, where, f"joint {j + 1} stiffness is {k[j]:g}", "> 0 N m/rad")


def _urdf_dof(urdf: Path, tip_link: str, path: Path | str) -> int:
    import pinocchio as pin

    try:
        model = pin.buildModelFromUrdf(str(urdf))
    except Exception as exc:  # pinocchio raises plain RuntimeError/ValueError
        raise InputError(urdf, "", f"cannot parse URDF: {exc}") from None
    if not model.existFrame(tip_link):
        raise InputError(
            path, "kinematics.tip_link", f"no link '{tip_link}' in {urdf.name}",
            ", ".join(f.name for f in model.frames),
        )
    return int(model.nq)


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


def robot_description_to_toml_dict(desc: RobotDescription) -> dict[str, Any]:
    """Serialise a description to a TOML-ready dict (file units: mm, deg)."""
    out: dict[str, Any] = {"name": desc.name, "title": desc.title, "euler": desc.euler}
    if isinstance(desc.chain, ModifiedDH):
        out["kinematics"] = {
            "convention": "modified_dh",
            "a_mm": _r(desc.chain.a * 1000.0),
            "d_mm": _r(desc.chain.d * 1000.0),
            "alpha_deg": _r(np.degrees(desc.chain.alpha)),
            "theta0_deg": _r(np.degrees(desc.chain.theta0)),
            "source": desc.sources.get("kinematics", "not stated"),
        }
    else:
        out["kinematics"] = {
            "urdf": str(desc.chain.path.resolve()),
            "tip_link": desc.chain.tip_link,
            "source": desc.sources.get("kinematics", "not stated"),
        }
    out["tool"] = {
        "xyz_mm": _r(desc.tool[:3, 3] * 1000.0),
        "rpy_deg": _r(np.degrees(_matrix_to_rpy(desc.tool[:3, :3]))),
        "source": desc.sources.get("tool", "not stated"),
    }
    out["joints"] = {
        "lower_deg": _r(np.degrees(desc.lower)),
        "upper_deg": _r(np.degrees(desc.upper)),
        "velocity_deg_s": _r(np.degrees(desc.velocity)),
        "acceleration_deg_s2": _r(np.degrees(desc.acceleration)),
        "jerk_deg_s3": _r(np.degrees(desc.jerk)),
        "coupling": [_r(row) for row in desc.coupling],
        "source": desc.sources.get("joints", "not stated"),
    }
    out["stiffness"] = {
        "k_Nm_per_rad": [float(f"{k:.6g}") for k in desc.stiffness],
        "source": desc.sources.get("stiffness", "not stated"),
    }
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
    """Write a description as TOML; returns the path written."""
    import tomli_w

    from rfsw_plan.io.files import write_text

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    return write_text(p, tomli_w.dumps(robot_description_to_toml_dict(desc)))


def _r(arr: FloatArray) -> list[float]:
    return [float(round(x, 9)) for x in np.asarray(arr, dtype=float)]
