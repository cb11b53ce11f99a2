"""Re-verify a controller program, as written or as a programmer touched it up, against its plan.

:func:`check_program` reads a KRL, TP or RAPID file with its own format's reader, recovers the
joint values of every point on the posture the file states, and runs the planner's
sample-by-sample verification (:func:`rfsw_plan.planning.verify.verify_samples`: the weld
window and every other envelope row it holds under the plan's elastostatic model and process
forces, the joint limits) on the path the controller will run:

* **Plan.** The program's header names its plan (``plan id: <problem>-<12 hex of the SHA-256
  of waypoints.csv>``); a program of another plan is refused as such (exit 3), even when its
  points are the same. A program edited inside its plan folder (the touch-up workflow) is
  not refused for differing from the bytes ``plan.json`` vouches for: the result says it was
  edited and re-verifies it.
* **Points to samples.** Each program point is matched, in order, to the plan sample at its
  position (samples within 3 um of the nearest, the pin at rest or a base re-taught to the
  pendant's precision, are told apart by the
  program's own clock). Deleted or added motions need no special case: the remaining points
  are matched where they are.
* **Path.** Between two program points the controller runs the straight line (LIN, L,
  MoveL): every plan sample between them is moved onto that chord, at its own fraction along
  the plan's chord between the two matched samples, plus the edit of the two points
  interpolated (rotation as a rotation vector). An unedited program gives back the verified
  samples within the path tolerance it was exported with; a point moved 2 mm gives a 2 mm
  tent; 30 deleted arc points give the chord that cuts inside the arc.
* **Posture.** A point whose stated posture (KUKA S/T, FANUC CONFIG with turn numbers, ABB
  confdata) has no joint solution, or whose joint values differ from the plan sample's by a
  turn or a branch (more than :data:`POSTURE_TOL` on an axis), fails with the point, the line
  and the axis.
* **Timing.** Each segment is re-timed as the program runs it: its programmed speed (or
  motion time, or wait) over its programmed length; a segment whose time differs from the
  plan's by more than :data:`TIMING_TOL` fails with the point, the line, the programmed and
  planned times, and the re-timed samples are verified (the envelope's speed rows see it).
  A move or wait shorter than the controller's interpolation cycle
  (:attr:`~rfsw_plan.export.format.ControllerFormat.cycle`) fails too: the controller
  cannot run it as written.
* **Stream.** A stream file (``_stream.csv``, :attr:`ControllerFormat.runs_rows
  <rfsw_plan.export.format.ControllerFormat.runs_rows>`) is its run: each row is the joint
  target of one controller cycle at the stream clock ``t_s``, under the process state the
  plan has at the row's planned time ``t_plan_s`` (:func:`run_stream`); its
  ``spindle_on`` column's switches are judged as the spindle hooks, where the pin is; the
  joint velocity, acceleration and jerk and the pin's speed are reported (nothing between
  the rows enforces them). A stream holds the level ``plan.json`` records for it
  (``export.held_as_run``), else the plan's.
* **Checks.** Every failure :func:`~rfsw_plan.planning.verify.verify_samples` returns, except
  the joint velocity, acceleration and jerk (the controller's own motion planner enforces
  them on the path it runs; a stream's rows report them).

Result: ``holds``, or the first failure with the point, its line in the file and the
quantity (exit 3 in the CLI); every failure is in :meth:`CheckResult.to_dict`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.export.format import ControllerFormat, ReadPoint, ReadProgram, format_for_file
from rfsw_plan.export.program import Samples, sample_fk
from rfsw_plan.export.stream import StreamRows, read_stream
from rfsw_plan.robot.kinematics import Robot
from rfsw_plan.robot.rotation import Rotation

FloatArray = NDArray[np.float64]
#: Joint values of a program's points solved from known seeds: (seeds, joint values) [rad],
#: each (P, n), in the order of the program's points (:func:`judge_program`).
Solved = tuple[FloatArray, FloatArray]

#: Failures of verify_samples not reported: the joint derivative limits (the controller's
#: motion planner enforces them) and the pin's travel speed on the re-timed samples. The
#: re-timing runs each segment at its programmed speed, a step at every point that the
#: controller blends; the speed a controller keeps is checked per segment instead (each
#: segment's programmed time within TIMING_TOL of the verified plan's, so the pin's speed over
#: it is within TIMING_TOL of a speed the plan verified).
NOT_REPORTED = ("joint_velocity", "joint_acceleration", "joint_jerk", "pin_speed")
#: Largest relative difference of a segment's programmed time from the plan's.
TIMING_TOL = 0.02
#: A stream's clock steps and planned times are compared within this [s] (the file writes
#: times to 1 us).
CLOCK_TOL = 1.5e-6
#: A stream row's stated process state is the plan's within this: arc length [m], force
#: [N], moment [N m] (linear interpolation between 10 ms samples is off by up to 3.2 N on
#: kr600_forming_contour's steepest ramp and 0.1 um in arc length).
STATE_TOL = (1e-5, 10.0, 10.0, 10.0, 2.0, 2.0, 2.0)
#: Largest difference of a point's joint value from its plan sample's [rad] (a turn or branch
#: change is 2 pi or a large angle; an edit of millimetres moves the joints by far less).
POSTURE_TOL = math.radians(5.0)
#: Program points are told apart from plan samples at the same place below this [m] (the pin
#: at rest; a base re-taught to the pendant's precision moves every point by about 1 um).
TIE = 3e-6
#: Newton steps of the batched inverse kinematics from the planned joints.
NEWTON_STEPS = 4
#: A point moved farther than this from its plan sample is listed as an edit [m] (the round
#: trip's tolerance).
EDIT_TOL = 1e-5
#: A work object turned by more than this against the exported one is listed as an edit
#: [deg] (a base re-taught on the plate by the 3-point method: about 1e-4 deg).
BASE_ANGLE_TOL = 1e-3
#: The order in which failures are named: the physical quantities of the weld first, then
#: the hooks, the postures, the timing and any other check.
ORDER = ("depth", "lateral", "clearance", "tilt", "speed", "hook", "posture", "timing")
#: A move or wait is said to be shorter than the controller's interpolation cycle below this
#: share of it under the cycle (the files round lengths to 0.1 um and speeds to 0.1 um/s).
CYCLE_TOL = 1e-3
#: A hook's rule holds within this [m] (a few plan samples at the plunge speed).
HOOK_TOL = 1e-4
#: The program as run is said to hold less force uncertainty than the plan claims when its
#: level is below the claimed one by more than this share of it (the claims are bisected and
#: rounded to 0.01 %; the same samples give the same level).
CLAIM_TOL = 0.01


@dataclass(frozen=True)
class CheckResult:
    """Outcome of :func:`check_program`.

    Attributes:
        program: The program file.
        plan: The plan folder.
        holds: Every check holds at every sample, the timing and the postures too.
        n_points: Program points read.
        n_samples: Samples checked.
        max_edit: Largest displacement of a program point from its plan sample [m].
        point: The named point of the first failure (``XP23``, ``P[23]``, ``p23``), or "".
        phase: Its phase.
        s: Its arc length along the seam [m].
        lateral_error: Predicted lateral pin error there [m].
        window: The weld window (lower, upper) [m].
        failure: The failing check (``window``, ``joint_limit_q2``, ``timing``,
            ``posture``, ``plan_id``, ``claim``: the program as run holds less force uncertainty
            than the plan claims...), or "".
        value: Its value and bound (file units, e.g. mm or deg), and the unit.
        min_margin: Smallest window margin over the in-material samples [m].
        line_no: The failing point's motion line in the program file (1-based; 0: none).
        file: The file of that line.
        failures: Every failure, one line each.
        edited: The program's files that differ from the bytes ``plan.json`` vouches for.
        detail: The failure's text when it is not a window or a bound.
        edits: Every edit found against the plan, one line each: a point moved by more than
            :data:`EDIT_TOL` (name, line, mm), points deleted or added against the export
            (the count ``plan.json`` recorded), listed even when the program holds.
        quantity: The physical quantity of the first failure (``depth``, ``lateral``,
            ``clearance``, ``tilt``, ``speed``, ``hook``), or the check's name.
        held: The largest uniform relative force uncertainty every weld quantity holds at
            with the program as run (:func:`~rfsw_plan.planning.verify.robust_claim` on the
            run's samples), and the quantity that limits it first; (NaN, "") if not computed.
        claimed: The level the program claims: the plan's verdict's (``plan.json``
            ``tolerated_force_uncertainty``), or the lower level the program's header states
            (the export writes it where the program as run holds less than the plan); NaN if
            neither names one.
        plan_claimed: The plan's verdict's level, NaN if it names none.
        stated_by: Who states :attr:`claimed` where it is below the plan's: the program's
            header, or for a file without one (the stream) ``plan.json``'s record of it.
    """

    program: Path
    plan: Path
    holds: bool
    n_points: int
    n_samples: int
    max_edit: float
    point: str = ""
    phase: str = ""
    s: float = 0.0
    lateral_error: float = 0.0
    window: tuple[float, float] = (0.0, 0.0)
    failure: str = ""
    value: tuple[float, float, str] = (0.0, 0.0, "")
    min_margin: float = math.inf
    line_no: int = 0
    file: str = ""
    failures: tuple[str, ...] = ()
    edited: tuple[str, ...] = ()
    detail: str = ""
    edits: tuple[str, ...] = ()
    quantity: str = ""
    held: tuple[float, str] = (math.nan, "")
    claimed: float = math.nan
    plan_claimed: float = math.nan
    stated_by: str = "this program states"

    @property
    def below_claim(self) -> bool:
        """The program as run holds less force uncertainty than it claims
        (:data:`CLAIM_TOL`)."""
        return bool(self.held[0] < self.claimed * (1.0 - CLAIM_TOL))

    @property
    def states_less(self) -> bool:
        """The program's header states a lower level than the plan's (the export found it
        as run)."""
        return bool(self.claimed < self.plan_claimed * (1.0 - CLAIM_TOL))

    def claim_text(self) -> str:
        """``; as run it holds +-3.66 % force uncertainty (speed first), below the plan's
        +-4.55 %`` where :attr:`below_claim`; ``; as run it holds +-2.73 % (speed first),
        the level this program states (the plan's +-2.83 %)`` where the program states less
        than its plan; else ""."""
        whose = (f"the +-{100 * self.claimed:.3g} % {self.stated_by}"
                 if self.states_less else f"the plan's +-{100 * self.claimed:.2f} %")
        if self.below_claim:
            return (f"; as run it holds +-{100 * self.held[0]:.2f} % force uncertainty "
                    f"({self.held[1]} first), below {whose}")
        if self.states_less:
            return (f"; as run it holds +-{100 * self.held[0]:.2f} % force uncertainty "
                    f"({self.held[1]} first), the level {self.stated_by} (the plan's "
                    f"+-{100 * self.plan_claimed:.2f} %)")
        return ""

    def line(self) -> str:
        """One line for the terminal."""
        edited = (f"; edited against the export: {', '.join(self.edited)}"
                  if self.edited else "")
        if self.edits:
            edited += f"; edits: {'; '.join(self.edits[:3])}" + (
                f" (+{len(self.edits) - 3} more)" if len(self.edits) > 3 else "")
        if self.holds:
            return (f"{self.program.name}: holds ({self.n_points} points, {self.n_samples} "
                    f"samples; smallest window margin {self.min_margin * 1e3:.3f} mm; largest "
                    f"edit {self.max_edit * 1e3:.3f} mm{edited}){self.claim_text()}")
        more = (f" (+{len(self.failures) - 1} more failure"
                f"{'s' if len(self.failures) > 2 else ''})" if len(self.failures) > 1 else "")
        where = f"line {self.line_no}" + (f" of {self.file}" if self.file and
                                           self.file != self.program.name else "")
        if self.point == f"row {self.line_no}":  # a stream's row is its line
            where = ""
        at = (f"{self.program.name}: {self.point} ({self.phase}, s = {self.s * 1e3:.1f} mm"
              f"{', ' + where if where else ''})") if self.point else f"{self.program.name}:"
        lo, hi = (w * 1e3 for w in self.window)
        if self.failure == "window":
            return (f"{at} leaves the weld window: lateral error "
                    f"{self.lateral_error * 1e3:+.3f} mm, window {lo:+.3f} .. {hi:+.3f} mm"
                    f"{more}")
        if self.detail:
            return f"{at} {self.detail}{more}"
        v, b, unit = self.value
        return f"{at}: {self.failure} {v:.3f} {unit} beyond {b:.3f} {unit}{more}"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (file units)."""
        return {"program": str(self.program), "plan": str(self.plan), "holds": self.holds,
                "points": self.n_points, "samples": self.n_samples,
                "max_edit_mm": self.max_edit * 1e3, "point": self.point, "phase": self.phase,
                "s_mm": self.s * 1e3, "lateral_error_mm": self.lateral_error * 1e3,
                "window_mm": [w * 1e3 for w in self.window], "failure": self.failure,
                "min_margin_mm": self.min_margin * 1e3, "line_no": self.line_no,
                "file": self.file, "failures": list(self.failures),
                "edited": [*(f"{f}: changed since the export" for f in self.edited),
                           *self.edits],
                "edited_files": list(self.edited), "quantity": self.quantity,
                "held_pct": _pct(self.held[0]), "held_limited_by": self.held[1],
                "claimed_pct": _pct(self.claimed), "below_claim": self.below_claim,
                "plan_claimed_pct": _pct(self.plan_claimed),
                "line": self.line()}


def _pct(u: float) -> float | None:
    """A relative level as percent for JSON (None: not computed or not claimed)."""
    return None if not math.isfinite(u) else 100.0 * u


@dataclass(frozen=True)
class _Finding:
    """A failure found before or beside verify_samples: a point, what, and the text."""

    point: int
    check: str
    detail: str


def check_program(program: str | Path, plan_dir: str | Path | None = None) -> CheckResult:
    """Re-verify a program file against its plan (module docstring).

    Args:
        program: A ``.src`` (with its ``.dat``), ``.ls`` or ``.mod`` file.
        plan_dir: The plan folder (default: the program's folder).

    Raises:
        InputError: An unreadable program or plan folder, or a plan whose model cannot be
            rebuilt (one line).
    """
    from rfsw_plan.planfiles.folder import PlanFolder, touched_programs

    path = Path(program)
    if not path.is_file():
        raise InputError(path, "", "not a file", "a program written by rfsw-plan export")
    folder = Path(plan_dir) if plan_dir is not None else path.parent
    fmt = format_for_file(path)
    try:
        read = fmt.read(path)
    except InputError:
        # an infeasible or damaged plan is named first; the program's own files (edited on
        # the pendant, or broken) are the reader's to name
        siblings = tuple(path.parent.glob(f"{path.stem}.*"))
        with touched_programs(_own_files(folder, siblings)):
            PlanFolder.open_with_robot(folder)
        raise
    own = _own_files(folder, read.files)
    with touched_programs(own):
        return _check(path, folder, read, own)


def _check(path: Path, folder: Path, read: ReadProgram, own: dict[str, bool]) -> CheckResult:
    from rfsw_plan.planfiles.folder import PlanFolder
    from rfsw_plan.planning.verify import verify_samples

    plan, robot = PlanFolder.open_with_robot(folder)  # own files: touched_programs
    edited = tuple(sorted(n for n, changed in own.items() if changed))
    plan_id = f"{plan.record.get('problem', '')}-{plan.waypoints_sha256[:12]}"
    stated = _stated(path).get("plan id")
    if stated is not None and stated != plan_id:
        return CheckResult(path, folder, False, len(read.points), 0, 0.0, failure="plan_id",
                           detail=f"is a program of plan {stated}, not of this plan "
                                  f"{plan_id} ({folder}): check it against its own plan",
                           failures=(f"plan id {stated} != {plan_id}",), edited=edited)
    model, task, window = _plan_model(plan, robot)
    base = verify_samples(model, task, window, plan.samples, robust=False)
    if _reported(base):
        raise InputError(folder, "", "the plan's own samples do not verify with the model "
                         "rebuilt from its files (robot or problem file changed?)",
                         "the robot and problem files the plan was made with")
    basis = PlanBasis(plan.samples, plan.record, plan.problem_file, model, task, window)
    basis = replace(basis, work=_exported_work(basis, robot))
    return judge_program(path, folder, read, basis, edited)


@dataclass(frozen=True)
class PlanBasis:
    """What a program is judged against (:func:`judge_program`).

    Attributes:
        samples: The plan's verified samples (``waypoints.csv``).
        record: The plan's record (``plan.json``; while ``plan --export`` writes the
            programs, the summary it is about to commit).
        problem_file: The plan's problem file (the plate surface for the hooks).
        model: The plan's elastostatic model.
        task: The plan's task (seam frames, seam reference).
        window: The weld window.
        work: The work object the plan's programs are exported with, controller base frame,
            (4, 4) [m] (None: not known; a program's base is then taken as exported).
    """

    samples: Samples
    record: Any
    problem_file: str
    model: Any
    task: Any
    window: Any
    work: FloatArray | None = None
    #: What every program of the plan is judged with that depends on the plan alone (its
    #: plate surface, the predicted pin's spindle clearance), computed once for all the
    #: programs judged against this basis and its copies (:func:`dataclasses.replace` keeps
    #: it): ``export`` judges one program per format against the same plan.
    memo: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    def surface(self) -> tuple[FloatArray | None, float, str, str]:
        """:func:`~rfsw_plan.export.api.plate_surface` of the plan's problem and samples."""
        if "surface" not in self.memo:
            from rfsw_plan.export.api import plate_surface

            self.memo["surface"] = plate_surface(self.problem_file, self.samples)
        out: tuple[FloatArray | None, float, str, str] = self.memo["surface"]
        return out


def judge_program(path: Path, folder: Path, read: ReadProgram, basis: PlanBasis,
                  edited: tuple[str, ...] = (), solved: Solved | None = None) -> CheckResult:
    """Judge a program file as its controller runs it against its plan (module docstring):
    the weld envelope at every sample of the run, the hooks where the predicted pin is, the
    postures and the timing, and the force uncertainty the run holds against the level the
    program states in its header (the plan's, unless the export wrote the lower level this
    program holds as run).

    Args:
        path: The program file (its format from the suffix).
        folder: The plan folder (named in the result).
        read: The program as its format's reader reads it.
        basis: The plan it was exported from.
        edited: The program's files changed since the plan vouched for them.
        solved: The joint values of the program's points already solved from known seeds
            (the export's round trip of the same re-read program,
            :func:`~rfsw_plan.export.readback.round_trip`): a point seeded by the same joint
            values takes them instead of solving again (:func:`run_as_controller`).
    """
    from rfsw_plan.planning.verify import verify_samples

    fmt = format_for_file(path)
    robot, plan = basis.model.robot, basis
    model, task, window = basis.model, basis.task, basis.window
    if fmt.runs_rows:  # the rows are the run (a stream): no path, posture or base between
        rows = read_stream(path)
        run = run_stream(robot, rows, plan.samples, task)
        lines = {n: (path.name, k + 2) for k, n in enumerate(run.names)}
        hooks = _stream_hooks(rows)
    else:
        run = run_as_controller(robot, fmt, read, plan.samples, basis.work, solved)
        lines = _motion_lines(read.files, run.names)
        hooks = _hook_positions(read.files)
    ver = verify_samples(model, task, window, run.samples)
    held = ((ver.claim.tolerated, ver.claim.limiting.quantity) if ver.claim is not None
            else (math.nan, ""))
    plan_claim = plan.record.get("tolerated_force_uncertainty")
    plan_claimed = float(plan_claim) if isinstance(plan_claim, (int, float)) else math.nan
    claimed = (_recorded_claim(plan.record, fmt.name, plan_claimed) if fmt.runs_rows
               else _stated_claim(path, plan_claimed))
    res = CheckResult(path, folder, True, len(run.names), len(run.samples), run.max_edit,
                      window=(window.lower, window.upper), min_margin=ver.min_margin,
                      edited=edited, edits=_edits(run, lines, plan.record, fmt.name),
                      held=held, claimed=claimed,
                      plan_claimed=plan_claimed,
                      stated_by=("plan.json records for this stream" if fmt.runs_rows
                                 else "this program states"))
    # (point, check, text, sample, failure, quantity)
    texts: list[tuple[int, str, str, int, Any, str]] = []
    for f in [*run.findings, *_hook_findings(hooks, run, model, basis),
              *_below_cycle(read, fmt.cycle)]:
        texts.append((f.point, f.check, f.detail, int(run.idx[f.point]), None,
                      "hook" if f.check.startswith("hook") else f.check))
    for f in _reported(ver, fmt.runs_rows):
        k = _named_point(f.index, run.idx, ver.e_lat, window, run.edits) \
            if f.check == "window" else _nearest_point(f.index, run.idx)
        texts.append((k, f.check, f"{f.check} {f.value:.3f} {f.unit} beyond {f.bound:.3f} "
                      f"{f.unit}", f.index, f, f.quantity))
    if not texts:
        if res.below_claim:  # the envelope holds nominally, not at the plan's claim
            return replace(res, holds=False, failure="claim", quantity=held[1],
                           detail=f"holds the weld envelope nominally, but {res.claim_text()[2:]}"
                                  f": the controller does not run what was verified",
                           failures=(res.claim_text()[2:],))
        return res
    # the weld's physical quantities first (depth, lateral, clearance...), then by sample
    texts.sort(key=lambda x: (ORDER.index(x[5]) if x[5] in ORDER else len(ORDER), x[3], x[0]))
    k, check, text, sample, f, quantity = texts[0]
    file, line_no = lines.get(run.names[k], ("", 0))
    every = tuple(f"{run.names[p]} ({lines.get(run.names[p], ('', 0))[0]}:"
                  f"{lines.get(run.names[p], ('', 0))[1]}): {t}" for p, _, t, _, _, _ in texts)
    if check == "window":  # the worst sample beside the named point (a tent, a chord)
        lo_i, hi_i = int(run.idx[max(k - 1, 0)]), int(run.idx[min(k + 1, len(run.idx) - 1)])
        span = ver.e_lat[lo_i:hi_i + 1]
        out_of = np.maximum(window.lower - span, span - window.upper)
        e = float(span[int(np.nanargmax(out_of))]) if span.size else float(ver.e_lat[sample])
    else:
        e = float(ver.e_lat[sample])
    return replace(res, holds=False, point=run.names[k], phase=str(run.samples.phase[run.idx[k]]),
                   s=float(run.samples.s[run.idx[k]]), lateral_error=e, failure=check,
                   value=(f.value, f.bound, f.unit) if f is not None else (0.0, 0.0, ""),
                   line_no=line_no, file=file, failures=every, quantity=quantity,
                   detail="" if f is not None else text)


def _own_files(folder: Path, files: tuple[Path, ...]) -> dict[str, bool]:
    """The program's files that lie in the plan folder and are vouched for by its plan.json,
    each with whether its bytes changed since (the touch-up workflow edits them there)."""
    from rfsw_plan.files import sha256_file
    from rfsw_plan.planfiles.record import PlanRecord

    try:
        digests = PlanRecord.read(folder / "plan.json").get("sha256") or {}
    except InputError:
        return {}
    out = {}
    for f in files:
        if f.resolve().parent == folder.resolve() and f.name in digests:
            out[f.name] = sha256_file(f) != digests[f.name]
    return out


def _stated(path: Path) -> dict[str, str]:
    """The ``plan id`` and the ``verified tolerated force uncertainty`` (``+-2.83`` or
    ``unbounded``) the program's header states; a key is missing where it states none. The
    header's comment lines are read as one text (a TP comment wraps a line over several)."""
    import re

    text = format_for_file(path).header_text(path)
    out: dict[str, str] = {}
    for key, value in (("plan id", r"[\w.-]+"),
                       ("verified tolerated force uncertainty", r"\+-[0-9.]+|unbounded")):
        m = re.search(rf"{key}:\s*({value})", text)
        if m is not None:
            out[key] = m.group(1)
    return out


def _stated_claim(path: Path, plan_claimed: float) -> float:
    """The force uncertainty the program states it holds: the plan's level (exact) where its
    header states the plan's (as the export writes it to 3 digits), else the level it states
    (the lower one the export found as run, or a programmer's edit), else the plan's."""
    text = _stated(path).get("verified tolerated force uncertainty", "")
    if not text.startswith("+-"):
        return plan_claimed
    try:
        stated = float(text[2:]) / 100.0
    except ValueError:
        return plan_claimed
    if math.isfinite(plan_claimed) and f"{100 * plan_claimed:.3g}" == text[2:]:
        return plan_claimed
    return stated


def _recorded_claim(record: Any, fmt: str, plan_claimed: float) -> float:
    """The force uncertainty a file without a header (the stream) is vouched for: the level
    ``plan.json`` records for its format as run (``export.held_as_run``, where the export
    found it below the plan's), else the plan's."""
    exp = record.get("export") if hasattr(record, "get") else None
    held = (exp.get("held_as_run") or {}).get(fmt) if isinstance(exp, dict) else None
    pct = held.get("tolerated_pct") if isinstance(held, dict) else None
    return float(pct) / 100.0 if isinstance(pct, (int, float)) else plan_claimed


def _motion_lines(files: tuple[Path, ...], names: list[str]) -> dict[str, tuple[str, int]]:
    """Point name -> (file name, 1-based line) of the motion that moves to it (a TP line as
    the pendant numbers it: the ``/MN`` line number, not the file's)."""
    import re

    want = {x.upper(): x for x in reversed(names)}  # the first name of each spelling
    out: dict[str, tuple[str, int]] = {}
    move = re.compile(r"^\s*(?:\d+:)?\s*(?:LIN|PTP|CIRC|[JLC]\s|Move\w*)\s*(\w+(?:\[\d+\])?)")
    for f in files:
        if f.suffix.lower() == ".dat":
            continue
        for n, line in enumerate(f.read_text(encoding="utf-8", errors="replace").splitlines(),
                                 start=1):
            m = move.match(line)
            if m is None:
                continue
            if (tp := re.match(r"^\s*(\d+):", line)) is not None:
                n = int(tp.group(1))  # a TP line as the pendant numbers it (/MN)
            name = m.group(1)
            if name.upper() in want and name not in out:
                out.setdefault(want[name.upper()], (f.name, n))
            elif line.strip().startswith("MoveAbsJ"):
                out.setdefault("jStart", (f.name, n))
    return out


def _edits(run: ControllerRun, lines: dict[str, tuple[str, int]], record: Any,
           fmt: str) -> tuple[str, ...]:
    """Every edit against the plan, one line each: points moved by more than
    :data:`EDIT_TOL` (the first 20 named) and the points deleted or added against the count
    the export recorded in ``plan.json``."""
    out = _base_edit(run)
    moved = [k for k in range(len(run.names)) if run.edits[k] > EDIT_TOL]
    for k in moved[:20]:
        f, n = lines.get(run.names[k], ("", 0))
        out.append(f"{run.names[k]} ({f}:{n}) moved {run.edits[k] * 1e3:.3f} mm")
    if len(moved) > 20:
        out.append(f"+{len(moved) - 20} more points moved")
    exp = record.get("export") if hasattr(record, "get") else None
    wrote = (exp.get("points_per_format") or {}).get(fmt) if isinstance(exp, dict) else None
    if isinstance(wrote, int) and wrote != len(run.names):
        d = wrote - len(run.names)
        out.append(f"{abs(d)} point{'s' if abs(d) > 1 else ''} "
                   f"{'deleted' if d > 0 else 'added'} ({len(run.names)} of the {wrote} "
                   "exported)")
    return tuple(out)


def _exported_work(plan: PlanBasis, robot: Robot) -> FloatArray:
    """The work object the plan's programs were exported with (controller base frame, (4, 4)
    [m]): the plate frame on the surface at the first weld sample
    (:func:`rfsw_plan.export.program.work_frame`, from the plan's problem file)."""
    from rfsw_plan.export.program import work_frame

    normal, depth, _, _ = plan.surface()
    T = sample_fk(robot, plan.samples.q)
    return work_frame(plan.samples, T, robot.description.convention.base, normal, depth)[0]


def _base_edit(run: ControllerRun) -> list[str]:
    """The base edit as one line, in the exported base's axes (mm, deg), when the
    program's base differs from the exported one by more than :data:`EDIT_TOL` or
    :data:`BASE_ANGLE_TOL`."""
    D = run.base_edit
    if D is None:
        return []
    shift = D[:3, 3]
    angle = float(np.degrees(Rotation.from_matrix(D[:3, :3]).magnitude()))
    if float(np.linalg.norm(shift)) <= EDIT_TOL and angle <= BASE_ANGLE_TOL:
        return []
    x, y, z = (float(v) * 1e3 for v in shift)
    return [f"base moved x {x:+.3f} y {y:+.3f} z {z:+.3f} mm, turned {angle:.4f} deg against "
            "the exported one: every Cartesian point moves with it"]


def _hook_positions(files: tuple[Path, ...]) -> dict[str, int]:
    """Hook name -> index of the program point moved to before it (the writers mark every
    hook with a ``hook <name>`` comment line), in the order the reader follows the files."""
    import re

    move = re.compile(r"^\s*(?:\d+:)?\s*(?:LIN|PTP|CIRC|[JLC]\s|Move\w*)\s*(\w+(?:\[\d+\])?)")
    mark = re.compile(r"^\s*(?:\d+:)?\s*[;!]\s*hook (\w+)\s*;?\s*$")
    out: dict[str, int] = {}
    k = -1
    for f in files:
        if f.suffix.lower() == ".dat":
            continue
        for line in f.read_text(encoding="utf-8", errors="replace").splitlines():
            if move.match(line):
                k += 1
            elif (m := mark.match(line)) is not None and k >= 0:
                out.setdefault(m.group(1), k)
    return out


def _stream_hooks(rows: StreamRows) -> dict[str, int]:
    """Hook name -> row of a stream where its ``spindle_on`` column switches the spindle:
    ``spindle_start`` at the first row on after a row off, ``spindle_stop`` at the first row
    off after a row on (the spindle runs as the row states from that row on)."""
    if rows.spindle_on is None:
        return {}
    on = rows.spindle_on.astype(int)
    step = np.diff(on)
    out: dict[str, int] = {}
    for hook, k in (("spindle_start", np.flatnonzero(step > 0)),
                    ("spindle_stop", np.flatnonzero(step < 0))):
        if k.size:
            out[hook] = int(k[0]) + 1
    return out


def _hook_findings(pos: dict[str, int], run: ControllerRun, model: Any,
                   plan: PlanBasis) -> list[_Finding]:
    """Hooks placed (``pos``: hook name -> the program point or stream row it fires at)
    where the predicted pin (the controller's run, deflected by the process wrench) breaks
    their rule: the spindle starts with the tip above the surface and stops with it clear by
    the spindle clearance; force control goes on at or below the surface and off with the
    pin still in (:func:`rfsw_plan.export.program.pin_heights`)."""
    from rfsw_plan.export.program import pin_heights, spindle_clearance

    normal, depth, ref, _ = plan.surface()
    if not pos or normal is None:
        return []

    def heights(samples: Samples) -> FloatArray:
        pin = (sample_fk(model.robot, samples.q)[:, :3, 3]
               + model.process_deflection(samples.q, samples.wrench, ref)[:, :3])
        return pin_heights(samples, pin, normal, depth)

    h_run = heights(run.samples)
    if plan.memo.get("clearance_model") is not model:  # the plan's, once per model
        plan.memo["clearance"] = spindle_clearance(plan.samples, heights(plan.samples))
        plan.memo["clearance_model"] = model
    clear = float(plan.memo["clearance"])
    rules = {"spindle_start": (lambda h: h > 0.0, "the spindle starts with the pin tip "
                               "{h} from the surface (it must be above it)"),
             "spindle_stop": (lambda h: h >= clear - HOOK_TOL, "the spindle stops with the "
                              "pin tip {h} from the surface (it must be clear by the spindle "
                              f"clearance, {clear * 1e3:.2f} mm)"),
             "force_on": (lambda h: h <= HOOK_TOL, "force control goes on with the pin tip "
                          "{h} from the surface (on at contact)"),
             "force_off": (lambda h: h < 0.0, "force control goes off with the pin tip {h} "
                           "from the surface (off before the pin leaves)")}
    out = []
    for hook, k in sorted(pos.items(), key=lambda kv: kv[1]):
        if hook in rules and k < len(run.idx):
            h = float(h_run[run.idx[k]])
            ok, text = rules[hook]
            if not ok(h):
                out.append(_Finding(k, f"hook_{hook}", "hook: " + text.format(
                    h=f"{h * 1e3:+.2f} mm")))
    return out


def _reported(ver: Any, rows: bool = False) -> list[Any]:
    """The failures ``check`` reports: all of them where the rows are the run (a stream:
    no motion planner of the controller's stands between them and the joints), else all but
    :data:`NOT_REPORTED`."""
    return [f for f in ver.failures if rows or not f.check.startswith(NOT_REPORTED)]


def _nearest_point(sample: int, idx: NDArray[np.int_]) -> int:
    return int(np.argmin(np.abs(idx - sample)))


def _named_point(sample: int, idx: NDArray[np.int_], e: FloatArray, window: Any,
                 edits: FloatArray | None = None) -> int:
    """The program point to name for a failing sample: of the points around it (all points
    on the same samples included: an added point), the most edited one if it was moved by
    more than 0.1 mm, else the one farther outside the window."""
    k = int(np.clip(np.searchsorted(idx, sample), 0, len(idx) - 1))
    lo = int(idx[max(k - 1, 0)])
    hi = int(idx[k])
    cands = [c for c in range(len(idx)) if lo <= idx[c] <= hi] or [k]
    if edits is not None:
        c = max(cands, key=lambda c: float(edits[c]))
        if edits[c] > 1e-4:
            return c

    def outside(c: int) -> float:
        x = float(e[idx[c]])
        return max(window.lower - x, x - window.upper)

    return max(cands, key=outside)


def _plan_model(plan: Any, robot: Robot) -> tuple[Any, Any, Any]:
    """The plan's elastostatic model, task and window, rebuilt from its robot and problem
    files (with the fitted forces of ``plan --forces``)."""
    from rfsw_plan.elastostatics.model import ElastostaticModel

    rebuilt = plan.rebuild()
    return ElastostaticModel(robot), rebuilt.task(), rebuilt.problem.window


@dataclass(frozen=True)
class ControllerRun:
    """What :func:`run_as_controller` finds.

    Attributes:
        samples: The re-timed samples on the path the controller runs, with joint values.
        names: The program points' names, in order.
        idx: The plan sample index of each point.
        max_edit: Largest position edit of a point [m].
        findings: Posture and timing failures, by point.
        edits: Position edit of every point [m].
        base_edit: The program's work object in the exported one's frame, (4, 4) [m]
            (identity: the base as exported; None: the exported one not known).
    """

    samples: Samples
    names: list[str]
    idx: NDArray[np.int_]
    max_edit: float
    findings: tuple[_Finding, ...]
    edits: FloatArray = field(default_factory=lambda: np.zeros(0))
    base_edit: FloatArray | None = None


def run_as_controller(robot: Robot, fmt: ControllerFormat, read: ReadProgram,
                      plan: Samples, work: FloatArray | None = None,
                      solved: Solved | None = None) -> ControllerRun:
    """The samples the controller runs for a (possibly edited) program (module docstring).

    ``work`` is the work object (base) the plan's programs were exported with, controller base
    frame [m], (4, 4). Where the program's own differs (a base re-taught elsewhere), its
    Cartesian points are matched to the plan's samples by what the program says (the points
    in the exported base), and run where the program's base puts them. ``solved``: joint
    values of the points already solved (:func:`judge_program`)."""
    conv = robot.description.convention
    to_model = np.linalg.inv(read.tool) @ np.linalg.inv(conv.flange) @ robot.description.tool
    T_plan = sample_fk(robot, plan.q)
    pts = read.points
    poses, names, q_pts, findings = _point_poses(robot, fmt, read, pts, to_model, T_plan, plan,
                                                 solved)
    seg_t = _segment_times(read, poses)
    shift = np.eye(4) if work is None else \
        conv.base @ work @ np.linalg.inv(read.work) @ np.linalg.inv(conv.base)
    as_written = poses.copy()
    cart = np.array([p.pose is not None for p in pts], dtype=bool)
    as_written[cart] = shift[None] @ poses[cart]
    idx = _match(as_written, T_plan, plan.t, seg_t)
    findings += _posture_changes(q_pts, plan.q[idx], names, robot)
    findings += _timing_changes(seg_t, plan.t[idx], names)
    dp = poses[:, :3, 3] - T_plan[idx, :3, 3]
    dr = (Rotation.from_matrix(poses[:, :3, :3])
          * Rotation.from_matrix(T_plan[idx, :3, :3]).inv()).as_rotvec()
    t = _retime(seg_t, idx, plan.t)
    target = T_plan.copy()
    n = len(plan)
    spans: list[NDArray[np.int_]] = []
    rots: list[FloatArray] = []
    for k in range(len(idx) - 1):
        i, j = int(idx[k]), int(idx[k + 1])
        if j <= i:
            continue
        a, b = T_plan[i, :3, 3], T_plan[j, :3, 3]
        d = b - a
        L2 = float(d @ d)
        m = np.arange(i, j + 1)
        f = np.clip(((T_plan[m, :3, 3] - a) @ d) / L2, 0.0, 1.0) if L2 > 1e-18 else \
            (plan.t[m] - plan.t[i]) / max(plan.t[j] - plan.t[i], 1e-12)
        # the chord between the two (edited) points, at the sample's fraction along it
        target[m, :3, 3] = (poses[k, :3, 3][None] + f[:, None]
                            * (poses[k + 1, :3, 3] - poses[k, :3, 3])[None])
        spans.append(m)
        rots.append((1 - f)[:, None] * dr[k] + f[:, None] * dr[k + 1])
    if spans:  # the edits' rotations of every segment in one call (each row its own)
        turn = Rotation.from_rotvec(np.concatenate(rots)).as_matrix()
        at = np.cumsum([0, *(len(m) for m in spans)])
        for m, lo, hi in zip(spans, at[:-1], at[1:], strict=True):  # in order: the later
            target[m, :3, :3] = turn[lo:hi] @ T_plan[m, :3, :3]  # segment's end sample wins
    last = int(idx[-1])
    if last < n - 1:
        target[last + 1:, :3, 3] += dp[-1]
    first = int(idx[0])
    if first > 0:
        target[:first, :3, 3] += dp[0]
    q = _batch_ik(robot, target, plan.q)
    out = Samples(t, plan.phase, plan.s, q, plan.wrench, plan.seam)
    edits = np.linalg.norm(as_written[:, :3, 3] - T_plan[idx, :3, 3], axis=1)
    return ControllerRun(out, names, idx, float(np.max(edits)), tuple(findings), edits,
                         None if work is None else np.linalg.inv(work) @ read.work)


def run_stream(robot: Robot, rows: StreamRows, plan: Samples, task: Any) -> ControllerRun:
    """The samples a real-time interface runs for a stream file: its rows themselves, one
    per controller cycle at the stream clock ``t_s`` (KUKA RSI and ABB EGM send each row as
    the joint target of its cycle; no path, posture or base stands between), each under the
    process state its row states (arc length and wrench: the plan's at the row's planned
    time ``t_plan_s``), its seam point from the task at that arc length (as the stream was
    written, :func:`rfsw_plan.planning.verify.seam_frames_at`).

    The stated state is first held against the plan's: ``waypoints.csv`` interpolated
    linearly in its time at ``t_plan_s`` (the stream and the plan share the planned clock)
    must agree within :data:`STATE_TOL` (the interpolation's own error between 10 ms
    samples). The linear interpolation is not the judgement's state: its time derivatives
    are steps at every 10 ms sample, and judged under it fanuc_butt_1700mm's stream held
    2.71 % instead of 2.80 % (speed first). A stream without the state columns (written
    before them) is judged under the interpolated state.

    Findings: a row whose clock step is not the stream's cycle (the first step), a planned
    time outside the plan's, a phase that lasts longer or shorter on the stream clock than
    in the plan by more than :data:`TIMING_TOL` (at least one cycle: each piece is
    stretched by less than one cycle to a whole number of cycles), a stated state off the
    plan's, and a row off its plan pose by a turn or a branch. ``edits`` is each row's
    commanded TCP distance from the plan's at the same planned time (the plan's joint values
    interpolated likewise)."""
    from rfsw_plan.planning.verify import seam_frames_at

    n = len(rows.t)
    names = [rows.name(k) for k in range(n)]
    t_plan = np.asarray(plan.t, dtype=float)
    at = rows.t_plan

    def interp(a: FloatArray) -> FloatArray:
        return np.stack([np.interp(at, t_plan, a[:, i]) for i in range(a.shape[1])], axis=1)

    q_plan = interp(plan.q)
    planned = interp(np.column_stack([plan.s, plan.wrench]))
    findings = _stream_timing(rows, t_plan)
    state = planned
    if rows.state is not None:
        R = robot.description.convention.base[:3, :3]  # the base frame's wrench to the model's
        state = np.column_stack([rows.state[:, 0], rows.state[:, 1:4] @ R.T,
                                 rows.state[:, 4:] @ R.T])
        findings += _state_changes(state, planned)
    s = state[:, 0]
    samples = Samples(rows.t, rows.phase, s, rows.q, state[:, 1:], seam_frames_at(task, s)[0],
                      spindle_rpm=rows.spindle_rpm, spindle_on=rows.spindle_on)
    findings += _posture_changes(rows.q, q_plan, names, robot)
    edits = np.linalg.norm(sample_fk(robot, rows.q)[:, :3, 3]
                           - sample_fk(robot, q_plan)[:, :3, 3], axis=1)
    return ControllerRun(samples, names, np.arange(n), float(np.max(edits, initial=0.0)),
                         tuple(findings), edits, None)


#: The stream's process state columns as ``check`` names them: (name, unit, file scale).
_STATE_NAMES = (("s", "mm", 1e3), ("fx", "N", 1.0), ("fy", "N", 1.0), ("fz", "N", 1.0),
                ("mx", "N m", 1.0), ("my", "N m", 1.0), ("mz", "N m", 1.0))


def _state_changes(state: FloatArray, planned: FloatArray) -> list[_Finding]:
    """The first row whose stated process state (arc length [m], wrench [N, N m], (R, 7),
    the model's base frame) leaves the plan's (``planned``) by more than
    :data:`STATE_TOL`."""
    off = np.abs(state - planned) > np.asarray(STATE_TOL)[None]
    bad = np.flatnonzero(off.any(axis=1))
    if not bad.size:
        return []
    k = int(bad[0])
    j = int(np.flatnonzero(off[k])[0])
    name, unit, scale = _STATE_NAMES[j]
    return [_Finding(k, "forces", f"forces: the row states {name} {state[k, j] * scale:.3f} "
                     f"{unit} where the plan has {planned[k, j] * scale:.3f} {unit} at its "
                     f"planned time (tolerance {STATE_TOL[j] * scale:g} {unit}; model base "
                     "frame): edited, or another plan's")]


def _stream_timing(rows: StreamRows, t_plan: FloatArray) -> list[_Finding]:
    """The stream's timing findings (:func:`run_stream`)."""
    out: list[_Finding] = []
    if len(rows.t) < 2:
        return out
    step = np.diff(rows.t)
    cycle = float(step[0])
    off = np.flatnonzero(np.abs(step - cycle) > CLOCK_TOL)
    if cycle <= 0 or off.size:
        k = int(off[0]) + 1 if off.size else 1
        out.append(_Finding(k, "timing", f"timing: the row comes {step[k - 1] * 1e3:.3f} ms "
                            f"after the previous one, the stream's cycle is {cycle * 1e3:.3f} "
                            "ms (one row per cycle)"))
        return out
    late = np.flatnonzero((rows.t_plan < t_plan[0] - CLOCK_TOL)
                          | (rows.t_plan > t_plan[-1] + CLOCK_TOL) | (np.diff(
                              rows.t_plan, prepend=-np.inf) < 0))
    if late.size:
        k = int(late[0])
        out.append(_Finding(k, "timing", f"timing: its planned time {rows.t_plan[k]:.6f} s is "
                            f"not after the previous row's or outside the plan's "
                            f"{t_plan[0]:.3f} .. {t_plan[-1]:.3f} s"))
    cuts = np.flatnonzero(rows.phase[1:] != rows.phase[:-1]) + 1
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(rows.t)], strict=True):
        # from the piece's first row to the next piece's first (the last row: the piece's end)
        end = min(int(b), len(rows.t) - 1)
        runs, want = rows.t[end] - rows.t[a], rows.t_plan[end] - rows.t_plan[a]
        if abs(runs - want) > max(TIMING_TOL * want, cycle + CLOCK_TOL):
            out.append(_Finding(int(a), "timing", f"timing: the {rows.phase[a]} lasts "
                                f"{runs:.3f} s on the stream's clock, the plan {want:.3f} s "
                                f"(tolerance {100 * TIMING_TOL:g} %, at least one cycle): the "
                                f"speed is {want / runs if runs > 0 else math.inf:.2f} x the "
                                "plan's"))
    return out


def _point_poses(robot: Robot, fmt: ControllerFormat, read: ReadProgram, pts: list[ReadPoint],
                 to_model: FloatArray, T_plan: FloatArray, plan: Samples,
                 solved: Solved | None = None,
                 ) -> tuple[FloatArray, list[str], FloatArray, list[_Finding]]:
    """Model TCP poses (base frame) and joint values of the program's points: joint targets
    by FK, Cartesian points on their stated posture (IK seeded by the nearest plan sample); a
    stated posture without a joint solution is a finding (its point keeps the nearest
    sample's joints; the seeded solutions' postures in one pass:
    :func:`~rfsw_plan.export.config.seeded_on_branch`). ``solved`` (seeds, joint values):
    a point whose seed is the same takes the joint values solved from it (the same target,
    seed and search give the same solution; the round trip of an export found it)."""
    from rfsw_plan.export.config import ik_on_branch, seeded_on_branch

    conv = robot.description.convention
    poses = np.empty((len(pts), 4, 4))
    qs = np.empty((len(pts), robot.nq))
    findings: list[_Finding] = []
    targets: dict[int, FloatArray] = {}
    nearest: dict[int, int] = {}
    for k, p in enumerate(pts):
        if p.q is None:
            assert p.pose is not None
            targets[k] = conv.base @ read.work @ p.pose @ to_model
    cart = list(targets)
    index = _SampleIndex(T_plan[:, :3, 3])
    prev = 0
    for k in cart:
        nearest[k] = prev = index.nearest(targets[k][:3, 3], prev)
    known: dict[int, FloatArray] = {}
    if solved is not None and len(solved[0]) == len(pts):
        known = {k: solved[1][k] for k in cart
                 if np.array_equal(solved[0][k], plan.q[nearest[k]])}
    todo = [k for k in cart if k not in known]
    first: dict[int, FloatArray | None] = dict(known)
    first.update(zip(todo, seeded_on_branch(
        robot, np.array([targets[k] for k in todo]), [pts[k].config for k in todo],
        fmt.postures, plan.q[[nearest[k] for k in todo]]), strict=True))
    for k, p in enumerate(pts):
        if p.q is not None:
            qs[k] = p.q
            poses[k] = robot.fk(p.q)
            continue
        near = nearest[k]
        q = first[k]
        if q is None:  # at a boundary, on another branch, or none: the search
            try:
                q = ik_on_branch(robot, targets[k], lambda x, p=p: fmt.matches(robot, p, x),
                                 plan.q[near])
            except InputError:
                findings.append(_Finding(k, "posture", f"states the posture {p.config}, "
                                         "which has no joint solution at this pose (the "
                                         "plan's is "
                                         f"{fmt.posture(robot, plan.q[near])})"))
                q = plan.q[near]
        qs[k] = q
        poses[k] = robot.fk(qs[k])
    return poses, [p.name for p in pts], qs, findings


def _posture_changes(q: FloatArray, q_plan: FloatArray, names: list[str],
                     robot: Robot) -> list[_Finding]:
    """Points whose joint values leave their plan sample's by a turn or a branch."""
    axes = robot.description.convention.axes
    out = []
    diff = np.asarray(q) - np.asarray(q_plan)
    worst = np.argmax(np.abs(diff), axis=1)
    far = np.abs(diff[np.arange(len(diff)), worst]) > POSTURE_TOL
    for k in np.flatnonzero(far).tolist():  # a stream has tens of thousands of rows
        j = int(worst[k])
        out.append(_Finding(k, "posture", f"posture changed: {axes[j]} "
                            f"{math.degrees(q[k, j]):+.1f} deg where the plan has "
                            f"{math.degrees(q_plan[k, j]):+.1f} deg "
                            f"({math.degrees(diff[k, j]):+.1f} deg: a turn or a branch)"))
    return out


def _below_cycle(read: ReadProgram, cycle: float) -> list[_Finding]:
    """Moves and waits shorter than the controller's interpolation cycle ``cycle`` [s]: the
    controller cannot run them as written (it slows down or stops), so the timing checked is
    not the timing run. A move's time is its programmed duration, or the length between its
    Cartesian points (the program's own coordinates) over its programmed speed."""
    out: list[_Finding] = []
    if cycle <= 0:
        return out
    prev: ReadPoint | None = None
    k = -1
    for m in read.motions:
        if m.kind == "wait":
            if 0 < m.duration < cycle * (1.0 - CYCLE_TOL) and k >= 0:
                out.append(_Finding(k, "timing", f"timing: the wait after it lasts "
                                    f"{m.duration * 1e3:.1f} ms, below the controller's "
                                    f"{cycle * 1e3:g} ms interpolation cycle: it cannot run "
                                    "as written"))
            continue
        k += 1
        t = m.duration
        if t <= 0 and m.speed > 0 and prev is not None and m.pose is not None \
                and prev.pose is not None:
            t = float(np.linalg.norm(m.pose[:3, 3] - prev.pose[:3, 3])) / m.speed
        if prev is not None and 0 < t < cycle * (1.0 - CYCLE_TOL):
            out.append(_Finding(k, "timing", f"timing: the move to it takes {t * 1e3:.1f} ms, "
                                f"below the controller's {cycle * 1e3:g} ms interpolation "
                                "cycle: it cannot run as written"))
        prev = m
    return out


def _timing_changes(seg_t: FloatArray, t_plan: FloatArray, names: list[str]) -> list[_Finding]:
    """Segments whose programmed time differs from the plan's by more than TIMING_TOL."""
    out = []
    plan_dt = np.diff(t_plan)
    for k in range(1, len(seg_t)):
        want = float(plan_dt[k - 1])
        if want <= 0 or seg_t[k] <= 0:
            continue
        rel = seg_t[k] / want - 1.0
        if abs(rel) > TIMING_TOL:
            out.append(_Finding(k, "timing", f"timing: the move to it takes {seg_t[k]:.3f} s, "
                                f"the plan {want:.3f} s ({100 * rel:+.1f} %, tolerance "
                                f"{100 * TIMING_TOL:g} %): the speed is {1 / (1 + rel):.2f} x "
                                "the plan's"))
    return out


def _segment_times(read: ReadProgram, poses: FloatArray) -> FloatArray:
    """Programmed time from each point to the next one's arrival [s], (len(poses),): waits
    after the previous point plus the move (motion time, or length over speed, the length
    between the points' TCP ``poses`` [m]); 0 for the first point and for a move without a
    stated speed or time."""
    out = np.zeros(len(poses))
    pending, k = 0.0, -1
    for m in read.motions:
        if m.kind == "wait":
            pending += m.duration
            continue
        k += 1
        if k > 0:
            length = float(np.linalg.norm(poses[k, :3, 3] - poses[k - 1, :3, 3]))
            move = m.duration if m.duration > 0 else (length / m.speed if m.speed > 0 else 0.0)
            out[k] = pending + move if move > 0 else 0.0
        pending = 0.0
    return out


def _match(poses: FloatArray, T_plan: FloatArray, t_plan: FloatArray,
           seg_t: FloatArray) -> NDArray[np.int_]:
    """Plan sample index of each program point, in order, never before the previous point's:
    the sample at its position; samples within :data:`TIE` of the nearest (at rest) are told
    apart by the previous point's time plus the programmed segment time."""
    idx = np.zeros(len(poses), dtype=int)
    start = 0
    index = _SampleIndex(T_plan[:, :3, 3])
    for k in range(len(poses)):
        near = index.within_tie(poses[k, :3, 3], start, TIE)  # sample indices, ascending
        if k == 0 or seg_t[k] <= 0:
            j = int(near[0])
        else:
            expect = t_plan[idx[k - 1]] + seg_t[k]
            j = int(near[np.argmin(np.abs(t_plan[near] - expect))])
        idx[k] = start = j
    return idx


class _SampleIndex:
    """Exact nearest-sample queries on the plan's sample positions (N, 3) [m], the same
    answers as ``np.linalg.norm(p - q, axis=1)`` over every sample (the same distances, the
    first index among equal ones) without computing them all: a sample nearer to q than a
    known distance d lies in the slab |p_a - q_a| <= d on the axis a of the samples' largest
    extent, found by bisection in the samples sorted along it."""

    def __init__(self, p: FloatArray) -> None:
        p = np.asarray(p, dtype=float)
        self._xyz = tuple(np.ascontiguousarray(p[:, i]) for i in range(3))
        self._axis = int(np.argmax(np.ptp(p, axis=0))) if len(p) else 0
        self._order = np.argsort(p[:, self._axis], kind="stable")
        self._sorted = p[self._order, self._axis]

    def _dist(self, idx: NDArray[np.int_], q: FloatArray) -> FloatArray:
        x, y, z = (c[idx] for c in self._xyz)
        dx, dy, dz = x - q[0], y - q[1], z - q[2]
        # np.linalg.norm's own sum, in its order: (dx^2 + dy^2) + dz^2, then the square root
        return np.asarray(np.sqrt(dx * dx + dy * dy + dz * dz))

    def _slab(self, q: FloatArray, radius: float, start: int) -> NDArray[np.int_]:
        """Every sample index >= start within ``radius`` of q along the axis (a superset of
        those within ``radius`` of q), ascending."""
        r = radius * (1.0 + 1e-12) + 1e-15  # the rounding of the distances
        a = np.searchsorted(self._sorted, q[self._axis] - r, side="left")
        b = np.searchsorted(self._sorted, q[self._axis] + r, side="right")
        idx = np.sort(self._order[a:b])
        return idx[idx >= start]

    def nearest(self, q: FloatArray, guess: int) -> int:
        """The index of the sample nearest to q (the first of equal ones); ``guess`` is any
        sample index, a near one prunes most."""
        d0 = float(self._dist(np.array([guess]), q)[0])
        cand = self._slab(q, d0, 0)
        return int(cand[np.argmin(self._dist(cand, q))])

    def within_tie(self, q: FloatArray, start: int, tie: float) -> NDArray[np.int_]:
        """The sample indices >= start whose distance to q is within ``tie`` of the nearest
        one's among them, ascending."""
        d0 = float(self._dist(np.array([start]), q)[0])
        cand = self._slab(q, d0 + tie, start)
        d = self._dist(cand, q)
        return cand[d <= d.min() + tie]


def _retime(seg_t: FloatArray, idx: NDArray[np.int_], t_plan: FloatArray) -> FloatArray:
    """Sample times as the program runs: each segment's plan time scaled to its programmed
    time. Samples after the last point keep their plan spacing."""
    out = np.array(t_plan, dtype=float)
    for k in range(len(idx) - 1):
        i, j = int(idx[k]), int(idx[k + 1])
        dt_plan = t_plan[j] - t_plan[i]
        scale = seg_t[k + 1] / dt_plan if dt_plan > 0 and seg_t[k + 1] > 0 else 1.0
        out[i + 1:j + 1] = out[i] + (t_plan[i + 1:j + 1] - t_plan[i]) * scale
    last = int(idx[-1])
    out[last + 1:] = t_plan[last + 1:] + (out[last] - t_plan[last])
    return out


def _batch_ik(robot: Robot, target: FloatArray, q0: FloatArray) -> FloatArray:
    """Joint values reaching ``target`` (m, 4, 4) from ``q0`` (m, n): damped Newton steps on
    all samples at once (the targets are within millimetres of the planned poses). The first
    step's kinematics at ``q0`` (the plan's joint values, the same for every program of the
    plan: :func:`_newton_start`) is computed once."""
    q = np.array(q0, dtype=float)
    goal = Rotation.from_matrix(target[:, :3, :3])  # the same every step
    for step in range(NEWTON_STEPS):
        if step == 0:
            T, J, inv, JJt = _newton_start(robot, q)
        else:
            T, J = robot.batch_fk_jacobian(q)
            inv = Rotation.from_matrix(T[:, :3, :3]).inv()
            JJt = J @ np.swapaxes(J, 1, 2) + 1e-12 * np.eye(6)
        err = np.concatenate([target[:, :3, 3] - T[:, :3, 3], (goal * inv).as_rotvec()],
                             axis=1)
        q += np.einsum("kji,kj->ki", J, np.linalg.solve(JJt, err[:, :, None])[:, :, 0])
    return q


_START: list[tuple[Robot, FloatArray, tuple[FloatArray, FloatArray, Rotation, FloatArray]]] = []


def _newton_start(robot: Robot, q: FloatArray
                  ) -> tuple[FloatArray, FloatArray, Rotation, FloatArray]:
    """Poses (m, 4, 4), Jacobians (m, 6, n), inverse rotations and damped J J^T (m, 6, 6) at
    joint values q [rad], (m, n): :func:`_batch_ik`'s first step, remembered for the last
    two joint arrays of equal values (``export`` judges every format's program from the
    same plan samples)."""
    for r, q_k, out in _START:
        if r is robot and q_k.shape == q.shape and np.array_equal(q_k, q):
            return out
    T, J = robot.batch_fk_jacobian(q)
    out = (T, J, Rotation.from_matrix(T[:, :3, :3]).inv(),
           J @ np.swapaxes(J, 1, 2) + 1e-12 * np.eye(6))
    for a in (T, J, out[3]):
        a.setflags(write=False)
    _START[:] = [*_START[-1:], (robot, q.copy(), out)]
    return out
