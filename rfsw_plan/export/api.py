"""Export a verified plan as controller programs: build, write, re-read, check, commit.

Every program is first written into a private staging folder in the system's temporary
directory by its format (:mod:`rfsw_plan.export.format`), re-read by the same format and taken
through the robot model (:func:`rfsw_plan.export.readback.round_trip`): the re-read points must
reproduce the plan samples they were written from to 0.01 mm and 0.01 deg on the configuration
the program states, (``check``) pass the planner's sample-by-sample verification, and
(``basis``) hold as their controller runs them what their header claims
(:func:`rfsw_plan.export.check.judge_program`, ``rfsw-plan check``'s judgement). Only then
is each file written under its name in the output folder, atomically
(:func:`rfsw_plan.files.write_bytes`: an unnamed file that gets its name when whole). A failure
leaves nothing in the output folder and raises :class:`~rfsw_plan.exceptions.InfeasibleError`
(exit 3); a run killed at any point, ``SIGKILL`` included, leaves no stray entry there (its
staging folder is in the temporary directory, which the system cleans).

:func:`export_plan_folder` does the same from a written plan folder read by the strict reader
(:meth:`rfsw_plan.planfiles.folder.PlanFolder.open_with_robot`), and makes the programs part of
what the folder's record vouches for.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan import __version__
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InfeasibleError, InputError, OutputPathError
from rfsw_plan.export.check import CLAIM_TOL, CheckResult, PlanBasis, judge_program
from rfsw_plan.export.format import (
    ControllerFormat,
    ReadProgram,
    formats,
    get_format,
    parse_formats,
)
from rfsw_plan.export.program import (
    Program,
    ProgramHeader,
    ProgramOptions,
    Samples,
    build_program,
    sample_fk,
    tolerated_from_record,
)
from rfsw_plan.export.readback import RoundTrip, round_trip
from rfsw_plan.files import sha256_file, write_bytes
from rfsw_plan.progress import Stages
from rfsw_plan.robot.kinematics import Robot

__all__ = ["ExportResult", "export_plan_folder", "export_programs", "parse_formats",
           "plan_spacing"]

SampleCheck = Callable[[Samples], None]


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export_programs` wrote and how well it round-trips.

    Attributes:
        files: The files written, final names.
        round_trips: Per format, the re-read points against the plan.
        n_points: Number of program points (of the first format written that has moves: the
            program is built once per interpolation cycle, so formats of another cycle may
            have others, ``points_per_format``).
        points_per_format: Points (rows, for a stream) each format wrote.
        header: The program header.
        sample_check: What checked the re-read points and stream rows (empty: none).
        max_path_deviation: Largest bound of a verified sample's distance to the path the
            controller runs, blending included [m].
        notes: What the programmer must know (payload, frames), also in every header.
        n_moved: Of ``n_points``, the points a motion moves to (the others are held by a
            wait); -1: not known.
        held_as_run: Per program format judged as its controller runs it
            (:func:`~rfsw_plan.export.check.judge_program`), the force uncertainty it holds
            and the quantity that limits it first.
        plan_tolerated: The plan's own tolerated force uncertainty (the header's level).
    """

    files: tuple[Path, ...]
    round_trips: dict[str, RoundTrip]
    n_points: int
    points_per_format: dict[str, int]
    header: ProgramHeader
    sample_check: str = ""
    max_path_deviation: float = 0.0
    notes: tuple[str, ...] = ()
    n_moved: int = -1
    held_as_run: dict[str, tuple[float, str]] = field(default_factory=dict)
    plan_tolerated: float = math.nan

    def below_plan(self) -> list[str]:
        """:func:`below_plan_lines` of this export."""
        return below_plan_lines(self.held_as_run, self.plan_tolerated)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (file units). ``files`` are named inside the folder they were
        written to (``plan.json``'s or ``export.json``'s own), so the record's bytes do not
        depend on where the folder is."""
        return {
            "plan_id": self.header.plan_id,
            "files": [f.name for f in self.files],
            "points": self.n_points,
            "spacing_mm": self.header.spacing * 1e3,
            "path_tolerance_mm": self.header.path_tol * 1e3,
            "max_path_deviation_mm": self.max_path_deviation * 1e3,
            "points_per_format": dict(self.points_per_format),
            "sample_check": self.sample_check or "none (plan samples vouched by plan.json)",
            "notes": list(self.notes),
            "round_trip": {k: {"max_position_error_mm": float(np.max(r.pose_error)) * 1e3,
                               "max_angle_error_deg": math.degrees(float(np.max(r.angle_error))),
                               "max_joint_error_deg": math.degrees(float(np.max(r.joint_error)))}
                           for k, r in self.round_trips.items()},
            **({"held_as_run": {k: {"tolerated_pct": _pct(u), "limited_by": by}
                                for k, (u, by) in self.held_as_run.items()}}
               if self.held_as_run else {}),
        }


def below_plan_lines(held: Mapping[str, tuple[float, str]], plan_tolerated: float
                     ) -> list[str]:
    """The formats whose program as its controller runs it holds less force uncertainty
    than the plan (``held``: format -> (level, limiting quantity), as
    :attr:`ExportResult.held_as_run` and ``plan.json``'s ``export.held_as_run``), one line
    each: ``krl: as its controller runs it the program holds +-2.73 % force uncertainty
    (speed first), below the plan's +-2.83 %; its header states it``."""
    return [f"{name}: as its controller runs it the program holds +-{100 * u:.2f} % force "
            f"uncertainty ({by} first), below the plan's +-{100 * plan_tolerated:.2f} %; "
            + ("plan.json records it (export.held_as_run)" if get_format(name).runs_rows
               else "its header states it")
            for name, (u, by) in held.items() if u < plan_tolerated * (1.0 - CLAIM_TOL)]


def plan_spacing(record: Mapping[str, Any]) -> float:
    """The plan's waypoint spacing along the seam [m] (median step of the weld waypoints,
    :attr:`rfsw_plan.planfiles.record.PlanRecord.spacing`)."""
    from rfsw_plan.planfiles.record import PlanRecord

    return PlanRecord(dict(record)).spacing


def plate_normal(problem_file: str, samples: Samples) -> tuple[np.ndarray | None, str]:
    """The plate's surface normal at the first weld sample and why it is not known
    (:func:`plate_surface`)."""
    normal, _, _, why = plate_surface(problem_file, samples)
    return normal, why


def plate_surface(problem_file: str, samples: Samples
                  ) -> tuple[np.ndarray | None, float, str, str]:
    """The plate's surface normal at the first weld sample (base frame, (3,)), from the plan's
    problem: the seam's *declared* surface normal there (``surface_normal``, interpolated
    along the seam as :class:`~rfsw_plan.process.seam.Seam` does), not made normal to the
    seam tangent (a seam that climbs 0.9 mm over 113 mm, zk500_table6_seam, would tilt the
    work object's z 0.454 deg off the plate). The work object's x is then the seam direction
    projected onto the plate (:func:`~rfsw_plan.export.program.plate_frame`). None, with the
    reason, when the problem cannot be read or its seam is not the one the samples follow
    (> 0.01 mm apart).

    Returns:
        (normal, plunge depth [m] (0 when unknown), the seam reference (``taught`` or
        ``absolute``), the reason the normal is unknown or "").
    """
    from rfsw_plan.exceptions import RfswError
    from rfsw_plan.process.problem import load_problem

    if not problem_file:
        return None, 0.0, "taught", "the plan names no problem file"
    try:
        problem = load_problem(problem_file)
    except (RfswError, OSError) as exc:
        return None, 0.0, "taught", f"problem {problem_file} not readable ({exc})"
    seam, depth, ref = problem.seam, problem.process.plunge_depth, problem.seam_reference
    weld = np.flatnonzero(np.isin(samples.phase, ("accelerate", "weld", "decelerate")))
    if weld.size == 0:
        return None, depth, ref, "no weld samples"
    fr = seam.frames_at(np.array([samples.s[weld[0]]]))
    if np.linalg.norm(fr.p[0] - samples.seam[weld[0]]) > 1e-5:
        return None, 0.0, ref, f"problem {Path(problem_file).name} has another seam than the plan"
    ns = seam.surface_normal_at(np.array([samples.s[weld[0]]]))[0]
    return np.asarray(ns / np.linalg.norm(ns)), depth, ref, ""



def _program_header(robot: Robot, record: Mapping[str, Any], problem: str, plan_sha256: str,
                    path_tol: float, spacing: float, depth: float) -> ProgramHeader:
    """The program's header from the plan's record (set force under axial force control,
    tolerated and requested uncertainty, window) and the export's settings [m]."""
    robot_file, robot_sha256 = _robot_file(robot)
    envelope = record.get("envelope") or {}
    set_force = _number(envelope.get("set_force_N")) \
        if envelope.get("axial_control") == "force" else 0.0
    header = ProgramHeader(
        name=f"rfsw_{problem}", plan_id=f"{problem}-{plan_sha256[:12]}",
        problem=problem, robot=robot.name, robot_file=robot_file, robot_sha256=robot_sha256,
        version=__version__,
        tolerated_uncertainty=tolerated_from_record(dict(record)),
        requested_uncertainty=_number(record.get("force_uncertainty_requested",
                                                 record.get("force_uncertainty", 0.0))),
        window_mm=_window(record), path_tol=path_tol, spacing=spacing, set_force=set_force,
        notes=() if depth > 0 else ("PLUNGE DEPTH UNKNOWN (problem file not readable): the "
                                    "base origin is on the seam point, not on the plate "
                                    "surface",))
    return header


def export_programs(
    robot: Robot, samples: Samples, record: Mapping[str, Any], fmts: Sequence[str], out: Path, *,
    plan_sha256: str, spacing: float | None = None, path_tol: float = 1e-5,
    check: SampleCheck | None = None, stream: Samples | None = None, cycle: float = 0.0,
    options: ProgramOptions | None = None, normal: np.ndarray | None = None,
    depth: float | None = None, reference: str | None = None, basis: PlanBasis | None = None,
) -> ExportResult:
    """Write the programs of a plan (see the module docstring).

    Args:
        robot: The robot of the plan.
        samples: The plan's verified samples (``waypoints.csv``).
        record: The plan's ``plan.json`` record (problem, uncertainty, waypoints).
        fmts: Format names (:func:`rfsw_plan.export.format.format_names`).
        out: Output folder.
        plan_sha256: SHA-256 of ``waypoints.csv`` (the plan id).
        spacing: Point spacing along the seam [m] (default: the plan's).
        path_tol: Largest distance of a verified sample from the path the controller runs [m].
        check: The planner's sample check, applied to the re-read points and the stream.
        stream: The plan timed at the controller cycle (``plan --export stream``); without it
            the stream is the written samples at the plan's own sample time.
        cycle: The stream's cycle [s] (with ``stream``).
        options: Tool/base numbers and hooks.
        normal: The plate's surface normal, base frame, (3,) (None: see :func:`build_program`).
        depth: The pin's plunge depth [m] (the work object's origin is this far above the
            seam, on the plate surface), and ``reference`` the seam reference of the
            predicted pin's deflection; None: from the record's problem file
            (:func:`plate_surface`).
        basis: The plan's model, task and window: each program format's file (a controller
            cycle, :attr:`~rfsw_plan.export.format.ControllerFormat.cycle`) is judged as its
            controller runs it (:func:`~rfsw_plan.export.check.judge_program`, what
            ``rfsw-plan check`` does). A program that breaks the weld envelope, a hook's
            rule, or the plan's GO (it holds less than the requested uncertainty) is refused;
            one that holds less than the plan's level, which already was below the request,
            is written with that level in its header (:attr:`ExportResult.held_as_run`).
            None (a plan without its problem, in tests): not judged.

    Raises:
        InfeasibleError: A program that does not reproduce the plan or is refused as run.
    """
    problem = str(record.get("problem", "plan"))
    spacing = plan_spacing(record) if spacing is None else spacing
    if not spacing > 0:
        raise InputError("export_spacing", "", f"got {spacing * 1e3:g}", "> 0")
    if depth is None or reference is None:
        n2, d2, r2, _ = plate_surface(str(record.get("problem_file") or ""), samples)
        normal = n2 if normal is None else normal
        depth = d2 if depth is None else depth
        reference = r2 if reference is None else reference
    model = ElastostaticModel(robot)
    ref: Any = reference
    deflection = np.asarray(model.process_deflection(samples.q, samples.wrench, ref))
    pin = sample_fk(robot, samples.q)[:, :3, 3] + deflection[:, :3]
    header = _program_header(robot, record, problem, plan_sha256, path_tol, spacing, depth)
    with Stages("export", ("points", "programs written and judged")) as stages:
        programs = ProgramsPerCycle(lambda c: build_program(
            robot, samples, header, path_tol, normal=normal, payload=model.tool_payload(),
            options=options, stream=stream, cycle=cycle, depth=depth, pin=pin, min_move=c))
        lead = next((n for n in fmts if get_format(n).cycle > 0), fmts[0])
        program = programs[lead]  # here, before the formats' jobs fork: theirs if they share it
        try:
            stage = Path(tempfile.mkdtemp(prefix="rfsw-plan-export-"))
        except OSError as exc:  # a full or read-only temporary directory: one line, exit 2
            raise OutputPathError("TMPDIR", tempfile.gettempdir(),
                                  f"cannot stage the programs ({exc.strerror}); set TMPDIR to "
                                  "a writable folder") from None
        try:
            stages.start("programs written and judged")
            staged, trips, held, deviation = _write_all(programs, fmts, stage, check, basis,
                                                        path_tol)
            out.mkdir(parents=True, exist_ok=True)
            for old in out.glob(".export-*"):  # staging folders of versions that staged there
                shutil.rmtree(old, ignore_errors=True)
            for f in staged:
                _refuse_collision(out / f.name, problem)
            final = [write_bytes(out / f.name, f.read_bytes()) for f in staged]
        finally:
            shutil.rmtree(stage, ignore_errors=True)
    checked = "" if check is None else f"passed: {getattr(check, '__doc__', '') or 'check'}"
    rows = {name: len(trip.q) for name, trip in trips.items()}
    return ExportResult(tuple(final), trips, len(program.sample_index), rows, program.header,
                        checked.strip(), deviation, program.header.notes,
                        len(trips[lead].q), held, program.header.tolerated_uncertainty)


def _path_deviation(name: str, fmt: ControllerFormat, program: Program, path_tol: float
                    ) -> float:
    """The largest bound of a verified sample's distance to the path the format's controller
    runs, its rounding at the points [m].

    Raises:
        InfeasibleError: The path leaves a sample by more than ``path_tol``.
    """
    dev = fmt.path_deviation(program)
    k = int(np.argmax(dev))
    if dev[k] > path_tol * (1 + 1e-9):
        raise InfeasibleError(
            f"{name}: programmed path leaves verified sample {k} by "
            f"{dev[k] * 1e3:.4f} mm (tolerance {path_tol * 1e3:g} mm)", None,
            "path_tolerance", path_tol - float(dev[k]))
    return float(dev[k])


class ProgramsPerCycle:
    """Per format, its program: ``build(cycle)`` once per interpolation cycle
    (:attr:`ControllerFormat.cycle`) in a process, on first use, so no move or wait of a
    format's file is shorter than its controller's cycle and a file does not depend on the
    other formats written. ``programs[name]`` is the program of format ``name``."""

    def __init__(self, build: Callable[[float], Program]) -> None:
        self._build = build
        self._built: dict[float, Program] = {}

    def __getitem__(self, name: str) -> Program:
        c = get_format(name).cycle
        if c not in self._built:
            self._built[c] = self._build(c)
        return self._built[c]


def _refuse_collision(path: Path, problem: str) -> None:
    """A program file of another problem under the same name is never replaced: the names of
    two problems can meet after a vendor's length limit (one-line error, exit 2)."""
    if not path.is_file():
        return
    try:
        with path.open(encoding="utf-8", errors="replace") as fh:
            head = [line for _, line in zip(range(60), fh, strict=False)]
    except OSError:
        return
    for line in head:
        text = line.split("problem: ", 1)
        if len(text) == 2 and "rfsw-plan" not in text[0]:
            other = text[1].strip().rstrip(";").strip()
            if other and other != problem:
                raise InputError(path, "", f"holds the program of problem {other!r}, not "
                                 f"{problem!r}", "another output folder (-o) for this problem")
            return


def _write_all(programs: ProgramsPerCycle, fmts: Sequence[str], stage: Path,
               check: SampleCheck | None, basis: PlanBasis | None, path_tol: float
               ) -> tuple[list[Path], dict[str, RoundTrip], dict[str, tuple[float, str]], float]:
    """Per format: build its program (unless this process has, ``programs``), bound its path
    deviation (:func:`_path_deviation`), write it into ``stage``, re-read it, take it through
    the model and (with ``basis``) judge it as its controller runs it.

    The formats are independent: they are shared with forked processes on the machine's cores
    (:func:`rfsw_plan.parallel.fork_map`, the shortest controller cycle first), the same
    computations wherever they run, so the same files. A failure is raised as the serial
    order raises it: the first format in the order of ``fmts`` that fails, its path first.
    Then each claim is settled in the order of ``fmts``.

    Returns:
        The staged files, the round trips and the levels held as run by format name, and the
        largest path deviation [m].
    """
    from rfsw_plan.parallel import fork_map

    judged = {n for n in fmts if basis is not None
              and (get_format(n).cycle > 0 or get_format(n).runs_rows)}
    if judged:
        assert basis is not None
        basis.surface()  # computed once, before the workers inherit the memo

    def job(i: int) -> tuple[float, list[Path], ReadProgram, RoundTrip, CheckResult | None,
                             ProgramHeader]:
        name = fmts[i]
        fmt, program = get_format(name), programs[name]
        dev = _path_deviation(name, fmt, program, path_tol)
        files, read, trip = _write_read(fmt, program, stage, check)
        if name not in judged:
            return dev, files, read, trip, None, program.header
        assert basis is not None
        return dev, files, read, trip, judge_program(files[0], stage, read,
                                                     replace(basis, work=program.work),
                                                     solved=(fmt.expected(program).q, trip.q)
                                                     ), program.header

    # The shortest controller cycle first (the stream's rows, then the TP's 8 ms): the most
    # points or rows, the longest jobs.
    done = fork_map(job, len(fmts), order=sorted(range(len(fmts)),
                                                 key=lambda i: get_format(fmts[i]).cycle))
    written = {name: d[1:4] for name, d in zip(fmts, done, strict=True)}
    held: dict[str, tuple[float, str]] = {}
    for name, (*_, res, header) in zip(fmts, done, strict=True):
        if res is None:
            continue
        fmt = get_format(name)
        held[name], restated = _settled(name, fmt, header, res)
        if restated is not None:  # the same moves, the header states the level as run
            written[name] = _write_read(fmt, replace(programs[name], header=restated), stage,
                                        check)
    staged = [f for name in fmts for f in written[name][0]]
    return staged, {name: written[name][2] for name in fmts}, held, max(d[0] for d in done)


def _write_read(fmt: ControllerFormat, program: Program, stage: Path,
                check: SampleCheck | None) -> tuple[list[Path], ReadProgram, RoundTrip]:
    """Write one format's program into ``stage``, re-read it and take it through the
    model: its points reproduce the verified samples and (``check``) pass the sample check."""
    files = fmt.write(program, stage)
    expected = fmt.expected(program)
    read = fmt.read(files[0])
    trip = round_trip(program.robot, fmt, read, expected)
    if not trip.ok:
        raise InfeasibleError(f"{fmt.name} program does not reproduce the verified plan: "
                              f"{trip.summary()}", None, "round_trip", None)
    if check is not None:
        check(replace(expected, q=trip.q))
    return files, read, trip


def _settled(name: str, fmt: ControllerFormat, header: ProgramHeader, res: CheckResult
             ) -> tuple[tuple[float, str], ProgramHeader | None]:
    """The force uncertainty a staged program (its ``header``) holds as its controller runs it
    (``res``, its judgement), and the header to write it again with, stating that level (None:
    it holds the plan's, or it has no header: the stream's level is recorded in
    ``plan.json``).

    Raises:
        InfeasibleError: The program as run breaks the weld envelope, a hook's rule or the
            timing; or the plan holds the requested uncertainty (GO) and the program does not.
    """
    if not res.holds and res.failure != "claim":
        raise InfeasibleError(f"{name} program as its controller runs it: {res.line()}", None,
                              res.failure, None)
    u, by = res.held
    if res.failure != "claim":
        return res.held, None
    requested = header.requested_uncertainty
    how = ("its rows as the real-time interface sends them, one per cycle" if fmt.runs_rows
           else f"{1e3 * fmt.cycle:g} ms interpolation cycle")
    cause = (f"{name} program as its controller runs it ({how}) holds +-{100 * u:.2f} % force "
             f"uncertainty ({by} first), below the plan's "
             f"+-{100 * header.tolerated_uncertainty:.2f} %")
    if header.tolerated_uncertainty >= requested and u < requested * (1.0 - CLAIM_TOL):
        raise InfeasibleError(f"{cause} and the requested +-{100 * requested:.3g} % the plan "
                              "holds (GO): write a format of a shorter cycle or the stream, or "
                              f"plan for at most +-{100 * u:.2f} % force uncertainty", None,
                              "claim", u - requested)
    if fmt.runs_rows:  # no header to state it in: plan.json's export.held_as_run records it
        return res.held, None
    return res.held, replace(header, tolerated_uncertainty=u,
                             plan_tolerated=header.tolerated_uncertainty, held_by=by)


def export_plan_folder(
    folder: str | Path, fmts: Sequence[str], out: Path | None = None, *,
    spacing: float | None = None, path_tol: float = 1e-5,
    options: ProgramOptions | None = None,
) -> ExportResult:
    """Programs of a written plan folder (read by the strict reader), and their record.

    Into the plan folder itself (``out`` None or the folder), ``plan.json`` is rewritten to
    vouch for the programs: first without any earlier programs, then, after the new files
    have their names, with them, so a kill at any moment leaves a record that vouches for a
    whole set. Into another folder, ``export.json`` is written last and vouches for them.

    Raises:
        InputError: A damaged plan folder (one line), bad options.
        InfeasibleError: A plan that is not verified, or a program that does not reproduce it.
    """
    from rfsw_plan.files import write_json
    from rfsw_plan.planfiles.folder import PlanFolder

    folder = Path(folder)
    plan, robot = PlanFolder.open_with_robot(folder)
    normal, depth, reference, why = plate_surface(plan.problem_file, plan.samples)
    target = folder if out is None else Path(out)
    inside = target.resolve() == folder.resolve()
    record = plan.record
    if inside:  # the plan alone stays vouched for while the programs are replaced
        exp = record.get("export")
        old = set(exp.get("files", [])) if isinstance(exp, dict) else set()
        record = record.without("export").with_keys(sha256={
            k: v for k, v in record.sha256.items() if k not in {Path(f).name for f in old}})
        plan.write_record(record)
    rebuilt = plan.rebuild()
    basis = PlanBasis(plan.samples, plan.record, plan.problem_file, ElastostaticModel(robot),
                      rebuilt.task(), rebuilt.problem.window)
    res = export_programs(robot, plan.samples, plan.record, fmts, target,
                          plan_sha256=plan.waypoints_sha256, spacing=spacing,
                          path_tol=path_tol, options=options, normal=normal, depth=depth,
                          reference=reference, basis=basis)
    if why:
        res = replace(res, notes=(*res.notes, f"plate normal not known: {why}"))
    plan_ref = "." if inside else os.path.relpath(folder.resolve(), target.resolve())
    summary = {"status": "exported", "plan": plan_ref, **res.to_dict()}
    if inside:
        plan.write_record(record.with_keys(export=summary).with_keys(sha256={
            **record.sha256, **{f.name: sha256_file(f) for f in res.files}}))
    else:
        summary["sha256"] = {f.name: sha256_file(f) for f in res.files}
        write_json(target / "export.json", summary)
    return res


def _pct(u: float) -> float | None:
    """A relative level as percent for JSON (None: unbounded)."""
    return 100.0 * u if math.isfinite(u) else None


def _number(v: Any) -> float:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else 0.0


def _robot_file(robot: Robot) -> tuple[str, str]:
    """File name and hex SHA-256 of the robot's description file, ("", "") without one."""
    path = robot.description.path
    if path is None or not Path(path).is_file():
        return "", ""
    return Path(path).name, sha256_file(path)


def _window(record: Mapping[str, Any]) -> tuple[float, float]:
    w = record.get("window_mm")
    if not isinstance(w, list) or len(w) != 2:
        return float("nan"), float("nan")
    return _number(w[0]), _number(w[1])


def format_help() -> str:
    """``--format`` help text from the registry."""
    return ", ".join(f"{n} ({c.description})" for n, c in formats().items())
