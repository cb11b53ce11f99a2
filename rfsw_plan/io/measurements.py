"""Measurement files: joint values, wrench at the TCP and measured position (and orientation).

Format (CSV, header row, one sample per row; documented in docs/formats/measurements.md).
The delimiter (``,`` ``;`` or tab) and the decimal separator (point or comma) are detected; a
lab's own column names and units are read through a mapping file (``--columns FILE.toml``,
:class:`ColumnMap`).

* ``q1_<u> ... qN_<u>``: encoder joint values; ``<u>`` is ``deg``/``rad`` for a revolute joint,
  ``mm``/``m`` for a prismatic one (each joint its own unit).
* ``fx_N, fy_N, fz_N`` (or ``_kN``) and optional ``mx_Nm, my_Nm, mz_Nm`` (or ``_kNm``): the
  wrench the environment applies to the tool at the TCP. Robot base frame unless
  ``wrench_frame`` says ``tool`` (the TCP frame) or ``sensor`` (a force/torque sensor whose pose
  in the tool frame is given); converted to the base frame here, once. Missing moments mean 0;
  a file without any force column is a no-load session (all wrenches 0).
* ``x_mm, y_mm, z_mm`` (or ``_m``): measured position of the tracked point; a blank cell means
  "not measured". Robot base frame, or the measuring device's frame (``frame`` column or
  option ``device``), where a row gives all three axes or none.
* Optional orientation of the tool frame, in the same frame as the positions: a rotation
  vector ``rx_mrad, ry_mrad, rz_mrad`` (or ``_rad``/``_deg``), or a unit quaternion
  ``quat_w, quat_x, quat_y, quat_z``. All components or none.
* Several markers per pose (a laser tracker's three reflectors): ``x2_mm, y2_mm, z2_mm`` ...
  up to ``x9_mm`` beside marker 1's ``x_mm, y_mm, z_mm``, all in the same frame. Every marker
  is kept (:attr:`MeasurementSet.markers`); the position is their centroid, a point fixed to
  the tool like each of them.
* Orientation as Euler angles (a 6-D probe): ``rx, ry, rz`` columns with the mapping key
  ``orientation = "euler_xyz"`` (extrinsic x-y-z, scipy's ``"xyz"``) or another of
  :data:`ORIENTATIONS`; converted to a rotation vector here.
* A 6-D pose as markers: the mapping key ``orientation_markers_mm = L`` turns each row's
  measured pose (position p, orientation R) into four virtual markers p + L R v_k at the
  corners of a regular tetrahedron (|v_k| = 1, sum_k v_k = 0, :data:`TETRAHEDRON`), so that
  their centroid is the measured point and ``calibrate`` fits the orientation through the
  marker rows it already has: sum_k |e_k|^2 / 4 = |e_p|^2 + (2/3) L^2 |e_theta|^2 for a
  position error e_p and a small rotation error e_theta. L = sqrt(3/2) sigma_p / sigma_theta
  (the device's position noise per axis over its orientation noise per axis) weighs both
  by their noise (the least-squares weights 1/sigma_p^2 and 1/sigma_theta^2).
* Optional ``temperature_C`` (room or arm temperature [deg C], sanity-checked), kept as the
  extra ``temperature_C`` that the diagnosis correlates the residual with.
* Optional ``t_s`` (time [s]), ``pose_id`` (text), ``load_step`` (integer label of the commanded
  load), ``sigma_mm`` (1-sigma noise of the position measurement of that row), ``frame``
  (``base`` or ``device``, the same on every row). Any other numeric column is kept as an
  *extra* (temperature...).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.approach import approach_directions, check_directions
from rfsw_plan.elastostatics.measurement_set import (
    MEASUREMENT_FRAMES,
    FloatArray,
    MeasurementSet,
)
from rfsw_plan.exceptions import InputError
from rfsw_plan.files import atomic_path
from rfsw_plan.numfmt import cell, fixed, general
from rfsw_plan.table import (
    ColumnMap,
    Quantity,
    Table,
    read_column_map,
    read_table,
    refuse_group_near_misses,
    refuse_near_misses,
)

__all__ = [
    "FORCE_COLUMNS",
    "MOMENT_COLUMNS",
    "POSITION_COLUMNS",
    "WRENCH_FRAMES",
    "MeasurementSet",
    "read_measurements",
    "write_measurements",
]

FORCE_COLUMNS = ("fx_N", "fy_N", "fz_N")
MOMENT_COLUMNS = ("mx_Nm", "my_Nm", "mz_Nm")
POSITION_COLUMNS = ("x_mm", "y_mm", "z_mm")
#: Frames a logged wrench may be given in.
WRENCH_FRAMES = ("base", "tool", "sensor")
#: Keys a column mapping file may have besides ``[columns]``.
MAPPING_OPTIONS = {
    "frame": "base | device",
    "wrench_frame": "base | tool | sensor",
    "source": "a note on where the data comes from",
    "orientation": "rotation_vector | euler_xyz | euler_XYZ | euler_zyx | euler_ZYX",
    "orientation_markers_mm": "lever L > 0 [mm] of four virtual markers from the 6-D pose",
}
#: How the ``rx, ry, rz`` columns hold an orientation: a rotation vector, or Euler angles
#: (scipy's sequence names: lower case extrinsic, upper case intrinsic).
ORIENTATIONS = ("rotation_vector", "euler_xyz", "euler_XYZ", "euler_zyx", "euler_ZYX")
#: Unit directions of the virtual markers of a 6-D pose (``orientation_markers_mm``): the
#: corners of a regular tetrahedron centred on the measured point, sum_k v_k = 0 and
#: sum_k v_k v_k^T = (4/3) I (every rotation axis weighed alike).
TETRAHEDRON = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, -1.0], [-1.0, 1.0, -1.0],
                        [-1.0, -1.0, 1.0]]) / math.sqrt(3.0)
#: Largest lever of the virtual markers [mm].
MAX_ORIENTATION_LEVER_MM = 10_000.0
#: Extra markers beside marker 1 (x, y, z): x2 .. x9.
MAX_MARKERS = 9
#: A temperature outside this range [deg C] is refused as a unit slip (K or deg F).
TEMPERATURE_RANGE_C = (-40.0, 100.0)

_ANGLE = {"deg": math.pi / 180.0, "rad": 1.0}
_LENGTH = {"mm": 1e-3, "m": 1.0}
FORCES = tuple(Quantity(k, {"N": 1.0, "kN": 1e3}) for k in ("fx", "fy", "fz"))
MOMENTS = tuple(Quantity(k, {"Nm": 1.0, "kNm": 1e3}) for k in ("mx", "my", "mz"))
POSITIONS = tuple(Quantity(k, _LENGTH) for k in ("x", "y", "z"))
ROTVEC = tuple(Quantity(k, {"mrad": 1e-3, "rad": 1.0, "deg": math.pi / 180.0})
               for k in ("rx", "ry", "rz"))
QUATERNION = tuple(Quantity(f"quat_{k}", {"": 1.0}) for k in "wxyz")
TIME = Quantity("t", {"s": 1.0})
SIGMA = Quantity("sigma", _LENGTH)
POSE_ID = Quantity("pose_id", {"": 1.0}, text=True)
LOAD_STEP = Quantity("load_step", {"": 1.0}, text=True)
FRAME = Quantity("frame", {"": 1.0}, text=True)
TEMPERATURE = Quantity("temperature", {"C": 1.0})
MARKERS = tuple(tuple(Quantity(f"{a}{k}", _LENGTH) for a in "xyz")
                for k in range(2, MAX_MARKERS + 1))

#: A function giving the TCP rotation in the base frame for joint values (m, n), shape
#: (m, 3, 3): what the reader needs to bring a tool- or sensor-frame wrench into the base frame.
ToolRotation = Callable[[FloatArray], FloatArray]


def joint_quantity(j: int, prismatic: bool | None) -> Quantity:
    """Quantity of joint j (1-based): angles for revolute, lengths for prismatic, either if
    the joint type is not known."""
    units = _LENGTH if prismatic else _ANGLE if prismatic is False else {**_ANGLE, **_LENGTH}
    return Quantity(f"q{j}", units)


def load_column_map(path: str | Path | None) -> ColumnMap | None:
    """Read a ``--columns`` mapping file (None passes through)."""
    return None if path is None else read_column_map(path, MAPPING_OPTIONS)


def _choice(value: object, allowed: Sequence[str], source: str, where: str) -> str:
    if not isinstance(value, str) or value not in allowed:
        raise InputError(source, where, f"got {value!r}", " | ".join(allowed))
    return value


def _joints(tab: Table, n_joints: int | None, prismatic: Sequence[bool] | None) -> FloatArray:
    cols: list[FloatArray] = []
    j = 1
    while True:
        kind = None if prismatic is None or j > len(prismatic) else bool(prismatic[j - 1])
        q = joint_quantity(j, kind)
        hit = tab.find(q)
        if hit is None:
            other = tab.find(joint_quantity(j, None)) if kind is not None else None
            if other is not None:
                what = "a length (mm, m)" if kind else "an angle (deg, rad)"
                raise InputError(tab.path, f"column '{other[0]}'",
                                 f"joint {j} is {'prismatic' if kind else 'revolute'}", what)
            break
        cols.append(tab.numbers(*hit))
        j += 1
    n_file = len(cols)
    if n_file == 0:
        raise tab.missing(joint_quantity(1, None if prismatic is None else bool(prismatic[0])))
    if n_joints is not None and n_file != n_joints:
        raise InputError(tab.path, f"joint columns q1..q{n_file}",
                         f"file has {n_file} joints but the robot has {n_joints}",
                         f"q1 ... q{n_joints}")
    return np.stack(cols, axis=1)


def _vector(tab: Table, qs: Sequence[Quantity], label: str,
            allow_blank: bool = False) -> FloatArray | None:
    hits = [tab.find(q) for q in qs]
    present = [h[0] for h in hits if h is not None]
    if not present:
        return None
    if len(present) != len(qs):
        first = next(q for q, h in zip(qs, hits, strict=True) if h is None)
        err = tab.missing(first)
        raise InputError(err.source, err.where, f"{err.problem} ({label} needs all of "
                         f"{', '.join(q.key for q in qs)}; the file has {', '.join(present)})",
                         err.expected)
    return np.stack([tab.numbers(h[0], h[1], allow_blank) for h in hits if h is not None], axis=1)


def _orientation(tab: Table, kind: str = "rotation_vector") -> FloatArray | None:
    rv = _vector(tab, ROTVEC, "an orientation rotation vector")
    if rv is not None and kind != "rotation_vector":
        from scipy.spatial.transform import Rotation

        return np.asarray(Rotation.from_euler(kind.removeprefix("euler_"), rv).as_rotvec())
    quat = _vector(tab, QUATERNION, "an orientation quaternion")
    if rv is not None and quat is not None:
        raise InputError(tab.path, "header", "both a rotation vector and a quaternion",
                         "one orientation")
    if quat is None:
        return rv
    norm = np.linalg.norm(quat, axis=1)
    bad = np.flatnonzero(np.abs(norm - 1.0) > 1e-3)
    if bad.size:
        r = tab.row_numbers[int(bad[0])]
        raise InputError(tab.path, f"row {r}, columns quat_w..quat_z",
                         f"quaternion norm {norm[bad[0]]:.6g}", "a unit quaternion (norm 1)")
    quat = quat / norm[:, None]
    quat = np.where(quat[:, :1] < 0, -quat, quat)  # w >= 0: angle in [0, pi]
    angle = 2.0 * np.arctan2(np.linalg.norm(quat[:, 1:], axis=1), quat[:, 0])
    s = np.linalg.norm(quat[:, 1:], axis=1)
    axis = np.divide(quat[:, 1:], s[:, None], out=np.zeros_like(quat[:, 1:]),
                     where=s[:, None] > 0)
    return axis * angle[:, None]


def _frame(tab: Table, frame: str | None, mapping: ColumnMap | None) -> str:
    sources: list[tuple[str, str]] = []
    hit = tab.find(FRAME)
    if hit is not None:
        values = sorted(set(tab.texts(hit[0])))
        if len(values) > 1:
            raise InputError(tab.path, "column 'frame'", f"several frames {values}",
                             "the same frame on every row")
        sources.append((_choice(values[0], MEASUREMENT_FRAMES, str(tab.path), "column 'frame'"),
                        "the file's frame column"))
    if mapping is not None and "frame" in mapping.options:
        sources.append((_choice(mapping.options["frame"], MEASUREMENT_FRAMES, mapping.source,
                                "frame"), mapping.source))
    if frame is not None:
        sources.append((_choice(frame, MEASUREMENT_FRAMES, "frame", ""), "`frame`"))
    if len({s[0] for s in sources}) > 1:
        said = "; ".join(f"{b} says {a}" for a, b in sources)
        raise InputError(tab.path, "frame", f"conflicting frames: {said}", "one frame")
    return sources[0][0] if sources else "base"


def _to_base(
    tab: Table, wrench: FloatArray, q: FloatArray, frame: str,
    sensor_pose: FloatArray | None, tool_rotation: ToolRotation | None,
) -> FloatArray:
    """Bring a tool- or sensor-frame wrench to the TCP in the base frame.

    Tool frame: ``f_b = R f_t``, ``m_b = R m_t``. Sensor frame (sensor at ``p_s`` with rotation
    ``R_s`` in the tool frame): ``f_t = R_s f_s``, ``m_t = R_s m_s + p_s x f_t`` (the moment
    carried from the sensor origin to the TCP), then as the tool frame.
    """
    if frame == "base":
        if sensor_pose is not None:
            raise InputError(tab.path, "wrench frame", "a sensor pose was given but the "
                             "wrench frame is base", "`wrench_frame` sensor with a sensor pose")
        return wrench
    if frame == "sensor":
        if sensor_pose is None:
            raise InputError(tab.path, "wrench frame", "sensor frame without a sensor pose",
                             "`sensor_pose` X_MM,Y_MM,Z_MM,RX_DEG,RY_DEG,RZ_DEG (sensor in "
                             "the tool frame)")
        Rs, ps = sensor_pose[:3, :3], sensor_pose[:3, 3]
        f = wrench[:, :3] @ Rs.T
        m = wrench[:, 3:] @ Rs.T + np.cross(ps, f)
        wrench = np.concatenate([f, m], axis=1)
    elif sensor_pose is not None:
        raise InputError(tab.path, "wrench frame", "a sensor pose was given but the wrench "
                         "frame is tool", "`wrench_frame` sensor")
    if tool_rotation is None:
        raise InputError(tab.path, "wrench frame", f"a {frame}-frame wrench needs the robot's "
                         "kinematics", "the robot (read through the CLI or the API with it)")
    R = tool_rotation(q)  # (m, 3, 3)
    return np.concatenate([np.einsum("mab,mb->ma", R, wrench[:, :3]),
                           np.einsum("mab,mb->ma", R, wrench[:, 3:])], axis=1)


def read_measurements(
    path: str | Path,
    n_joints: int | None = None,
    *,
    prismatic: Sequence[bool] | None = None,
    columns: ColumnMap | str | Path | None = None,
    frame: str | None = None,
    wrench_frame: str | None = None,
    sensor_pose: FloatArray | None = None,
    tool_rotation: ToolRotation | None = None,
) -> MeasurementSet:
    """Read a measurement CSV (see module docstring).

    Args:
        path: CSV file.
        n_joints: Expected joint count (the robot's); None accepts what the file has.
        prismatic: Per joint, True if prismatic (its column must be a length); None accepts
            either unit kind.
        columns: A lab's column mapping (:class:`ColumnMap` or its TOML file).
        frame: Frame of the positions (``base`` or ``device``); must agree with a ``frame``
            column or mapping key if those exist.
        wrench_frame: ``base`` (default), ``tool`` or ``sensor``.
        sensor_pose: Pose of the force sensor in the tool frame, 4x4 [m] (``sensor`` only).
        tool_rotation: TCP rotation in the base frame for joint values (``tool``/``sensor``).

    Raises:
        InputError: Unreadable file, missing, duplicated or partial columns (named, with a
            rename hint only from a column of the same quantity), a bad cell (row given,
            counting the header as row 1), joint count mismatch, no measured axis,
            inconsistent frames, a sensor frame without a sensor pose.
    """
    mapping = columns if isinstance(columns, ColumnMap) or columns is None else (
        load_column_map(columns))
    tab = read_table(path, mapping)
    q = _joints(tab, n_joints, prismatic)
    wf = _wrench_frame(tab, mapping, wrench_frame)
    wrench = _to_base(tab, _logged_wrench(tab), q, wf, sensor_pose, tool_rotation)
    position = _positions(tab)
    markers = _markers(tab, position)
    if markers is not None:
        position = np.mean(markers, axis=1)
    t, sigma, pose_id, load_step = _optional(tab)
    quantities = [joint_quantity(j + 1, None) for j in range(q.shape[1])]
    quantities += [*FORCES, *MOMENTS, *ROTVEC, *QUATERNION, *POSITIONS]
    quantities += [TIME, SIGMA, POSE_ID, LOAD_STEP, FRAME, TEMPERATURE]
    markers_q = [q for m in MARKERS for q in m]
    names = {x.key: h[0] for x in quantities + markers_q if (h := tab.find(x)) is not None}
    # A known quantity under a misspelt name (x__mm, Z_MM) would become an "extra" column and
    # its axis would silently go missing: refused with the names it may have. (Markers 2..9
    # are not: a file's own x2, y2 columns of other points stay extras unless named x2_mm.)
    known = quantities + [joint_quantity(j + 1, None) for j in range(q.shape[1], 12)]
    refuse_near_misses(tab, known, set(names.values()))
    refuse_group_near_misses(tab, [FORCES, MOMENTS, POSITIONS, ROTVEC, QUATERNION],
                             set(names.values()))
    if mapping is not None:  # a mapped key no reader asks for would be ignored
        unknown = sorted(set(mapping.columns) - {x.key for x in known + markers_q})
        if unknown:
            raise InputError(mapping.source, f"columns.{unknown[0]}", "not a quantity of a "
                             "measurement file", ", ".join(x.key for x in known[:-6]))
    extra = _extras(tab, set(names.values()))
    temperature = _temperature(tab)
    if temperature is not None:
        extra["temperature_C"] = temperature
    approach = _approach(tab, extra, q, t)
    measured_in = _frame(tab, frame, mapping)
    if measured_in == "device":
        _whole_positions(tab, position)
    rotation = _orientation(tab, _orientation_kind(mapping))
    lever = _orientation_lever(mapping)
    if lever is not None:
        markers = _pose_markers(tab, position, rotation, markers, lever)
    data = MeasurementSet(
        q, wrench, position, t, pose_id, sigma, extra,
        str(tab.path), frame=measured_in, rotation=rotation,
        load_step=load_step, dialect=tab.dialect, columns=names, approach=approach,
        markers=markers,
    )
    return replace(data, load_change=data.load_changes(), load_history=data.load_histories())


def _approach(tab: Table, extra: dict[str, FloatArray], q: FloatArray,
              t: FloatArray | None) -> FloatArray:
    """Approach direction of every joint (:mod:`rfsw_plan.elastostatics.approach`): from
    ``dir_q1 .. dir_qN`` columns (-1, 0 or +1; all joints or none; taken out of the extras),
    else from the time column, else from the row order of the whole file."""
    n = q.shape[1]
    named = [f"dir_q{j + 1}" for j in range(n)]
    present = [c for c in named if c in extra]
    if not present:
        return approach_directions(q, t)
    if len(present) != n:
        missing = next(c for c in named if c not in extra)
        raise InputError(tab.path, f"column '{missing}'", "missing: approach directions are "
                         "given for some joints only", f"all of dir_q1..dir_q{n} or none")
    values = np.stack([extra.pop(c) for c in named], axis=1)
    bad = check_directions(values)
    if bad.any():
        i, j = (int(x) for x in np.argwhere(bad)[0])
        raise InputError(tab.path, f"row {tab.row_numbers[i]}, column '{named[j]}'",
                         f"got {values[i, j]:g}", "-1, 0 or 1 (the direction the joint last "
                         "moved in)")
    return values


def _logged_wrench(tab: Table) -> FloatArray:
    """Forces and moments as logged [N, N m], shape (m, 6); zeros without force columns."""
    wrench = np.zeros((len(tab), 6))
    f = _vector(tab, FORCES, "the force")
    if f is None:
        named = [h for h in tab.header if h.strip().lower().split("_")[0] in ("fx", "fy", "fz")]
        if named or any(tab.find(x) for x in MOMENTS):
            raise tab.missing(FORCES[0])  # a force under another name: never read it as 0
        return wrench
    wrench[:, :3] = f
    mom = _vector(tab, MOMENTS, "the moment")
    if mom is not None:
        wrench[:, 3:] = mom
    return wrench


def _wrench_frame(tab: Table, mapping: ColumnMap | None, wrench_frame: str | None) -> str:
    """The wrench frame from the option and the mapping file (they must agree)."""
    wf = wrench_frame
    if mapping is not None and "wrench_frame" in mapping.options:
        wf_map = _choice(mapping.options["wrench_frame"], WRENCH_FRAMES, mapping.source,
                         "wrench_frame")
        if wf is not None and wf != wf_map:
            raise InputError(tab.path, "wrench frame", f"{mapping.source} says {wf_map}, "
                             f"`wrench_frame` says {wf}", "one frame")
        wf = wf_map
    return _choice(wf or "base", WRENCH_FRAMES, "wrench_frame", "")


def _positions(tab: Table) -> FloatArray:
    """Measured positions [m], shape (m, 3); NaN where not measured."""
    hits = [tab.find(x) for x in POSITIONS]
    if not any(hits):
        raise InputError(tab.path, "columns x_mm, y_mm, z_mm", "no measured TCP axis in the "
                         "file", "at least one of x_mm, y_mm, z_mm (or _m)")
    position = np.full((len(tab), 3), math.nan)
    for k, h in enumerate(hits):
        if h is not None:
            position[:, k] = tab.numbers(h[0], h[1], allow_blank=True)
    if not np.any(np.isfinite(position)):
        raise InputError(tab.path, "columns x_mm, y_mm, z_mm", "every position cell is blank",
                         "at least one measured value")
    return position


def _markers(tab: Table, position: FloatArray) -> FloatArray | None:
    """All markers of every row [m], shape (m, k, 3) (marker 1 = ``position``), or None when
    the file has marker 1 only. Every marker needs all three axes on every row (a centroid of
    some markers would be another point)."""
    extra: list[FloatArray] = []
    for k, qs in enumerate(MARKERS, start=2):
        v = _vector(tab, qs, f"marker {k}")
        if v is None:
            break
        extra.append(v)
    later = next((qs[0].key for qs in MARKERS[len(extra) + 1:] if tab.find(qs[0])), None)
    if later is not None:
        raise InputError(tab.path, f"columns of marker {later[1:]}", "given, but marker "
                         f"{len(extra) + 2} is missing", "markers numbered 2, 3, ... without gaps")
    if not extra:
        return None
    out = np.stack([position, *extra], axis=1)
    blank = np.flatnonzero(~np.all(np.isfinite(out), axis=(1, 2)))
    if blank.size:
        raise InputError(tab.path, f"row {tab.row_numbers[int(blank[0])]}", "a marker axis is "
                         "blank", "every axis of every marker on every row (several markers)")
    return out


def _orientation_lever(mapping: ColumnMap | None) -> float | None:
    """The lever of the virtual markers of a 6-D pose [m] (``orientation_markers_mm``), or None."""
    if mapping is None or "orientation_markers_mm" not in mapping.options:
        return None
    value = mapping.options["orientation_markers_mm"]
    if (isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value)
            or not 0.0 < value <= MAX_ORIENTATION_LEVER_MM):
        raise InputError(mapping.source, "orientation_markers_mm", f"got {value!r}",
                         f"a lever in (0, {MAX_ORIENTATION_LEVER_MM:g}] mm")
    return float(value) / 1000.0


def _pose_markers(tab: Table, position: FloatArray, rotation: FloatArray | None,
                  markers: FloatArray | None, lever: float) -> FloatArray:
    """Four virtual markers p + L R v_k of every row's 6-D pose [m], shape (m, 4, 3)
    (:data:`TETRAHEDRON`; their centroid is p)."""
    from scipy.spatial.transform import Rotation

    if rotation is None:
        raise InputError(tab.path, "header", "orientation_markers_mm is set but the file has "
                         "no orientation columns", "rx, ry, rz (or quat_w..quat_z) mapped")
    if markers is not None:
        raise InputError(tab.path, "columns of marker 2", "given together with "
                         "orientation_markers_mm", "markers or a 6-D pose, not both")
    blank = np.flatnonzero(~(np.all(np.isfinite(position), axis=1)
                             & np.all(np.isfinite(rotation), axis=1)))
    if blank.size:
        raise InputError(tab.path, f"row {tab.row_numbers[int(blank[0])]}", "a position or "
                         "orientation cell is blank", "the whole 6-D pose on every row "
                         "(orientation_markers_mm)")
    R = Rotation.from_rotvec(rotation).as_matrix()
    return position[:, None, :] + lever * np.einsum("mab,kb->mka", R, TETRAHEDRON)


def _temperature(tab: Table) -> FloatArray | None:
    """The temperature column [deg C], sanity-checked, or None."""
    hit = tab.find(TEMPERATURE)
    if hit is None:
        return None
    temp = tab.numbers(*hit)
    lo, hi = TEMPERATURE_RANGE_C
    bad = np.flatnonzero((temp < lo) | (temp > hi))
    if bad.size:
        k = int(bad[0])
        raise InputError(tab.path, f"row {tab.row_numbers[k]}, column '{hit[0]}'",
                         f"temperature {temp[k]:g} deg C is outside {lo:g} .. {hi:g} "
                         "(kelvin or deg F?)", "degrees Celsius")
    return temp


def _orientation_kind(mapping: ColumnMap | None) -> str:
    if mapping is None or "orientation" not in mapping.options:
        return "rotation_vector"
    return _choice(mapping.options["orientation"], ORIENTATIONS, mapping.source, "orientation")


def _whole_positions(tab: Table, position: FloatArray) -> None:
    """In the device frame a position is turned into the base frame as a whole (every base
    axis mixes all three device axes), so a row with some axes blank cannot be used: refused,
    naming the first such row (a base-frame file may leave single axes blank)."""
    given = np.isfinite(position)
    partial = np.flatnonzero(given.any(axis=1) & ~given.all(axis=1))
    if partial.size:
        k = int(partial[0])
        blank = ", ".join(f"{a}_mm" for a, g in zip("xyz", given[k], strict=True) if not g)
        raise InputError(tab.path, f"row {tab.row_numbers[k]}", f"{blank} blank while the other "
                         f"axes are given, in the device frame ({partial.size} "
                         f"row{'s' if partial.size > 1 else ''} like it)",
                         "all three axes of a device-frame position, or none")


def _optional(tab: Table) -> tuple[FloatArray | None, FloatArray | None,
                                   NDArray[np.str_] | None, NDArray[np.int_] | None]:
    """Time [s], sigma [m] (> 0), pose ids and integer load steps, each None if absent."""
    t_hit, s_hit, id_hit = tab.find(TIME), tab.find(SIGMA), tab.find(POSE_ID)
    t = None if t_hit is None else tab.numbers(*t_hit)
    sigma = None if s_hit is None else tab.numbers(*s_hit)
    if s_hit is not None and sigma is not None and np.any(sigma <= 0):
        r = tab.row_numbers[int(np.nonzero(sigma <= 0)[0][0])]
        raise InputError(tab.path, f"row {r}, column '{s_hit[0]}'", "must be > 0")
    pose_id = None if id_hit is None else tab.texts(id_hit[0])
    step_hit = tab.find(LOAD_STEP)
    if step_hit is None:
        return t, sigma, pose_id, None
    steps = tab.numbers(step_hit[0])
    bad = np.flatnonzero(steps != np.round(steps))
    if bad.size:
        raise InputError(tab.path, f"row {tab.row_numbers[int(bad[0])]}, column "
                         f"'{step_hit[0]}'", "not an integer", "an integer load-step label")
    return t, sigma, pose_id, steps.astype(np.int_)


def _extras(tab: Table, used: set[str]) -> dict[str, FloatArray]:
    """Every other numeric column, by name (text columns are ignored, as documented)."""
    extra: dict[str, FloatArray] = {}
    for name in tab.header:
        if name in used:
            continue
        try:
            extra[name] = tab.numbers(name)
        except InputError:
            continue
    return extra


def write_measurements(
    path: str | Path, data: MeasurementSet, prismatic: Sequence[bool] | None = None
) -> Path:
    """Write a measurement set in the documented CSV format (mm, deg), atomically.

    Args:
        path: Target file.
        data: The samples.
        prismatic: Per joint, True for a prismatic joint (written in mm); default all revolute.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    n = data.n_joints
    pris = [False] * n if prismatic is None else [bool(x) for x in prismatic]
    with atomic_path(p) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(_header(data, pris))
        for i in range(len(data)):
            w.writerow(_row(data, i, pris))
    return p


def _header(data: MeasurementSet, pris: list[bool]) -> list[str]:
    """The columns :func:`write_measurements` writes for ``data``."""
    header = ([] if data.t is None else ["t_s"]) + ([] if data.pose_id is None else ["pose_id"])
    header += [] if data.load_step is None else ["load_step"]
    header += [f"q{j + 1}_{'mm' if pris[j] else 'deg'}" for j in range(data.n_joints)]
    header += list(FORCE_COLUMNS + MOMENT_COLUMNS + POSITION_COLUMNS)
    header += [] if data.rotation is None else ["rx_mrad", "ry_mrad", "rz_mrad"]
    header += [] if data.sigma is None else ["sigma_mm"]
    header += [] if data.frame == "base" else ["frame"]
    return header + list(data.extra)


def _row(data: MeasurementSet, i: int, pris: list[bool]) -> list[str]:
    """Row ``i`` of :func:`write_measurements` in file units (every number through
    :mod:`rfsw_plan.numfmt`: the same text on every machine)."""
    row: list[str] = []
    if data.t is not None:
        row.append(fixed(data.t[i], 4))
    if data.pose_id is not None:
        row.append(str(data.pose_id[i]))
    if data.load_step is not None:
        row.append(str(int(data.load_step[i])))
    row += [fixed(v * 1000.0, 6) if pris[j] else fixed(np.degrees(v), 8)
            for j, v in enumerate(data.q[i])]
    row += [fixed(v, 6) for v in data.wrench[i]]
    row += [cell(v * 1000.0, 6) for v in data.position[i]]
    if data.rotation is not None:
        row += [fixed(v * 1000.0, 6) for v in data.rotation[i]]
    if data.sigma is not None:
        row.append(fixed(data.sigma[i] * 1000.0, 6))
    if data.frame != "base":
        row.append(data.frame)
    row += [general(data.extra[k][i], 6) if np.isfinite(data.extra[k][i]) else ""
            for k in data.extra]
    return row
