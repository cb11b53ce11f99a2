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
    approach_height_mm, approach_speed_mm_s, rotation_speed_rpm, spindle_runup_s,
    end_stop_s, thickness_mm, material

    [process.forces]
    axial_N, lateral_N, traverse_N, lateral_sign (+1 = toward the advancing side),
    plunge_peak_axial_N, dwell_lateral_fraction, dwell_tau_s, ramp_length_mm,
    spindle_torque_Nm

    [process.coupling]                  # optional: co-simulation penetration law
    penetration_stiffness_N_per_mm, reference_penetration_mm, reference_force_N,
    commanded_depth_mm                  # or calibration = "seed001_fig10" (law fitted to
                                        # observed plunges, see fit_penetration_law)

    [window]
    lower_mm = -1.25                    # retreating side
    upper_mm = 0.7                      # advancing side
    target_mm = 1.0

    [planning]                          # planner options (rfsw_plan.process.plan_options)
    q_seed_deg = [...]                  # configuration that picks the IK branch
    tool_rotation_deg = 0.0             # rotation about the tool axis
    force_uncertainty = 0.2             # relative
    offset_rate_mm_per_mm = 0.05        # fake-target offset change per mm of seam
    margin_mm, w_stiffness, ...         # see OPTION_KEYS

Every table rejects unknown keys with a "did you mean" (they are usually typos), and every
number must be finite and inside its valid range (file units; the ranges are the ``ge``/``gt``/
``le`` arguments below and in docs/formats/problem-files.md). The problem's ``[planning]``
table is parsed here, once, into the
:class:`~rfsw_plan.process.plan_options.PlanOptions` the planner uses.
"""

from __future__ import annotations

import csv
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import MISSING, dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.elastostatics.model import SeamReference
from rfsw_plan.exceptions import InputError, UnknownNameError
from rfsw_plan.process.cosim import PenetrationLaw, PenetrationObservation
from rfsw_plan.process.forces import AXIAL_CONTROLS, ProcessForces, ProcessModel
from rfsw_plan.process.frames import FloatArray, SeamFrames
from rfsw_plan.process.plan_options import PlanOptions, options_from_table
from rfsw_plan.process.presets import (
    PENETRATION_CALIBRATIONS,
    penetration_calibration,
    process_preset,
)
from rfsw_plan.process.seam import INTERPOLATIONS, MAX_TILT_DEG, ROTATIONS, Seam
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.robot.bundled import bundled_names, resolve_bundled
from rfsw_plan.robot.description import (
    RobotDescription,
    load_robot_description,
    resolve_robot_path,
)
from rfsw_plan.tomlreader import Table, unknown_name_error

#: Folder of the bundled problems.
BUNDLED_PROBLEMS_DIR = Path(__file__).resolve().parents[2] / "problems"

TOP_KEYS = ("name", "title", "robot", "seam", "process", "window", "planning", "source")
SEAM_KEYS = ("points_mm", "csv", "interpolation", "spacing_mm", "tilt_deg", "rotation",
             "reverse", "surface_normal", "reference", "source")
PROCESS_KEYS = ("preset", "travel_speed_mm_s", "plunge_speed_mm_s", "plunge_depth_mm",
                "dwell_s", "retract_speed_mm_s", "approach_height_mm", "approach_speed_mm_s",
                "rotation_speed_rpm", "spindle_runup_s", "end_stop_s", "thickness_mm",
                "material", "name", "source", "forces",
                "coupling", "axial_control")
FORCE_KEYS = ("axial_N", "lateral_N", "traverse_N", "lateral_sign", "plunge_peak_axial_N",
              "dwell_lateral_fraction", "dwell_tau_s", "ramp_length_mm", "spindle_torque_Nm",
              "source")
COUPLING_KEYS = ("penetration_stiffness_N_per_mm", "reference_penetration_mm",
                 "reference_force_N", "commanded_depth_mm", "calibration", "source")
#: Keys of an explicit penetration law (not allowed together with ``calibration``).
LAW_KEYS = ("penetration_stiffness_N_per_mm", "reference_penetration_mm", "reference_force_N")
WINDOW_KEYS = ("lower_mm", "upper_mm", "target_mm", "depth_shallow_mm", "depth_deep_mm",
               "tilt_tol_deg", "speed_tol_pct", "source")

#: Largest |coordinate| of a seam point [mm] (100 m: beyond any robot cell).
MAX_COORD_MM = 1e5
#: Valid waypoint spacing [mm].
SPACING_RANGE_MM = (0.01, 1e4)
#: Largest force [N] and torque [N m] of the process model.
MAX_FORCE_N = 1e6
MAX_TORQUE_NM = 1e5
#: Columns of a seam CSV.
SEAM_CSV_COLUMNS = ("x_mm", "y_mm", "z_mm", "nx", "ny", "nz")


@dataclass(frozen=True)
class Coupling:
    """Co-simulation settings of a problem.

    Attributes:
        law: Penetration law of the axial force, or None when it is fitted to
            ``calibration`` at run time (it depends on the robot's compliance at the taught
            seam start; see :func:`~rfsw_plan.process.cosim.fit_penetration_law`).
        commanded_depth: Commanded plunge depth [m] (seed 001: 8 mm for a 4.8 mm pin,
            the rest taken up by the robot's axial deflection).
        calibration: Observed plunges the law is fitted to (empty with an explicit law).
        calibration_name: Name of the bundled calibration (``seed001_fig10``), or "".
    """

    law: PenetrationLaw | None
    commanded_depth: float
    calibration: tuple[PenetrationObservation, ...] = ()
    calibration_name: str = ""


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
        planning: Planner options from the ``[planning]`` table (defaults where absent);
            ``q_seed`` is checked against the robot's joint limits.
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
    planning: PlanOptions
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
            return np.asarray(self.planning.q_seed, dtype=float)
        return 0.5 * (self.robot.lower + self.robot.upper)


def bundled_problem_names() -> list[str]:
    """Stems of the problems shipped in ``problems/``."""
    return bundled_names(BUNDLED_PROBLEMS_DIR)


def resolve_problem_path(name_or_path: str | Path) -> Path:
    """A problem file path from a path or a bundled stem.

    Raises:
        UnknownNameError: Neither an existing file nor a bundled stem; lists the bundled ones.
        InputError: A path with a folder part that does not exist ("no such file").
    """
    return resolve_bundled("problem", BUNDLED_PROBLEMS_DIR, name_or_path)


# --------------------------------------------------------------------------------------------
# Seam


def _read_seam_csv(path: Path, where: str) -> tuple[FloatArray, FloatArray | None]:
    """Points [m] (m, 3) and, if the CSV has nx, ny, nz, normals (m, 3) of a seam CSV.

    Raises:
        InputError: Unreadable file, unknown / duplicated / partial columns, a cell that is not
            a finite number in range, or a ragged row; names the file, row and column.
    """
    rows = _csv_rows(path, where)
    if not rows:
        raise InputError(path, "", "empty file", "a header x_mm,y_mm,z_mm and points")
    header = [h.strip() for h in rows[0][1]]
    cols = _seam_columns(path, header)
    out = np.empty((len(rows) - 1, len(cols)))
    for r, (line, row) in enumerate(rows[1:]):
        if len(row) != len(header):
            raise InputError(path, f"row {line}", f"has {len(row)} cells",
                             f"{len(header)} cells, as the header")
        for j, c in enumerate(cols):
            cell = row[header.index(c)].strip()
            try:
                v = float(cell)
            except ValueError:
                raise InputError(path, f"row {line}, column {c}",
                                 f"'{cell[:40]}' is not a number", "a number") from None
            limit = MAX_COORD_MM if c.endswith("_mm") else 1e6
            if not (np.isfinite(v) and abs(v) <= limit):
                raise InputError(path, f"row {line}, column {c}", f"got {cell[:40]}",
                                 f"a finite number with |value| <= {limit:g}")
            out[r, j] = v
    normals = out[:, 3:6] if len(cols) == 6 else None
    return out[:, :3] * 1e-3, normals


def _csv_rows(path: Path, where: str) -> list[tuple[int, list[str]]]:
    """Non-blank rows of a CSV with their 1-based line numbers."""
    rows: list[tuple[int, list[str]]] = []
    try:
        with path.open(newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            try:
                for r in reader:
                    if r and any(c.strip() for c in r):
                        rows.append((reader.line_num, r))
            except csv.Error as exc:  # a cell over csv.field_size_limit(), a NUL byte...
                raise InputError(path, f"row {reader.line_num}", f"not readable as CSV: {exc}",
                                 "comma-separated numbers under a header x_mm,y_mm,z_mm") from None
    except FileNotFoundError:
        raise InputError(path, "", f"no such file (seam CSV of {where})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, "", f"cannot read seam CSV ({where}): "
                         f"{' '.join(str(exc).split())[:120]}") from None
    return rows


def _seam_columns(path: Path, header: list[str]) -> list[str]:
    """The columns to read: x, y, z and, if all three are there, nx, ny, nz."""
    _check_header_names(path, header)
    missing = [c for c in ("x_mm", "y_mm", "z_mm") if c not in header]
    if missing:
        raise InputError(path, "header", f"missing column(s) {', '.join(missing)}",
                         "x_mm, y_mm, z_mm[, nx, ny, nz]")
    normals = [c for c in ("nx", "ny", "nz") if c in header]
    if normals and len(normals) != 3:
        absent = [c for c in ("nx", "ny", "nz") if c not in header]
        raise InputError(path, "header", f"has {', '.join(normals)} but not {', '.join(absent)}",
                         "all of nx, ny, nz or none")
    return ["x_mm", "y_mm", "z_mm", *normals]


def _check_header_names(path: Path, header: list[str]) -> None:
    """One delimiter (commas), each column once, and only the seam CSV's columns."""
    if len(header) == 1 and any(d in header[0] for d in ";\t "):
        raise InputError(path, "header", f"'{header[0][:60]}' is one column",
                         "comma-separated columns x_mm,y_mm,z_mm[,nx,ny,nz]")
    twice = next((h for i, h in enumerate(header) if h in header[:i]), None)
    if twice is not None:
        raise InputError(path, "header", f"column '{twice}' appears twice", "each column once")
    unknown = next((h for h in header if h not in SEAM_CSV_COLUMNS), None)
    if unknown is not None:
        raise unknown_name_error(path, "header", unknown, SEAM_CSV_COLUMNS, "column")


def _surface_normal(tab: Table) -> FloatArray:
    """``surface_normal``: one [nx, ny, nz] or one per point."""
    v = tab.data["surface_normal"]
    if isinstance(v, list) and v and all(isinstance(x, list) for x in v):
        return tab.matrix("surface_normal", None, 3, ge=-1e6, le=1e6)
    return tab.vec("surface_normal", 3, ge=-1e6, le=1e6)


def _seam(path: Path, tab: Table) -> tuple[Seam, float]:
    has_pts, has_csv = tab.has("points_mm"), tab.has("csv")
    if has_pts == has_csv:
        raise InputError(path, "seam", "give exactly one of points_mm and csv",
                         "points_mm = [[x, y, z], ...] or csv = 'file.csv'")
    normals: FloatArray | None = None
    if has_pts:
        pts = tab.matrix("points_mm", None, 3, min_rows=2, ge=-MAX_COORD_MM,
                         le=MAX_COORD_MM) * 1e-3
    else:
        p = Path(tab.str_("csv"))
        if not p.is_absolute():
            p = path.parent / p
        pts, normals = _read_seam_csv(p, f"{path}: {tab.key('csv')}")
    if tab.has("surface_normal"):
        if normals is not None:
            raise tab.error("surface_normal", "the seam CSV already has normals",
                            "normals in one place")
        normals = _surface_normal(tab)
    tab.str_("source", "")  # free text, but text
    seam = Seam(
        points=pts,
        interpolation=tab.str_("interpolation", "linear", choices=INTERPOLATIONS),  # type: ignore[arg-type]
        tilt=np.deg2rad(tab.num("tilt_deg", 0.0, ge=-MAX_TILT_DEG, le=MAX_TILT_DEG)),
        rotation=tab.str_("rotation", "cw", choices=ROTATIONS),  # type: ignore[arg-type]
        surface_normal=np.array([0.0, 0.0, 1.0]) if normals is None else normals,
        reverse=tab.bool_("reverse", False),
        source=f"{path}: seam",
    )
    lo, hi = SPACING_RANGE_MM
    spacing = tab.num("spacing_mm", 5.0, ge=lo, le=hi) * 1e-3
    return seam, spacing


# --------------------------------------------------------------------------------------------
# Process


def _value(tab: Table | None, k: str, prior: float | None, scale: float = 1.0, *,
           ge: float | None = None, gt: float | None = None, le: float | None = None) -> float:
    """``tab[k] * scale`` if given (range in file units), else the prior (preset or default).

    Raises:
        InputError: Out of range, or absent with no prior.
    """
    if tab is not None and tab.has(k):
        if k.endswith("_fraction"):  # a relative amount: "did you mean N %?" above le
            return tab.fraction(k, le=le if le is not None else 1.0) * scale
        return tab.num(k, ge=ge, gt=gt, le=le) * scale
    if prior is None:
        where = tab.key(k) if tab is not None else f"process.forces.{k}"
        raise InputError(tab.source if tab is not None else "problem", where, "missing",
                         "a number (or a process preset)")
    return prior


#: ``[process.forces]`` numbers: key -> (field, file-to-SI factor, valid range in file units).
FORCE_NUMBERS: dict[str, tuple[str, float, dict[str, float]]] = {
    "axial_N": ("axial", 1.0, {"ge": 0.0, "le": MAX_FORCE_N}),
    "lateral_N": ("lateral", 1.0, {"ge": 0.0, "le": MAX_FORCE_N}),
    "traverse_N": ("traverse", 1.0, {"ge": 0.0, "le": MAX_FORCE_N}),
    "dwell_lateral_fraction": ("dwell_lateral_fraction", 1.0, {"ge": 0.0, "le": 2.0}),
    "dwell_tau_s": ("dwell_tau", 1.0, {"ge": 1e-3, "le": 3600.0}),
    "ramp_length_mm": ("ramp_length", 1e-3, {"ge": 1e-3, "le": 1e4}),
    "spindle_torque_Nm": ("spindle_torque", 1.0, {"ge": -MAX_TORQUE_NM, "le": MAX_TORQUE_NM}),
}
#: ``[process]`` numbers: key -> (field, file-to-SI factor, valid range in file units).
PHASE_NUMBERS: dict[str, tuple[str, float, dict[str, float]]] = {
    "travel_speed_mm_s": ("travel_speed", 1e-3, {"ge": 0.01, "le": 1e3}),
    "plunge_speed_mm_s": ("plunge_speed", 1e-3, {"ge": 0.01, "le": 1e3}),
    "plunge_depth_mm": ("plunge_depth", 1e-3, {"ge": 1e-3, "le": 100.0}),
    "dwell_s": ("dwell_time", 1.0, {"ge": 0.0, "le": 3600.0}),
    "retract_speed_mm_s": ("retract_speed", 1e-3, {"ge": 0.01, "le": 1e3}),
    "approach_height_mm": ("approach_height", 1e-3, {"ge": 0.0, "le": 1e4}),
    "approach_speed_mm_s": ("approach_speed", 1e-3, {"ge": 0.01, "le": 1e4}),
    "rotation_speed_rpm": ("rotation_speed_rpm", 1.0, {"ge": 0.0, "le": 1e5}),
    "spindle_runup_s": ("spindle_runup", 1.0, {"ge": 0.0, "le": 600.0}),
    "end_stop_s": ("end_stop", 1.0, {"ge": 0.0, "le": 600.0}),
    "thickness_mm": ("thickness", 1e-3, {"ge": 0.0, "le": 1e3}),
}


def _prior(base: Any, cls: type, name: str) -> Any:
    """The preset's value of field ``name``, else the dataclass default (None if required)."""
    if base is not None:
        return getattr(base, name)
    default = {f.name: f.default for f in fields(cls)}[name]
    return None if default is MISSING else default


def _numbers(tab: Table | None, spec: dict[str, tuple[str, float, dict[str, float]]],
             base: Any, cls: type) -> dict[str, Any]:
    """Every number of ``spec`` from ``tab`` (range-checked) or from the preset / default."""
    return {field: _value(tab, key, _prior(base, cls, field), scale, **rng)
            for key, (field, scale, rng) in spec.items()}


#: A friction stir weld presses the tool with kilonewtons (seed 001 Table 6: 4-9 kN axial): an
#: axial force below this [N] is kN written in an ``_N`` key.
MIN_AXIAL_N = 100.0


def _refuse_kilonewtons(ftab: Table) -> None:
    """``axial_N = 4.8`` (kN in an N key): one line naming the key and the likely unit."""
    for key in ("axial_N", "plunge_peak_axial_N"):
        if ftab.has(key):
            v = ftab.num(key, ge=0.0, le=MAX_FORCE_N)
            if 0.0 < v < MIN_AXIAL_N:
                raise ftab.error(key, f"got {v:g} N, which presses no friction stir weld: kN "
                                 "instead of N?", f"newtons (x1000: {v * 1e3:g} N); an axial "
                                 f"force of at least {MIN_AXIAL_N:g} N")


def _forces(path: Path, ftab: Table | None, base: ProcessForces | None) -> ProcessForces:
    """``[process.forces]`` over the preset's forces (every key optional with a preset)."""
    peak = _prior(base, ProcessForces, "plunge_peak_axial")
    sign = _prior(base, ProcessForces, "lateral_sign")
    source = _prior(base, ProcessForces, "source") or str(path)
    if ftab is not None:
        if ftab.has("plunge_peak_axial_N"):
            peak = ftab.num("plunge_peak_axial_N", ge=0.0, le=MAX_FORCE_N)
        sign = ftab.num("lateral_sign", sign, ge=-1.0, le=1.0)
        if sign not in (1.0, -1.0):
            raise ftab.error("lateral_sign", f"got {sign:g}",
                             "+1 (toward the advancing side) or -1")
        source = ftab.str_("source", "") or source
        _refuse_kilonewtons(ftab)
    return ProcessForces(**_numbers(ftab, FORCE_NUMBERS, base, ProcessForces),
                         lateral_sign=sign, plunge_peak_axial=peak, source=source)


def _phases(path: Path, tab: Table, forces: ProcessForces,
            base: ProcessModel | None) -> ProcessModel:
    """The phase kinematics of ``[process]`` over the preset's."""
    texts: dict[str, Any] = {k: tab.str_(k, _prior(base, ProcessModel, k))
                             for k in ("name", "material")}
    axial = tab.str_("axial_control", _prior(base, ProcessModel, "axial_control"))
    if axial not in AXIAL_CONTROLS:
        raise tab.error("axial_control", f"unknown axial control '{axial}'",
                        " or ".join(f'"{a}"' for a in AXIAL_CONTROLS))
    texts["axial_control"] = axial
    return ProcessModel(
        forces=forces,
        **_numbers(tab, PHASE_NUMBERS, base, ProcessModel),
        **texts,
        source=tab.str_("source", _prior(base, ProcessModel, "source") or str(path)),
    )


def _coupling(ctab: Table | None, proc: ProcessModel) -> Coupling | None:
    """``[process.coupling]``: the co-simulation penetration law, or None."""
    if ctab is None:
        return None
    depth = ctab.num("commanded_depth_mm", proc.plunge_depth * 1e3, ge=1e-3, le=100.0) * 1e-3
    if ctab.has("calibration"):
        given = [k for k in LAW_KEYS if ctab.has(k)]
        if given:
            raise ctab.error(given[0], "given together with 'calibration'",
                             "either calibration or an explicit law, not both")
        name = ctab.str_("calibration")
        if name not in PENETRATION_CALIBRATIONS:
            raise ctab.error("calibration", f"unknown calibration '{name}'",
                             ", ".join(PENETRATION_CALIBRATIONS))
        ctab.str_("source", "")
        return Coupling(law=None, commanded_depth=depth,
                        calibration=penetration_calibration(name), calibration_name=name)
    law = PenetrationLaw(
        stiffness=ctab.num("penetration_stiffness_N_per_mm", ge=1.0, le=1e9) * 1e3,
        ref_penetration=ctab.num("reference_penetration_mm", proc.plunge_depth * 1e3,
                                 ge=-100.0, le=100.0) * 1e-3,
        ref_force=ctab.num("reference_force_N", proc.forces.axial, ge=0.0, le=MAX_FORCE_N),
    )
    ctab.str_("source", "")
    return Coupling(law=law, commanded_depth=depth)


def _process(path: Path, tab: Table) -> tuple[ProcessModel, Coupling | None]:
    """``[process]`` with its ``[process.forces]`` and ``[process.coupling]`` tables."""
    base = process_preset(tab.str_("preset")) if tab.has("preset") else None
    ftab = tab.table("forces", FORCE_KEYS)
    if base is None and ftab is None:
        raise InputError(path, "process", "no preset and no [process.forces]",
                         "preset = 'seed001_aa6061_5mm' or a [process.forces] table")
    forces = _forces(path, ftab, base.forces if base is not None else None)
    proc = _phases(path, tab, forces, base)
    return proc, _coupling(tab.table("coupling", COUPLING_KEYS), proc)


# --------------------------------------------------------------------------------------------
# Window, robot and planning


def _window(wtab: Table | None) -> WeldWindow:
    if wtab is None:
        return WeldWindow()
    wtab.str_("source", "")
    return WeldWindow(
        lower=wtab.num("lower_mm", -1.25, ge=-100.0, le=100.0) * 1e-3,
        upper=wtab.num("upper_mm", 0.7, ge=-100.0, le=100.0) * 1e-3,
        target=wtab.num("target_mm", 1.0, ge=1e-3, le=100.0) * 1e-3,
        depth_shallow=wtab.num("depth_shallow_mm", 0.5, gt=0.0, le=100.0) * 1e-3,
        depth_deep=wtab.num("depth_deep_mm", 0.2, gt=0.0, le=100.0) * 1e-3,
        tilt_tol=float(np.deg2rad(wtab.num("tilt_tol_deg", 0.5, gt=0.0, le=45.0))),
        speed_tol=wtab.num("speed_tol_pct", 5.0, gt=0.0, le=100.0) * 1e-2,
    )


def _robot(path: Path, top: Table) -> RobotDescription:
    """The robot named by ``robot =`` (bundled name, or a path relative to the problem)."""
    ref = top.str_("robot")
    rp = Path(ref)
    if rp.suffix == ".toml" and not rp.is_absolute() and (path.parent / rp).is_file():
        ref = str(path.parent / rp)
    try:
        resolve_robot_path(ref)
    except UnknownNameError as exc:
        raise UnknownNameError(f"robot (in {path})", ref, exc.known) from None
    except InputError as exc:
        raise InputError(path, "robot", f"'{ref}': {exc.problem}",
                         "a bundled robot name or an existing .toml file") from None
    return load_robot_description(ref)


def _planning(path: Path, top: Table, robot: RobotDescription) -> PlanOptions:
    """``[planning]`` as :class:`PlanOptions`, with ``q_seed_deg`` inside the joint limits."""
    raw = top.data.get("planning", {})
    if not isinstance(raw, dict):
        raise top.error("planning", f"got {raw!r}"[:80], "a [planning] table")
    opts = options_from_table(raw, path)
    if opts.q_seed is None:
        return opts
    q = np.asarray(opts.q_seed)
    if q.shape != (robot.n_joints,):
        raise InputError(path, "planning.q_seed_deg", f"has {q.size} values",
                         f"{robot.n_joints} values, one per joint of {robot.name}")
    lo, hi = robot.lower, robot.upper
    bad = np.flatnonzero((q < lo - 1e-9) | (q > hi + 1e-9))
    if bad.size:
        j = int(bad[0])
        raise InputError(path, "planning.q_seed_deg",
                         f"joint {j + 1} at {np.rad2deg(q[j]):g} deg is outside "
                         f"[{np.rad2deg(lo[j]):g}, {np.rad2deg(hi[j]):g}] deg",
                         f"values within the limits of {robot.name}")
    return opts


@contextmanager
def _in_file(path: Path) -> Iterator[None]:
    """Re-raise an :class:`InputError` that names a table (``process.forces``) with the file."""
    try:
        yield
    except InputError as exc:
        if exc.source.startswith(str(path)) or exc.source.endswith(".csv"):
            raise
        where = f"{exc.source}.{exc.where}" if exc.where else exc.source
        raise InputError(path, where, exc.problem, exc.expected) from None


def load_problem(name_or_path: str | Path) -> Problem:
    """Load and validate a problem file (path or bundled stem).

    Raises:
        UnknownNameError: Unknown bundled problem, robot or process preset.
        InputError: Malformed file, unknown key or impossible value; the message names the
            file and key.
    """
    path = resolve_problem_path(name_or_path)
    top = Table.load(path, TOP_KEYS)
    robot = _robot(path, top)
    seam_tab = top.table("seam", SEAM_KEYS, required=True)
    proc_tab = top.table("process", PROCESS_KEYS, required=True)
    assert seam_tab is not None and proc_tab is not None
    with _in_file(path):  # the value objects' own checks name the table, not the file
        seam, spacing = _seam(path, seam_tab)
        process, coupling = _process(path, proc_tab)
        window = _window(top.table("window", WINDOW_KEYS))
    planning = _planning(path, top, robot)
    reference = seam_tab.str_("reference", "taught", choices=("taught", "absolute"))
    top.str_("source", "")
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
    "Problem",
    "bundled_problem_names",
    "load_problem",
    "resolve_problem_path",
    "with_process",
]
