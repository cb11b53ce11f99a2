"""Re-verify a controller program, as written or as a programmer touched it up, against its plan.

:func:`check_program` reads a KRL, TP or RAPID file with its own format's reader, recovers the
joint values of every point on the posture the file states, and runs the planner's
sample-by-sample verification (:func:`rfsw_plan.planning.verify.verify_samples`: the weld
window under the plan's elastostatic model and process forces, the joint limits) on the path
the controller will run:

* **Path.** At export every verified sample was shown to lie within the path tolerance of the
  programmed path (:func:`rfsw_plan.export.program.path_deviation`). A program whose point k
  now differs from the plan sample it was written from by ``D_k`` (position, and rotation
  vector) is therefore modelled as the verified samples displaced by the edit, interpolated
  linearly in time between neighbouring points: sample m between points k and k + 1 gets
  ``(1 - f) D_k + f D_{k+1}``, ``f`` its time fraction. An unedited program gives back the
  verified samples (to the file's rounding); a point moved 2 mm gives a 2 mm tent around it.
* **Timing.** Each segment is re-timed as the program runs it: its programmed speed (or
  motion time, or wait) over its programmed length, so a touched-up speed shows.
* **Points to samples.** Each program point is matched, in order, to the plan sample nearest
  in position and in the program's own cumulative time.
* **Checks.** The weld window at every in-material sample and the joint limits at every
  sample. The derivative limits are the controller's own business (its motion planner enforces
  them) and are not reported here.

Result: ``holds``, or the first point that leaves the window with its lateral error and the
window (exit 3 in the CLI).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from rfsw_plan.exceptions import InputError
from rfsw_plan.export.format import ControllerFormat, ReadPoint, ReadProgram, format_for_file
from rfsw_plan.export.program import Samples
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: Checks reported by :func:`check_program` (prefixes of :class:`SampleFailure` checks).
REPORTED = ("window", "joint_limit")
#: Program points are matched to plan samples within this much programmed time [s].
MATCH_WINDOW = 1.0
#: Newton steps of the batched inverse kinematics from the planned joints.
NEWTON_STEPS = 4


@dataclass(frozen=True)
class CheckResult:
    """Outcome of :func:`check_program`.

    Attributes:
        program: The program file.
        plan: The plan folder.
        holds: Every sample stays in the weld window and the joint limits.
        n_points: Program points read.
        n_samples: Samples checked.
        max_edit: Largest displacement of a program point from its plan sample [m].
        point: The named point of the first failure (``XP23``, ``P[23]``, ``p23``), or "".
        phase: Its phase.
        s: Its arc length along the seam [m].
        lateral_error: Predicted lateral pin error there [m].
        window: The weld window (lower, upper) [m].
        failure: The failing check (``window``, ``joint_limit_q2``...), or "".
        value: Its value and bound (file units, e.g. mm or deg), and the unit.
        min_margin: Smallest window margin over the in-material samples [m].
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

    def line(self) -> str:
        """One line for the terminal."""
        if self.holds:
            return (f"{self.program.name}: holds ({self.n_points} points, {self.n_samples} "
                    f"samples; smallest window margin {self.min_margin * 1e3:.3f} mm; largest "
                    f"edit {self.max_edit * 1e3:.3f} mm)")
        lo, hi = (w * 1e3 for w in self.window)
        if self.failure == "window":
            return (f"{self.program.name}: {self.point} ({self.phase}, s = {self.s * 1e3:.1f} "
                    f"mm) leaves the weld window: lateral error {self.lateral_error * 1e3:+.3f} "
                    f"mm, window {lo:+.3f} .. {hi:+.3f} mm")
        v, b, unit = self.value
        return (f"{self.program.name}: {self.point} ({self.phase}, s = {self.s * 1e3:.1f} mm): "
                f"{self.failure} {v:.3f} {unit} beyond {b:.3f} {unit}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (file units)."""
        return {"program": str(self.program), "plan": str(self.plan), "holds": self.holds,
                "points": self.n_points, "samples": self.n_samples,
                "max_edit_mm": self.max_edit * 1e3, "point": self.point, "phase": self.phase,
                "s_mm": self.s * 1e3, "lateral_error_mm": self.lateral_error * 1e3,
                "window_mm": [w * 1e3 for w in self.window], "failure": self.failure,
                "min_margin_mm": self.min_margin * 1e3, "line": self.line()}


def check_program(program: str | Path, plan_dir: str | Path | None = None) -> CheckResult:
    """Re-verify a program file against its plan (module docstring).

    Args:
        program: A ``.src`` (with its ``.dat``), ``.ls`` or ``.mod`` file.
        plan_dir: The plan folder (default: the program's folder).

    Raises:
        InputError: An unreadable program or plan folder, a point without a joint solution in
            its posture, or a plan whose model cannot be rebuilt (one line).
    """
    from rfsw_plan.planfiles.folder import read_plan_folder_and_robot
    from rfsw_plan.planning.verify import verify_samples

    path = Path(program)
    if not path.is_file():
        raise InputError(path, "", "not a file", "a program written by rfsw-plan export")
    fmt = format_for_file(path)
    folder = Path(plan_dir) if plan_dir is not None else path.parent
    plan, robot = read_plan_folder_and_robot(folder)
    read = fmt.read(path)
    model, task, window = _plan_model(plan, robot)
    base = verify_samples(model, task, window, plan.samples)
    if _reported(base) is not None:
        raise InputError(folder, "", "the plan's own samples do not verify with the model "
                         "rebuilt from its files (robot or problem file changed?)",
                         "the robot and problem files the plan was made with")
    samples, names, idx, edit = run_as_controller(robot, fmt, read, plan.samples)
    ver = verify_samples(model, task, window, samples)
    res = CheckResult(path, folder, True, len(names), len(samples), edit,
                      window=(window.lower, window.upper), min_margin=ver.min_margin)
    f = _reported(ver)
    if f is None:
        return res
    k = _named_point(f.index, idx, ver.e_lat, window)
    e = float(ver.e_lat[idx[k]]) if f.check == "window" else float(ver.e_lat[f.index])
    return replace(res, holds=False, point=names[k], phase=str(samples.phase[idx[k]]),
                   s=float(samples.s[idx[k]]), lateral_error=e, failure=f.check,
                   value=(f.value, f.bound, f.unit))


def _reported(ver: Any) -> Any:
    return next((f for f in ver.failures if f.check.startswith(REPORTED)), None)


def _named_point(sample: int, idx: NDArray[np.int_], e: FloatArray, window: Any) -> int:
    """The program point to name for a failing sample: of the two points around it, the one
    farther outside the window (the edited one)."""
    k = int(np.clip(np.searchsorted(idx, sample), 0, len(idx) - 1))
    cands = [c for c in (k - 1, k) if 0 <= c < len(idx)]

    def outside(c: int) -> float:
        x = float(e[idx[c]])
        return max(window.lower - x, x - window.upper)

    return max(cands, key=outside)


def _plan_model(plan: Any, robot: Robot) -> tuple[Any, Any, Any]:
    """The plan's elastostatic model, task and window, rebuilt from its robot and problem
    files (with the fitted forces of ``plan --forces``)."""
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.export.api import plan_spacing
    from rfsw_plan.process.task import task_from_schedule
    from rfsw_plan.validation.plan_record import read_plan_dir

    pr = read_plan_dir(plan.folder)
    pb = pr.problem
    frames = pb.seam.frames(plan_spacing(plan.record))
    sched = pb.process.schedule(frames, 0.05, approach=False)
    n_start = plan.record.get("n_start_waypoints")
    task = task_from_schedule(frames, sched, int(n_start) if isinstance(n_start, int) else 12,
                              pb.seam_reference)
    return ElastostaticModel(robot), task, pb.window


def run_as_controller(robot: Robot, fmt: ControllerFormat, read: ReadProgram,
                      plan: Samples) -> tuple[Samples, list[str], NDArray[np.int_], float]:
    """The samples the controller runs for a (possibly edited) program (module docstring).

    Returns:
        ``(samples, names, idx, max_edit)``: the re-timed, displaced samples with their joint
        values; the program points' names, the plan sample index of each, and the largest
        position edit [m].
    """
    conv = robot.description.convention
    to_model = np.linalg.inv(read.tool) @ np.linalg.inv(conv.flange) @ robot.description.tool
    T_plan = robot.batch_fk_jacobian(plan.q)[0]
    pts = read.points
    poses, names = _point_poses(robot, fmt, read, pts, to_model, T_plan, plan)
    idx = _match(poses, T_plan, plan.t, _program_times(read, poses))
    dp = poses[:, :3, 3] - T_plan[idx, :3, 3]
    dr = (Rotation.from_matrix(poses[:, :3, :3])
          * Rotation.from_matrix(T_plan[idx, :3, :3]).inv()).as_rotvec()
    t = _retime(read, poses, idx, plan.t)
    f_t = np.interp(np.arange(len(plan)), idx, np.arange(len(idx), dtype=float))
    k0 = np.clip(np.floor(f_t).astype(int), 0, len(idx) - 1)
    k1 = np.minimum(k0 + 1, len(idx) - 1)
    w = np.clip(f_t - k0, 0.0, 1.0)
    frac = np.where(k1 > k0, (plan.t - plan.t[idx[k0]])
                    / np.maximum(plan.t[idx[k1]] - plan.t[idx[k0]], 1e-12), w)
    frac = np.clip(frac, 0.0, 1.0)[:, None]
    target = T_plan.copy()
    target[:, :3, 3] += (1 - frac) * dp[k0] + frac * dp[k1]
    rot = (1 - frac) * dr[k0] + frac * dr[k1]
    target[:, :3, :3] = Rotation.from_rotvec(rot).as_matrix() @ T_plan[:, :3, :3]
    q = _batch_ik(robot, target, plan.q)
    out = Samples(t, plan.phase, plan.s, q, plan.wrench, plan.seam)
    return out, names, idx, float(np.max(np.linalg.norm(dp, axis=1)))


def _point_poses(robot: Robot, fmt: ControllerFormat, read: ReadProgram, pts: list[ReadPoint],
                 to_model: FloatArray, T_plan: FloatArray,
                 plan: Samples) -> tuple[FloatArray, list[str]]:
    """Model TCP poses (base frame) of the program's points: joint targets by FK, Cartesian
    points on their stated posture (IK seeded by the nearest plan sample)."""
    from rfsw_plan.export.config import ik_on_branch

    conv = robot.description.convention
    poses = np.empty((len(pts), 4, 4))
    for k, p in enumerate(pts):
        if p.q is not None:
            poses[k] = robot.fk(p.q)
            continue
        assert p.pose is not None
        T = conv.base @ read.work @ p.pose @ to_model
        near = int(np.argmin(np.linalg.norm(T_plan[:, :3, 3] - T[:3, 3], axis=1)))
        q = ik_on_branch(robot, T, lambda x, p=p: fmt.matches(robot, p, x), plan.q[near])
        poses[k] = robot.fk(q)
    return poses, [p.name for p in pts]


def _program_times(read: ReadProgram, poses: FloatArray) -> FloatArray:
    """Cumulative programmed time at each point [s] (speed over length, motion times, waits)."""
    times = np.zeros(len(poses))
    clock, k = 0.0, -1
    for m in read.motions:
        if m.kind == "wait":
            clock += m.duration
            continue
        k += 1
        if k > 0:
            length = float(np.linalg.norm(poses[k, :3, 3] - poses[k - 1, :3, 3]))
            clock += m.duration if m.duration > 0 else (length / m.speed if m.speed > 0 else 0.0)
        times[k] = clock
    return times


def _match(poses: FloatArray, T_plan: FloatArray, t_plan: FloatArray,
           t_prog: FloatArray) -> NDArray[np.int_]:
    """Plan sample index of each program point, in order, never before the previous point's:
    the nearest in position among the samples within :data:`MATCH_WINDOW` of the program's
    own cumulative time (all later samples if none), ties (stationary phases) broken by time."""
    idx = np.zeros(len(poses), dtype=int)
    start = 0
    for k in range(len(poses)):
        dt = np.abs(t_plan[start:] - t_plan[0] - t_prog[k])
        dist = np.linalg.norm(T_plan[start:, :3, 3] - poses[k, :3, 3], axis=1) * 1e3
        cost = np.where(dt <= MATCH_WINDOW, dist, np.inf) + 1e-2 * dt
        if not np.isfinite(cost).any():
            cost = dist + 1e-2 * dt
        idx[k] = start + int(np.argmin(cost))
        start = idx[k]
    return idx


def _retime(read: ReadProgram, poses: FloatArray, idx: NDArray[np.int_],
            t_plan: FloatArray) -> FloatArray:
    """Sample times as the program runs: each segment's plan time scaled to its programmed
    duration (the waits after its first point plus the move: speed over length, or the
    motion time). Samples after the last point keep their plan spacing."""
    moves: list[ReadPoint] = []
    waits = np.zeros(len(poses))
    for m in read.motions:
        if m.kind == "wait":
            waits[max(len(moves) - 1, 0)] += m.duration
        else:
            moves.append(m)
    out = np.array(t_plan, dtype=float)
    for k in range(len(idx) - 1):
        i, j = int(idx[k]), int(idx[k + 1])
        dt_plan = t_plan[j] - t_plan[i]
        m = moves[k + 1]
        length = float(np.linalg.norm(poses[k + 1, :3, 3] - poses[k, :3, 3]))
        dt_move = m.duration if m.duration > 0 else (length / m.speed if m.speed > 0 else 0.0)
        dt_prog = waits[k] + dt_move
        scale = dt_prog / dt_plan if dt_plan > 0 and dt_move > 0 else 1.0
        out[i + 1:j + 1] = out[i] + (t_plan[i + 1:j + 1] - t_plan[i]) * scale
    last = int(idx[-1])
    out[last + 1:] = t_plan[last + 1:] + (out[last] - t_plan[last])
    return out


def _batch_ik(robot: Robot, target: FloatArray, q0: FloatArray) -> FloatArray:
    """Joint values reaching ``target`` (m, 4, 4) from ``q0`` (m, n): damped Newton steps on
    all samples at once (the targets are within millimetres of the planned poses)."""
    q = np.array(q0, dtype=float)
    for _ in range(NEWTON_STEPS):
        T, J = robot.batch_fk_jacobian(q)
        err = np.concatenate([target[:, :3, 3] - T[:, :3, 3],
                              (Rotation.from_matrix(target[:, :3, :3])
                               * Rotation.from_matrix(T[:, :3, :3]).inv()).as_rotvec()], axis=1)
        JJt = J @ np.swapaxes(J, 1, 2) + 1e-12 * np.eye(6)
        q += np.einsum("kji,kj->ki", J, np.linalg.solve(JJt, err[:, :, None])[:, :, 0])
    return q
