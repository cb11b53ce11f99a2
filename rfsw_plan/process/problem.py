"""Problem files: robot, seam, process, weld window and planning options in one TOML file.

Units are in the key names (mm, deg, s, N, N m); SI inside. Layout::

    name = "zk500_table6_seam"          # optional, default: file stem
    title = "..."                       # optional
    robot = "zk500"                     # bundled robot name or path (relative to this file)

    [seam]
    points_mm = [[x, y, z], ...]        # >= 2 taught points, base frame, travel order
    # csv = "seam.csv"                  # or a CSV with x_mm,y_mm,z_mm[,nx,ny,nz] columns
    interpolation = "linear"            # "linear" | "spline"
    spacing_mm = 5.0                    # waypoint spacing along the seam
    tilt_deg = 2.0                      # trailing tilt about l, |tilt| <= 15
    rotation = "cw"                     # spindle sense seen from above: "cw" | "ccw"
    reverse = false                     # travel from the last point to the first
    reference = "taught"                # "taught" (jogged with this robot and tool, default)
                                        # or "absolute" (CAD / measured, calibrated base frame)
    surface_normal = [0, 0, 1]          # or one [nx, ny, nz] per point

    [process]
    preset = "seed001_aa6061_5mm"       # optional start values (see presets.py)
    travel_speed_mm_s, plunge_speed_mm_s, plunge_depth_mm, dwell_s, retract_speed_mm_s,
    approach_height_mm, approach_speed_mm_s, rotation_speed_rpm, thickness_mm, material

    [process.forces]
    axial_N, lateral_N, traverse_N, lateral_sign (+1 = toward the advancing side),
    plunge_peak_axial_N, dwell_lateral_fraction, dwell_tau_s, ramp_length_mm,
    spindle_torque_Nm

    [process.coupling]                  # optional: co-simulation penetration law
    penetration_stiffness_N_per_mm, reference_penetration_mm, reference_force_N,
    commanded_depth_mm

    [window]
    lower_mm = -1.25                    # retreating side
    upper_mm = 0.7                      # advancing side
    target_mm = 1.0

    [planning]                          # read by the planner; unknown keys are kept
    q_seed_deg = [...]                  # configuration that picks the IK branch
    tool_rotation_deg = 0.0             # rotation about the tool axis
    force_uncertainty = 0.2             # relative
    offset_rate_mm_per_mm = 0.05        # fake-target offset change per mm of seam

Every table except ``[planning]`` rejects unknown keys (they are usually typos).
"""

from __future__ import annotations

import csv
import tomllib
from dataclasses import dataclass, field, replace
from difflib import get_close_matches
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.elastostatics.model import SeamReference
from rfsw_plan.exceptions import InputError, UnknownNameError
from rfsw_plan.process.cosim import PenetrationLaw
from rfsw_plan.process.forces import ProcessForces, ProcessModel
from rfsw_plan.process.frames import FloatArray, SeamFrames
from rfsw_plan.process.presets import process_preset
from rfsw_plan.process.seam import Seam
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.robot.bundled import bundled_names, resolve_bundled
from rfsw_plan.robot.description import (
    RobotDescription,
    load_robot_description,
    resolve_robot_path,
)

#: Folder of the bundled problems.
BUNDLED_PROBLEMS_DIR = Path(__file__).resolve().parents[2] / "problems"

_TOP_KEYS = {"name", "title", "robot", "seam", "process", "window", "planning", "source"}
_SEAM_KEYS = {"points_mm", "csv", "interpolation", "spacing_mm", "tilt_deg", "rotation",
              "reverse", "surface_normal", "reference", "source"}
_PROCESS_KEYS = {"preset", "travel_speed_mm_s", "plunge_speed_mm_s", "plunge_depth_mm",
                 "dwell_s", "retract_speed_mm_s", "approach_height_mm", "approach_speed_mm_s",
                 "rotation_speed_rpm", "thickness_mm", "material", "name", "source", "forces",
                 "coupling"}
_FORCE_KEYS = {"axial_N", "lateral_N", "traverse_N", "lateral_sign", "plunge_peak_axial_N",
               "dwell_lateral_fraction", "dwell_tau_s", "ramp_length_mm", "spindle_torque_Nm",
               "source"}
_COUPLING_KEYS = {"penetration_stiffness_N_per_mm", "reference_penetration_mm",
                  "reference_force_N", "commanded_depth_mm", "source"}
_WINDOW_KEYS = {"lower_mm", "upper_mm", "target_mm", "source"}


@dataclass(frozen=True)
class Coupling:
    """Co-simulation settings of a problem.

    Attributes:
        law: Penetration law of the axial force.
        commanded_depth: Commanded plunge depth [m] (seed 001: 8 mm for a 4.8 mm pin,
            the rest taken up by the robot's axial deflection).
    """

    law: PenetrationLaw
    commanded_depth: float


@dataclass(frozen=True)
class PlanningOptions:
    """Options for the planner.

    Attributes:
        q_seed: Seed configuration [rad], shape (n,), or None (robot-neutral).
        tool_rotation: Rotation about the tool axis [rad].
        force_uncertainty: Relative force uncertainty for robust planning [-].
        offset_rate: Allowed fake-target offset change per seam length [m/m], or None.
        extra: Other ``[planning]`` keys, as written (for the planner).
    """

    q_seed: FloatArray | None = None
    tool_rotation: float = 0.0
    force_uncertainty: float = 0.2
    offset_rate: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Problem:
    """A welding problem.

    Attributes:
        name: Problem name (file stem unless given).
        robot: Robot description (stiffness and effects from the robot file).
        seam: The taught seam.
        spacing: Waypoint spacing [m].
        process: Process and force model.
        window: Weld window.
        planning: Planner options.
        coupling: Co-simulation settings, or None.
        seam_reference: ``taught`` if the seam points were taught with this robot and tool
            (load-independent deflection such as payload sag is already in them), or
            ``absolute`` if they are CAD/measured points in the calibrated base frame; see
            :meth:`~rfsw_plan.elastostatics.model.ElastostaticModel.process_deflection`.
        title: One-line description.
        path: File the problem came from, or None.
    """

    name: str
    robot: RobotDescription
    seam: Seam
    spacing: float
    process: ProcessModel
    window: WeldWindow
    planning: PlanningOptions
    coupling: Coupling | None = None
    seam_reference: SeamReference = "taught"
    title: str = ""
    path: Path | None = None

    def frames(self) -> SeamFrames:
        """Seam waypoint frames at the problem's spacing."""
        return self.seam.frames(self.spacing)

    def q_seed(self) -> FloatArray:
        """Seed configuration [rad] (the middle of the joint range if none is given)."""
        if self.planning.q_seed is not None:
            return self.planning.q_seed
        return 0.5 * (self.robot.lower + self.robot.upper)


def bundled_problem_names() -> list[str]:
    """Stems of the problems shipped in ``problems/``."""
    return bundled_names(BUNDLED_PROBLEMS_DIR)


def resolve_problem_path(name_or_path: str | Path) -> Path:
    """A problem file path from a path or a bundled stem.

    Raises:
        UnknownNameError: Neither an existing file nor a bundled stem; lists the bundled ones.
    """
    return resolve_bundled("problem", BUNDLED_PROBLEMS_DIR, name_or_path)


class _Table:
    """Typed access to one TOML table; errors name the file and the dotted key."""

    def __init__(self, path: Path, data: Any, prefix: str, allowed: set[str] | None) -> None:
        self.path = path
        self.prefix = prefix
        if not isinstance(data, dict):
            raise InputError(path, prefix.rstrip("."), "is not a table", "a [table]")
        self.data: dict[str, Any] = data
        if allowed is not None:
            for k in data:
                if k not in allowed:
                    close = get_close_matches(k, sorted(allowed), n=1)
                    hint = f"; did you mean '{close[0]}'?" if close else ""
                    raise InputError(path, self.key(k), f"unknown key{hint}",
                                     ", ".join(sorted(allowed)))

    def key(self, k: str) -> str:
        return f"{self.prefix}{k}"

    def has(self, k: str) -> bool:
        return k in self.data

    def num(self, k: str, default: float | None = None) -> float:
        if k not in self.data:
            if default is None:
                raise InputError(self.path, self.key(k), "missing", "a number")
            return default
        v = self.data[k]
        if isinstance(v, bool) or not isinstance(v, int | float) or not np.isfinite(v):
            raise InputError(self.path, self.key(k), f"got {v!r}", "a finite number")
        return float(v)

    def str_(self, k: str, default: str | None = None) -> str:
        if k not in self.data:
            if default is None:
                raise InputError(self.path, self.key(k), "missing", "a string")
            return default
        v = self.data[k]
        if not isinstance(v, str):
            raise InputError(self.path, self.key(k), f"got {v!r}", "a string")
        return v

    def bool_(self, k: str, default: bool) -> bool:
        v = self.data.get(k, default)
        if not isinstance(v, bool):
            raise InputError(self.path, self.key(k), f"got {v!r}", "true or false")
        return v

    def array(self, k: str, shape: tuple[int | None, ...]) -> FloatArray:
        v = self.data[k]
        try:
            a = np.asarray(v, dtype=float)
        except (TypeError, ValueError):
            raise InputError(self.path, self.key(k), "not a numeric array",
                             _shape_text(shape)) from None
        ok = a.ndim == len(shape) and all(s is None or s == d for s, d in zip(shape, a.shape,
                                                                              strict=True))
        if not ok:
            raise InputError(self.path, self.key(k), f"got shape {a.shape}", _shape_text(shape))
        if not np.all(np.isfinite(a)):
            raise InputError(self.path, self.key(k), "contains NaN or infinity", "finite values")
        return a

    def sub(self, k: str, allowed: set[str] | None) -> _Table | None:
        if k not in self.data:
            return None
        return _Table(self.path, self.data[k], f"{self.prefix}{k}.", allowed)


def _shape_text(shape: tuple[int | None, ...]) -> str:
    if len(shape) == 1:
        return f"a list of {shape[0]} numbers"
    return "a list of [x, y, z] triples"


def _read_seam_csv(path: Path, where: str) -> tuple[FloatArray, FloatArray | None]:
    try:
        with path.open(newline="") as fh:
            rows = [r for r in csv.reader(fh) if r and any(c.strip() for c in r)]
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, "", f"cannot read seam CSV ({where}): {exc}") from None
    if not rows:
        raise InputError(path, "", "empty file", "a header x_mm,y_mm,z_mm and points")
    header = [h.strip() for h in rows[0]]
    need = ["x_mm", "y_mm", "z_mm"]
    missing = [c for c in need if c not in header]
    if missing:
        raise InputError(path, "header", f"missing column(s) {', '.join(missing)}",
                         "x_mm, y_mm, z_mm[, nx, ny, nz]")
    use_n = all(c in header for c in ("nx", "ny", "nz"))
    cols = need + (["nx", "ny", "nz"] if use_n else [])
    out = np.empty((len(rows) - 1, len(cols)))
    for r, row in enumerate(rows[1:], start=2):
        for j, c in enumerate(cols):
            i = header.index(c)
            cell = row[i].strip() if i < len(row) else ""
            try:
                out[r - 2, j] = float(cell)
            except ValueError:
                raise InputError(path, f"row {r}, column {c}", f"'{cell}' is not a number",
                                 "a number") from None
    return out[:, :3] * 1e-3, (out[:, 3:6] if use_n else None)


def _seam(path: Path, tab: _Table) -> tuple[Seam, float]:
    src = str(path)
    has_pts, has_csv = tab.has("points_mm"), tab.has("csv")
    if has_pts == has_csv:
        raise InputError(path, "seam", "give exactly one of points_mm and csv",
                         "points_mm = [[x, y, z], ...] or csv = 'file.csv'")
    normals: FloatArray | None = None
    if has_pts:
        pts = tab.array("points_mm", (None, 3)) * 1e-3
    else:
        p = Path(tab.str_("csv"))
        if not p.is_absolute():
            p = path.parent / p
        pts, normals = _read_seam_csv(p, tab.key("csv"))
    if tab.has("surface_normal"):
        if normals is not None:
            raise InputError(path, tab.key("surface_normal"), "the seam CSV already has normals",
                             "normals in one place")
        v = np.asarray(tab.data["surface_normal"], dtype=float)
        normals = tab.array("surface_normal", (3,) if v.ndim == 1 else (None, 3))
    interp = tab.str_("interpolation", "linear")
    rot = tab.str_("rotation", "cw")
    seam = Seam(
        points=pts,
        interpolation=interp,  # type: ignore[arg-type]  # validated by Seam
        tilt=np.deg2rad(tab.num("tilt_deg", 0.0)),
        rotation=rot,  # type: ignore[arg-type]
        surface_normal=np.array([0.0, 0.0, 1.0]) if normals is None else normals,
        reverse=tab.bool_("reverse", False),
        source=f"{src}: seam",
    )
    spacing = tab.num("spacing_mm", 5.0) * 1e-3
    if spacing <= 0:
        raise InputError(path, tab.key("spacing_mm"), f"got {spacing * 1e3:g}", "> 0")
    return seam, spacing


def _process(path: Path, tab: _Table) -> tuple[ProcessModel, Coupling | None]:
    base = process_preset(tab.str_("preset")) if tab.has("preset") else None
    ftab = tab.sub("forces", _FORCE_KEYS)
    if base is None and ftab is None:
        raise InputError(path, "process", "no preset and no [process.forces]",
                         "preset = 'seed001_aa6061_5mm' or a [process.forces] table")

    def num(t: _Table | None, k: str, prior: float | None, scale: float = 1.0) -> float:
        if t is not None and t.has(k):
            return t.num(k) * scale
        if prior is None:
            raise InputError(path, (t.key(k) if t is not None else k), "missing", "a number")
        return prior

    bf = base.forces if base is not None else None
    peak = bf.plunge_peak_axial if bf is not None else None
    if ftab is not None and ftab.has("plunge_peak_axial_N"):
        peak = ftab.num("plunge_peak_axial_N")
    forces = ProcessForces(
        axial=num(ftab, "axial_N", bf.axial if bf else None),
        lateral=num(ftab, "lateral_N", bf.lateral if bf else None),
        traverse=num(ftab, "traverse_N", bf.traverse if bf else None),
        lateral_sign=num(ftab, "lateral_sign", bf.lateral_sign if bf else 1.0),
        plunge_peak_axial=peak,
        dwell_lateral_fraction=num(ftab, "dwell_lateral_fraction",
                                   bf.dwell_lateral_fraction if bf else 0.5),
        dwell_tau=num(ftab, "dwell_tau_s", bf.dwell_tau if bf else 2.0),
        ramp_length=num(ftab, "ramp_length_mm", bf.ramp_length if bf else 1e-3, 1e-3),
        spindle_torque=num(ftab, "spindle_torque_Nm", bf.spindle_torque if bf else 0.0),
        source=(ftab.str_("source", "") if ftab is not None else "") or (bf.source if bf
                                                                         else str(path)),
    )
    b = base
    proc = ProcessModel(
        forces=forces,
        travel_speed=num(tab, "travel_speed_mm_s", b.travel_speed if b else None, 1e-3),
        plunge_speed=num(tab, "plunge_speed_mm_s", b.plunge_speed if b else None, 1e-3),
        plunge_depth=num(tab, "plunge_depth_mm", b.plunge_depth if b else None, 1e-3),
        dwell_time=num(tab, "dwell_s", b.dwell_time if b else 5.0),
        retract_speed=num(tab, "retract_speed_mm_s", b.retract_speed if b else 5e-3, 1e-3),
        approach_height=num(tab, "approach_height_mm", b.approach_height if b else 0.0, 1e-3),
        approach_speed=num(tab, "approach_speed_mm_s", b.approach_speed if b else 10e-3, 1e-3),
        rotation_speed_rpm=num(tab, "rotation_speed_rpm", b.rotation_speed_rpm if b else 0.0),
        name=tab.str_("name", b.name if b else ""),
        material=tab.str_("material", b.material if b else ""),
        thickness=num(tab, "thickness_mm", b.thickness if b else 0.0, 1e-3),
        source=tab.str_("source", b.source if b else str(path)),
    )
    ctab = tab.sub("coupling", _COUPLING_KEYS)
    coupling = None
    if ctab is not None:
        law = PenetrationLaw(
            stiffness=ctab.num("penetration_stiffness_N_per_mm") * 1e3,
            ref_penetration=ctab.num("reference_penetration_mm",
                                     proc.plunge_depth * 1e3) * 1e-3,
            ref_force=ctab.num("reference_force_N", proc.forces.axial),
        )
        cd = ctab.num("commanded_depth_mm", proc.plunge_depth * 1e3) * 1e-3
        if cd <= 0:
            raise InputError(path, ctab.key("commanded_depth_mm"), f"got {cd * 1e3:g}", "> 0")
        coupling = Coupling(law=law, commanded_depth=cd)
    return proc, coupling


def _planning(path: Path, tab: _Table | None, robot: RobotDescription) -> PlanningOptions:
    if tab is None:
        return PlanningOptions()
    known = {"q_seed_deg", "tool_rotation_deg", "force_uncertainty", "offset_rate_mm_per_mm"}
    q_seed = None
    if tab.has("q_seed_deg"):
        q_seed = np.deg2rad(tab.array("q_seed_deg", (robot.n_joints,)))
        lo, hi = robot.lower, robot.upper
        bad = np.flatnonzero((q_seed < lo - 1e-9) | (q_seed > hi + 1e-9))
        if bad.size:
            j = int(bad[0])
            raise InputError(path, tab.key("q_seed_deg"),
                             f"joint {j + 1} at {np.rad2deg(q_seed[j]):g} deg is outside "
                             f"[{np.rad2deg(lo[j]):g}, {np.rad2deg(hi[j]):g}] deg",
                             f"values within the limits of {robot.name}")
    fu = tab.num("force_uncertainty", 0.2)
    if fu < 0:
        raise InputError(path, tab.key("force_uncertainty"), f"got {fu:g}", ">= 0")
    rate = tab.num("offset_rate_mm_per_mm") if tab.has("offset_rate_mm_per_mm") else None
    if rate is not None and rate <= 0:
        raise InputError(path, tab.key("offset_rate_mm_per_mm"), f"got {rate:g}", "> 0")
    return PlanningOptions(
        q_seed=q_seed,
        tool_rotation=float(np.deg2rad(tab.num("tool_rotation_deg", 0.0))),
        force_uncertainty=fu,
        offset_rate=rate,
        extra={k: v for k, v in tab.data.items() if k not in known},
    )


def load_problem(name_or_path: str | Path) -> Problem:
    """Load and validate a problem file (path or bundled stem).

    Raises:
        UnknownNameError: Unknown bundled problem, robot or process preset.
        InputError: Malformed file; the message names the file and key.
    """
    path = resolve_problem_path(name_or_path)
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, "", f"cannot read file: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(path, "", f"not valid TOML: {exc}") from None
    top = _Table(path, data, "", _TOP_KEYS)
    robot_ref = top.str_("robot")
    rp = Path(robot_ref)
    if rp.suffix == ".toml" and not rp.is_absolute() and (path.parent / rp).is_file():
        robot_ref = str(path.parent / rp)
    try:
        resolve_robot_path(robot_ref)
    except UnknownNameError as exc:
        raise UnknownNameError(f"robot (in {path})", robot_ref, exc.known) from None
    robot = load_robot_description(robot_ref)
    for k in ("seam", "process"):
        if not top.has(k):
            raise InputError(path, k, "missing table", f"a [{k}] table")
    seam_tab = top.sub("seam", _SEAM_KEYS)
    proc_tab = top.sub("process", _PROCESS_KEYS)
    assert seam_tab is not None and proc_tab is not None
    try:
        seam, spacing = _seam(path, seam_tab)
        process, coupling = _process(path, proc_tab)
    except InputError as exc:
        if str(path) in str(exc):
            raise
        raise InputError(path, f"{exc.source}.{exc.where}", exc.problem, exc.expected) from None
    wtab = top.sub("window", _WINDOW_KEYS)
    try:
        window = WeldWindow() if wtab is None else WeldWindow(
            lower=wtab.num("lower_mm", -1.25) * 1e-3,
            upper=wtab.num("upper_mm", 0.7) * 1e-3,
            target=wtab.num("target_mm", 1.0) * 1e-3,
        )
    except InputError as exc:
        if str(path) in str(exc):
            raise
        raise InputError(path, f"window.{exc.where}", exc.problem, exc.expected) from None
    planning = _planning(path, top.sub("planning", None), robot)
    reference = seam_tab.str_("reference", "taught")
    if reference not in ("taught", "absolute"):
        raise InputError(path, seam_tab.key("reference"), f"got '{reference}'",
                         "'taught' or 'absolute'")
    return Problem(
        name=top.str_("name", path.stem),
        robot=robot,
        seam=seam,
        spacing=spacing,
        process=process,
        window=window,
        planning=planning,
        coupling=coupling,
        seam_reference=reference,  # type: ignore[arg-type]  # checked above
        title=top.str_("title", ""),
        path=path,
    )


def with_process(problem: Problem, process: ProcessModel) -> Problem:
    """The problem with another process (e.g. fitted to measured forces)."""
    return replace(problem, process=process)


__all__ = [
    "BUNDLED_PROBLEMS_DIR",
    "Coupling",
    "PlanningOptions",
    "Problem",
    "bundled_problem_names",
    "load_problem",
    "resolve_problem_path",
    "with_process",
]
