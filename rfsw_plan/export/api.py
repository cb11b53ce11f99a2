"""Export a written plan as controller programs: build, write, re-read, check, commit.

Every program is first written into a private folder beside the target, re-read by its own
reader and taken through the robot model (:func:`rfsw_plan.export.readback.round_trip`): the
re-read points must reproduce the plan samples they were written from to 0.01 mm and
0.01 deg on the configuration the program states, and (``check``) pass the planner's
sample-by-sample verification. Only then are the files moved to their names; a failure
leaves nothing behind and raises :class:`~rfsw_plan.exceptions.InfeasibleError` (exit 3).
"""

from __future__ import annotations

import math
import shutil
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan import __version__
from rfsw_plan.exceptions import InfeasibleError, InputError
from rfsw_plan.export.config import (
    abb_confdata,
    configs_near,
    fanuc_config,
    kuka_status_turn,
)
from rfsw_plan.export.fanuc_tp import read_tp, write_tp
from rfsw_plan.export.krl import read_krl, write_krl
from rfsw_plan.export.program import (
    Program,
    ProgramHeader,
    Samples,
    build_program,
    read_samples,
    tolerated_from_record,
)
from rfsw_plan.export.rapid import read_rapid, write_rapid
from rfsw_plan.export.readback import ReadPoint, RoundTrip, round_trip
from rfsw_plan.export.stream import DEFAULT_CYCLE, write_stream
from rfsw_plan.files import sha256_file
from rfsw_plan.robot.kinematics import Robot

#: Export formats (``--export`` / ``--format`` values).
FORMATS = ("krl", "fanuc_tp", "rapid", "stream")

SampleCheck = Callable[[Samples], None]


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export_programs` wrote and how well it round-trips.

    Attributes:
        files: The files written, final names.
        round_trips: Per program format, the re-read points against the plan.
        n_points: Number of program points.
        stream_rows: Rows of the stream file (0 if not written).
        header: The program header.
        sample_check: What checked the re-read points and stream rows (empty: none).
    """

    files: tuple[Path, ...]
    round_trips: dict[str, RoundTrip]
    n_points: int
    stream_rows: int
    header: ProgramHeader
    sample_check: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (file units)."""
        return {
            "plan_id": self.header.plan_id,
            "files": [str(f) for f in self.files],
            "points": self.n_points,
            "spacing_mm": self.header.spacing * 1e3,
            "path_tolerance_mm": self.header.path_tol * 1e3,
            "stream_rows": self.stream_rows,
            "sample_check": self.sample_check or "none (plan samples vouched by plan.json)",
            "round_trip": {k: {"max_position_error_mm": float(np.max(r.pose_error)) * 1e3,
                               "max_angle_error_deg": math.degrees(float(np.max(r.angle_error))),
                               "max_joint_error_deg": math.degrees(float(np.max(r.joint_error)))}
                           for k, r in self.round_trips.items()},
        }


def parse_formats(text: str, option: str = "--export") -> list[str]:
    """Comma-separated format list -> names (one-line error naming the bad one)."""
    names = [f.strip() for f in text.split(",") if f.strip()]
    bad = [f for f in names if f not in FORMATS]
    if bad or not names:
        raise InputError(option, bad[0] if bad else "", "unknown format" if bad else "empty",
                         ", ".join(FORMATS))
    return list(dict.fromkeys(names))


def plan_spacing(record: dict[str, Any]) -> float:
    """The plan's waypoint spacing along the seam [m] (median step of the weld waypoints)."""
    wp = record.get("waypoints") or {}
    s = np.asarray(wp.get("s_mm", []), dtype=float)
    steps = np.diff(s)
    steps = steps[steps > 1e-9]
    if steps.size == 0:
        raise InputError("plan.json", "waypoints.s_mm", "no weld waypoints",
                         "a plan record with waypoints")
    return float(np.median(steps)) * 1e-3


def export_programs(
    robot: Robot, waypoints_csv: Path, record: dict[str, Any], formats: Sequence[str],
    out: Path, spacing: float | None = None, cycle: float = DEFAULT_CYCLE,
    path_tol: float = 1e-5, check: SampleCheck | None = None,
    stream: Samples | None = None,
) -> ExportResult:
    """Write the programs of a plan (see the module docstring).

    Args:
        robot: The robot of the plan.
        waypoints_csv: The plan's verified samples.
        record: The plan's ``plan.json`` record (problem, uncertainty, waypoints).
        formats: Names from :data:`FORMATS`.
        out: Output folder.
        spacing: Point spacing along the seam [m] (default: the plan's).
        cycle: Stream cycle [s].
        path_tol: Largest distance of a verified sample from the programmed path [m].
        check: The planner's sample check, applied to the re-read points and the stream.
        stream: The plan timed at the controller cycle (``plan --export stream``). Without
            it the stream is the written samples themselves, which needs the plan's sample
            time to be the cycle: a resampled trajectory would be a new, unchecked one
            (interpolating 10 ms samples at 4 ms breaks the jerk limits).
    """
    problem = str(record.get("problem", "plan"))
    spacing = plan_spacing(record) if spacing is None else spacing
    if not spacing > 0:
        raise InputError("--export-spacing-mm", "", f"got {spacing * 1e3:g}", "> 0")
    robot_file, robot_sha256 = _robot_file(robot)
    header = ProgramHeader(
        name=f"rfsw_{problem}", plan_id=f"{problem}-{sha256_file(waypoints_csv)[:12]}",
        problem=problem, robot=robot.name, robot_file=robot_file, robot_sha256=robot_sha256,
        version=__version__,
        tolerated_uncertainty=tolerated_from_record(record),
        requested_uncertainty=float(record.get("force_uncertainty_requested",
                                               record.get("force_uncertainty", 0.0)) or 0.0),
        window_mm=_window(record),
        path_tol=path_tol, spacing=spacing)
    samples = read_samples(waypoints_csv, robot)
    program = build_program(robot, samples, header, path_tol)
    out.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=".export-", dir=out))
    try:
        staged: list[Path] = []
        trips: dict[str, RoundTrip] = {}
        rows = 0
        for fmt in formats:
            if fmt == "stream":
                st = stream if stream is not None else _stream_from(samples, cycle)
                if check is not None:
                    check(st)
                staged.append(write_stream(stage / f"{header.name}_stream.csv", robot, st, cycle))
                rows = len(st)
                continue
            files, trip = _write_and_read_back(fmt, program, stage)
            if not trip.ok:
                raise InfeasibleError(f"{fmt} program does not reproduce the verified plan: "
                                      f"{trip.summary()}", None, "round_trip", None)
            if check is not None:
                moved = program.samples.subset(program.moved_points())
                check(replace(moved, q=trip.q))
            staged += files
            trips[fmt] = trip
        final = []
        for f in staged:
            target = out / f.name
            f.replace(target)
            final.append(target)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    checked = "" if check is None else f"passed: {getattr(check, '__doc__', '') or 'check'}"
    return ExportResult(tuple(final), trips, len(program.sample_index), rows, header,
                        checked.strip())


def _stream_from(samples: Samples, cycle: float) -> Samples:
    dt = float(np.max(np.diff(samples.t)))
    if abs(dt - cycle) > 1e-6:
        raise InputError("--stream-cycle-ms", "", f"{cycle * 1e3:g} ms is not the plan's sample "
                         f"time {dt * 1e3:g} ms", "the plan's sample time, or plan again with "
                         "--export stream (it times the plan at the cycle)")
    return samples


def _robot_file(robot: Robot) -> tuple[str, str]:
    """File name and hex SHA-256 of the robot's description file, ("", "") without one."""
    path = robot.description.path
    if path is None or not Path(path).is_file():
        return "", ""
    return Path(path).name, sha256_file(path)


def _window(record: dict[str, Any]) -> tuple[float, float]:
    w = record.get("window_mm") or [float("nan"), float("nan")]
    return float(w[0]), float(w[1])


def _write_and_read_back(fmt: str, program: Program, stage: Path) -> tuple[list[Path],
                                                                          RoundTrip]:
    robot = program.robot
    q_plan = program.samples.q[program.moved_points()]
    matches: Callable[[ReadPoint, Any], bool]
    if fmt == "krl":
        files = write_krl(program, stage)
        tool, work, points = read_krl(files[0])

        def matches(p: ReadPoint, q: Any) -> bool:
            return (p.config["S"], p.config["T"]) in configs_near(kuka_status_turn, robot, q)
    elif fmt == "fanuc_tp":
        files = write_tp(program, stage)
        tool, work, points = read_tp(files[0])

        def matches(p: ReadPoint, q: Any) -> bool:
            return p.config["CONFIG"] in configs_near(fanuc_config, robot, q)
    elif fmt == "rapid":
        files = write_rapid(program, stage)
        tool, work, points = read_rapid(files[0])

        def matches(p: ReadPoint, q: Any) -> bool:
            return p.config["cf"] in configs_near(abb_confdata, robot, q)
    else:
        raise InputError("--export", fmt, "unknown format", ", ".join(FORMATS))
    return files, round_trip(robot, tool, work, points, q_plan, matches)
