"""Validate the model against a measured weld (``rfsw-plan validate-weld``).

After a trial weld a welding engineer holds the plan that was run, the force log of the
spindle or wrist sensor, and a measurement of where the weld went (a laser line scan of the
bead, or seed 000's lateral offset Delta y = D1 - D2, Figs. 15-17). This module:

1. **Predicts the executed pin path** from the plan's commanded joints (interpolated in arc
   length as the controller runs them), under the logged wrench (sensor effects of the model
   applied, smoothed over ``smooth_s`` to remove sensor noise the structure does not follow) or
   the planned one, with the current robot model::

       e_lat(s) = l . (FK_p(q(s)) + dX_p(q(s), F(s)) - p(s))      (advancing side +) [m]
       e_norm(s) = n . (FK_p(q(s)) + dX_p(q(s), F(s)) - p(s))     (up the tool axis +) [m]

   (dX the model's process deflection with the problem's seam reference; p the seam point at
   the pin depth.)
2. **Compares** with the track: residual r = measured - predicted against s and time, RMS,
   max, the share of the measured weld inside the window. The noise floor sigma is estimated
   from successive differences of the residual, sigma^2 = mean((r_k+1 - r_k)^2) / 2 (the
   model error is smooth along the seam, the measurement noise is not).
3. **Diagnoses**: every candidate (a stiffness scale of one joint, ``joint_compliance:jN``;
   every library effect the model lacks, at every joint where it applies) is fitted to the
   residual by Gauss-Newton on its parameters, and scored by cross-validation over contiguous
   blocks of s (one Gauss-Newton step from the full fit on the other blocks, as
   :mod:`~rfsw_plan.validation.diagnosis` does by pose groups). Held-out F test against the
   model as it is, Bonferroni over the candidates at level ``ALPHA``.
4. **Is honest about identifiability**: one weld at one pose sees few directions of the
   compliance. The regressor of every candidate parameter (the track's change for a 20 %
   change of the parameter) is stacked; its singular values say how many directions the
   track resolves (a direction counts when its coefficient's standard error sigma / s_i is
   below 1/3), and each candidate is *visible* (its column moves the track by more than 3
   sigma) and *distinguishable* from the best (held-out F test between the two at level
   ``TIE_LEVEL``) or not.

Verdict: ``adequate`` (the residual is at the noise floor), ``missing`` (the best candidate
brings the held-out residual to the noise floor; the candidates the weld cannot tell from it
are listed), ``unexplained`` (no candidate does).
"""

from __future__ import annotations

import logging
import shlex
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from scipy import stats

from rfsw_plan.elastostatics.effects import EFFECTS, parse_effect_label
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import IdentificationError, InputError
from rfsw_plan.io.force_series import ForceSeries
from rfsw_plan.io.weld_track import WeldTrack
from rfsw_plan.process.force_fit import series_in_seam_frame
from rfsw_plan.process.forces import FIT_PARAMS
from rfsw_plan.process.frames import FloatArray
from rfsw_plan.process.problem import Problem, load_problem, with_process
from rfsw_plan.process.seam import interpolate_frames
from rfsw_plan.realtime.compare import PlannedWaypoints

log = logging.getLogger(__name__)

#: Significance of the held-out F tests (Bonferroni over the candidates).
ALPHA = 1e-3
#: Level below which a candidate is indistinguishable from the best one on this track.
TIE_LEVEL = 0.05
#: A held-out RMS within this factor of the noise floor is "at the noise floor".
NOISE_TOLERANCE = 1.15
#: Relative parameter change whose effect on the track defines visibility (20 %).
PARAM_CHANGE = 0.2
#: A direction (or a candidate) is identifiable when its coefficient's standard error is
#: below 1/IDENT_RATIO of a PARAM_CHANGE change: singular value >= IDENT_RATIO sigma.
IDENT_RATIO = 3.0
#: A median |offset| above this is not a weld deviation: wrong units or wrong frame [m].
MAX_MEDIAN_OFFSET = 20e-3
#: The track must overlap at least this share of the seam.
MIN_OVERLAP_SHARE = 0.25
#: At most this many track points enter the diagnosis (evenly spread).
MAX_POINTS = 600
#: Default number of blocks of s.
DEFAULT_BLOCKS = 5
#: Plan statuses that are not a verified plan.
UNVERIFIED = ("infeasible", "incomplete", "failed", "unverified", "error", "not_verified")

Verdict = Literal["adequate", "missing", "unexplained"]


# --------------------------------------------------------------------------------------------
# The plan that was run


@dataclass(frozen=True)
class PlanRecord:
    """A verified plan read back from its folder.

    Attributes:
        folder: The plan folder.
        data: ``plan.json``.
        problem: The problem it was planned for (with the fitted forces if it was planned
            with ``--forces``).
        robot: The robot file or name the plan was made with.
        waypoints: The planned joints per waypoint.
    """

    folder: Path
    data: dict[str, Any]
    problem: Problem
    robot: str
    waypoints: PlannedWaypoints


def read_plan_dir(folder: str | Path, problem: str | None = None) -> PlanRecord:
    """Read ``plan.json`` of a plan folder and the problem it was planned for.

    Args:
        folder: Output folder of ``rfsw-plan plan``.
        problem: Problem file or bundled name (default: the one ``plan.json`` names).

    Raises:
        InputError: No ``plan.json``, not JSON, not a verified plan, or no waypoints.
    """
    folder = Path(folder)
    path = folder / "plan.json"
    if not folder.is_dir():
        raise InputError(folder, "", "is not a folder", "the output folder of rfsw-plan plan")
    if not path.is_file():
        raise InputError(folder, "plan.json", "missing: no plan in this folder",
                         "the output folder of a successful rfsw-plan plan")
    from rfsw_plan.planfiles.waypoints import check_plan_folder

    try:
        data = check_plan_folder(folder)  # status, and the files plan.json vouches for
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(path, "", f"not readable strict JSON ({exc})") from None
    if not isinstance(data, dict):
        raise InputError(path, "", "not a JSON object", "plan.json of rfsw-plan plan")
    status = str(data.get("status", ""))
    if not status or any(u in status.lower() for u in UNVERIFIED):
        raise InputError(path, "status", f"'{status or 'missing'}': not a verified plan",
                         "a plan that passed verification (status optimal or verified)")
    wp = data.get("waypoints")
    if not isinstance(wp, dict) or not all(k in wp for k in ("q_deg", "s_mm", "phase")):
        raise InputError(path, "waypoints", "missing q_deg/s_mm/phase",
                         "plan.json with its waypoints")
    name = problem or data.get("problem_file") or data.get("problem")
    if not name:
        raise InputError(path, "problem", "no problem named", "--problem FILE")
    pb = load_problem(name)
    robot_ref = data.get("robot_file")
    if robot_ref:
        from dataclasses import replace

        from rfsw_plan.robot.description import load_robot_description

        pb = replace(pb, robot=load_robot_description(robot_ref))
    fl = data.get("force_log")
    if isinstance(fl, dict) and fl.get("used"):
        params = fl.get("fit", {}).get("params", {})
        try:
            x = np.array([float(params[n]) for n in FIT_PARAMS])
        except (KeyError, TypeError, ValueError):
            raise InputError(path, "force_log.fit.params", "incomplete",
                             ", ".join(FIT_PARAMS)) from None
        pb = with_process(pb, _with_forces(pb, x))
    q = np.deg2rad(np.asarray(wp["q_deg"], dtype=float))
    s = np.asarray(wp["s_mm"], dtype=float) * 1e-3
    phase = np.asarray(wp["phase"]).astype(str)
    if q.ndim != 2 or q.shape[0] != s.size or s.size != phase.size:
        raise InputError(path, "waypoints", "q_deg, s_mm and phase differ in length")
    # Stationary waypoints (plunge, dwell) are timed by the process schedule.
    sched = pb.process.schedule(pb.frames(), 0.05, approach=False)
    t = np.zeros(s.size)
    for ph in ("plunge", "dwell"):
        m = phase == ph
        ms = np.asarray(sched.phase) == ph
        if np.any(m) and np.any(ms):
            t[m] = np.linspace(sched.t[ms][0], sched.t[ms][-1], int(np.sum(m)))
    wps = PlannedWaypoints(time=t, phase=phase, s=s - s[0], q=q)
    return PlanRecord(folder, data, pb, str(robot_ref or data.get("robot", "")), wps)


def _with_forces(problem: Problem, x: FloatArray) -> Any:
    from dataclasses import replace

    proc = problem.process
    return replace(proc, forces=proc.forces.with_vector(x, source="fitted (plan.json)"))


# --------------------------------------------------------------------------------------------
# Prediction of the executed pin path


@dataclass(frozen=True)
class WeldSamples:
    """The executed plan at the measured track points (weld phase).

    Attributes:
        s: Arc length from the seam start [m], shape (N,).
        t: Time from the process start at which the tool passes s [s], shape (N,).
        q: Commanded joints [rad], shape (N, n).
        wrench: Wrench used for the prediction, base frame [N, N m], shape (N, 6).
        p: Seam point at the pin depth, base frame [m], shape (N, 3).
        l: Lateral direction (advancing side), shape (N, 3).
        n: Tool axis, shape (N, 3).
        logged: True if the wrench is the (sensor-corrected) log, False if planned.
    """

    s: FloatArray
    t: FloatArray
    q: FloatArray
    wrench: FloatArray
    p: FloatArray
    l: FloatArray
    n: FloatArray
    logged: bool

    def predict(self, model: ElastostaticModel, reference: str) -> tuple[FloatArray, FloatArray]:
        """(e_lat, e_norm) of a model [m], each shape (N,) (module docstring, step 1)."""
        batch = model.batch(self.q)
        W = self.wrench
        if self.logged:
            sensor = [e for e in model.groups.wrench if e.sensor_only]
            if sensor:
                W = W + sum((e.delta_wrench(batch, W, e.params) for e in sensor),
                            np.zeros_like(W))
        dX = model.process_deflection_batch(batch, W, reference)  # type: ignore[arg-type]
        d = batch.T[:, :3, 3] + dX[:, :3] - self.p
        return np.einsum("ki,ki->k", d, self.l), np.einsum("ki,ki->k", d, self.n)


def _running_mean_time(t: FloatArray, y: FloatArray, window: float) -> FloatArray:
    """Centred running mean over ``window`` seconds of each column of y (N, d)."""
    if window <= 0 or y.shape[0] < 3:
        return y
    dt = float(np.median(np.diff(t)))
    n = max(1, round(window / dt) | 1)
    c = np.vstack([np.zeros((1, y.shape[1])), np.cumsum(y, axis=0)])
    k = np.arange(y.shape[0])
    lo = np.clip(k - n // 2, 0, y.shape[0])
    hi = np.clip(k + n - n // 2, 0, y.shape[0])
    out: FloatArray = (c[hi] - c[lo]) / (hi - lo)[:, None]
    return out


def weld_samples(
    problem: Problem, plan: PlannedWaypoints, s: FloatArray, series: ForceSeries | None = None,
    smooth_s: float = 0.25,
) -> WeldSamples:
    """Joints, wrench and seam frames where the tool passes the arc lengths ``s`` [m].

    Raises:
        InputError: The plan has no weld waypoints.
    """
    w = plan.phase == "weld"
    if not np.any(w):
        raise InputError("plan", "phase", "the plan has no weld waypoints")
    frames = problem.frames()
    length = float(frames.s[-1] - frames.s[0])
    sched = problem.process.schedule(frames, 0.02)
    ws = np.asarray(sched.phase) == "weld"
    sw, iw = np.unique(sched.s[ws], return_index=True)
    t = np.interp(s, sw, sched.t[ws][iw])
    s_wp, q_wp = plan.s[w], plan.q[w]
    q = np.stack([np.interp(s, s_wp, q_wp[:, j]) for j in range(q_wp.shape[1])], axis=1)
    fr = interpolate_frames(frames, frames.s[0] + np.clip(s, 0.0, length))
    at = problem.process.evaluate(frames, t)
    if series is None:
        wrench = at.wrench_base
        logged = False
    else:
        rot = problem.planning.tool_rotation
        sch_log = problem.process.evaluate(frames, series.t)
        f_seam, m_seam = series_in_seam_frame(series, sch_log, rot)
        f_seam = _running_mean_time(series.t, f_seam, smooth_s)
        f_t = np.stack([np.interp(t, series.t, f_seam[:, j]) for j in range(3)], axis=1)
        force = at.frames.to_base(f_t)
        if m_seam is not None:
            m_seam = _running_mean_time(series.t, m_seam, smooth_s)
            m_t = np.stack([np.interp(t, series.t, m_seam[:, j]) for j in range(3)], axis=1)
            moment = at.frames.to_base(m_t)
        else:
            moment = at.moment_base
        wrench = np.hstack([force, moment])
        logged = True
    return WeldSamples(s=s, t=t, q=q, wrench=wrench, p=fr.p, l=fr.l, n=fr.n, logged=logged)


# --------------------------------------------------------------------------------------------
# Track against seam


@dataclass(frozen=True)
class TrackOnSeam:
    """The measured track as offsets along the seam, inside the seam.

    Attributes:
        s: Arc length [m], shape (N,), increasing.
        e_lat: Measured lateral offset [m], (N,).
        e_norm: Measured normal offset [m], (N,), or None.
        overlap: (start, end) of the track on the seam [m].
        seam_length: Seam length [m].
        dropped: Points outside the seam.
        gaps: Rows of the file with a gap.
    """

    s: FloatArray
    e_lat: FloatArray
    e_norm: FloatArray | None
    overlap: tuple[float, float]
    seam_length: float
    dropped: int
    gaps: int


def track_on_seam(track: WeldTrack, problem: Problem) -> TrackOnSeam:
    """Offsets of the track from the joint line along the seam (seam form as it is; base
    form projected on the nearest seam point), checked for units and overlap.

    Raises:
        InputError: Median |offset| above :data:`MAX_MEDIAN_OFFSET` (wrong units or frame), or
            the track overlaps less than :data:`MIN_OVERLAP_SHARE` of the seam (says the
            overlap).
    """
    frames = problem.frames()
    length = float(frames.s[-1] - frames.s[0])
    src = track.source
    if track.form == "base":
        assert track.xyz is not None
        dense = problem.seam.frames(min(0.5e-3, length / 50))
        from scipy.spatial import cKDTree

        k = np.asarray(cKDTree(dense.p).query(track.xyz)[1], dtype=int)
        dk = track.xyz - dense.p[k]
        s = dense.s[k] - dense.s[0] + np.einsum("ki,ki->k", dk, dense.t[k])
        e_lat = np.einsum("ki,ki->k", dk, dense.l[k])
        e_norm = None
        where = "x_mm, y_mm, z_mm projected on the seam"
        order = np.argsort(s)
        s, e_lat = s[order], e_lat[order]
    else:
        assert track.s is not None and track.e_lat is not None
        s, e_lat, e_norm = track.s, track.e_lat, track.e_norm
        where = "column e_lat_mm"
    ok = np.isfinite(s) & np.isfinite(e_lat)
    if e_norm is not None:
        ok &= np.isfinite(e_norm)
    gaps = track.n_gaps + int(np.sum(~ok))
    s, e_lat = s[ok], e_lat[ok]
    e_norm = None if e_norm is None else e_norm[ok]
    if s.size < 3:
        raise InputError(src, "", f"{s.size} measured point(s)", "at least 3")
    med = float(np.median(np.abs(e_lat)))
    if med > MAX_MEDIAN_OFFSET:
        raise InputError(src, where, f"median offset {med * 1e3:.4g} mm = {med:.3g} m from the "
                         "joint line: wrong units or wrong frame",
                         f"offsets of a few mm at most (window {problem.window.lower * 1e3:g}.."
                         f"{problem.window.upper * 1e3:g} mm), in mm")
    lo, hi = max(float(s[0]), 0.0), min(float(s[-1]), length)
    ov = max(hi - lo, 0.0)
    inside = (s >= -1e-9) & (s <= length + 1e-9)
    if ov < MIN_OVERLAP_SHARE * length or int(np.sum(inside)) < 3:
        hint = " (s in metres?)" if float(s[-1]) < length * 1e3 * 2e-3 and track.form == "seam" \
            else ""
        raise InputError(src, "s" if track.form == "seam" else "x_mm, y_mm, z_mm",
                         f"the track covers s = {float(s[0]) * 1e3:.1f}..{float(s[-1]) * 1e3:.1f}"
                         f" mm, the seam 0..{length * 1e3:.1f} mm: overlap {ov * 1e3:.1f} mm "
                         f"({100 * ov / length:.0f} %){hint}",
                         f"a track along at least {100 * MIN_OVERLAP_SHARE:.0f} % of the seam")
    return TrackOnSeam(s=s[inside], e_lat=e_lat[inside],
                       e_norm=None if e_norm is None else e_norm[inside], overlap=(lo, hi),
                       seam_length=length, dropped=int(np.sum(~inside)), gaps=gaps)


def noise_floor(s: FloatArray, r: FloatArray) -> float:
    """1-sigma measurement noise from successive differences of the residual [m]:
    sigma^2 = mean((r_k+1 - r_k)^2) / 2 over neighbours no further apart than twice the
    median spacing (a gap does not count as a difference)."""
    ds = np.diff(s)
    dr = np.diff(r)
    near = ds <= 2.0 * float(np.median(ds))
    if not np.any(near):
        return float(np.std(r))
    return float(np.sqrt(np.mean(dr[near] ** 2) / 2.0))


# --------------------------------------------------------------------------------------------
# Candidates


@dataclass
class _Candidate:
    label: str
    build: Callable[[FloatArray], ElastostaticModel]
    theta0: FloatArray
    names: tuple[str, ...]
    lower: FloatArray | None = None


def _joint_candidate(model: ElastostaticModel, j: int) -> _Candidate:
    c0 = model.joint_compliance.params

    def build(theta: FloatArray) -> ElastostaticModel:
        m = model.copy()
        c = np.array(c0, dtype=float)
        c[j] = theta[0]
        m.joint_compliance.params = c
        return m

    return _Candidate(f"joint_compliance:j{j + 1}", build, np.array([c0[j]]), (f"c{j + 1}",))


def _effect_candidate(model: ElastostaticModel, label: str) -> _Candidate:
    proto = model.with_effect(label)
    eff = proto.effects[-1]
    names = tuple(eff.param_dict())

    def build(theta: FloatArray) -> ElastostaticModel:
        m = model.with_effect(label)
        m.effects[-1].params = np.array(theta, dtype=float)
        return m

    return _Candidate(label, build, np.array(eff.params, dtype=float), names)


def candidate(model: ElastostaticModel, label: str) -> _Candidate:
    """A candidate by label: ``joint_compliance:jN`` (the stiffness of joint N) or a library
    effect the model lacks.

    Raises:
        UnknownNameError, InputError: Unknown effect, bad joint, or already in the model.
    """
    name, _, jtxt = label.partition(":j")
    if name == "joint_compliance":
        try:
            j = int(jtxt) - 1
        except ValueError:
            raise InputError("--add", label, "needs a joint",
                             f"joint_compliance:jN with N in 1..{model.robot.nq}") from None
        if not 0 <= j < model.robot.nq:
            raise InputError("--add", label, "joint out of range", f"1..{model.robot.nq}")
        return _joint_candidate(model, j)
    parse_effect_label(label, model.robot.nq)
    if model.has(label):
        raise InputError("--add", label, "already in the model",
                         "an effect the robot file does not have")
    return _effect_candidate(model, label)


def candidate_labels(model: ElastostaticModel) -> list[str]:
    """Every joint stiffness and every library effect (per joint) the model lacks."""
    out = [f"joint_compliance:j{j + 1}" for j in range(model.robot.nq)]
    for name, cls in EFFECTS.items():
        if name == "joint_compliance":
            continue
        labels = [f"{name}:j{j + 1}" for j in range(model.robot.nq)] if cls.per_joint else [name]
        out += [x for x in labels if not model.has(x)]
    return out


# --------------------------------------------------------------------------------------------
# Fitting and scoring


@dataclass(frozen=True)
class CandidateScore:
    """One candidate fitted to the weld.

    Attributes:
        label: ``joint_compliance:jN`` or an effect label.
        params: Fitted parameters by name [SI].
        prior: Parameters before the fit [SI].
        rms: RMS residual after the fit, all points [m].
        heldout_rms: RMS of the held-out residual over the blocks of s [m].
        F: Held-out F statistic against the model as it is.
        p_value: Its p-value.
        significant: p below ALPHA / number of candidates.
        visible: A 20 % change of the parameters (of the prior; of the fit where the prior is 0)
            moves the
            track by more than IDENT_RATIO sigma (column norm).
        identifiable: Visible, and every parameter's standard error (sigma sqrt((J^T J)^-1))
            is below PARAM_CHANGE / IDENT_RATIO of its size: the weld fixes each parameter,
            not only a combination of them.
        relative_std: Standard error / size per parameter [-].
        distinguishable: The candidate does not also bring the held-out residual to the noise
            floor (True for the best itself): the weld tells it from the best.
        physical: Fitted parameters are physically admissible (compliance >= 0).
        note: Why it was not fitted, or a remark.
    """

    label: str
    params: dict[str, float]
    prior: dict[str, float]
    rms: float
    heldout_rms: float
    F: float
    p_value: float
    significant: bool
    visible: bool
    identifiable: bool = True
    relative_std: dict[str, float] = field(default_factory=dict)
    distinguishable: bool = True
    physical: bool = True
    note: str = ""

    @property
    def stiffness_scale(self) -> float | None:
        """Fitted / prior stiffness of the joint for a joint candidate."""
        if not self.label.startswith("joint_compliance:"):
            return None
        (k, v), = self.params.items()
        return self.prior[k] / v if v > 0 else float("inf")

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary (mm for lengths)."""
        return {
            "label": self.label, "params": self.params, "prior": self.prior,
            "stiffness_scale": self.stiffness_scale, "rms_mm": self.rms * 1e3,
            "heldout_rms_mm": self.heldout_rms * 1e3, "F": self.F, "p_value": self.p_value,
            "significant": self.significant, "visible": self.visible,
            "identifiable": self.identifiable, "relative_std": self.relative_std,
            "distinguishable_from_best": self.distinguishable, "physical": self.physical,
            "note": self.note,
        }


class _Problem:
    """The stacked observations of the diagnosis (lateral, and normal if measured)."""

    def __init__(self, samples: WeldSamples, track: TrackOnSeam, reference: str,
                 blocks: int) -> None:
        self.samples = samples
        self.reference = reference
        self.y = np.concatenate([track.e_lat] + ([track.e_norm] if track.e_norm is not None
                                                 else []))
        n = track.s.size
        self.n_points = n
        self.n_comp = 1 if track.e_norm is None else 2
        block = np.minimum((np.arange(n) * blocks) // n, blocks - 1)
        self.block = np.tile(block, self.n_comp)
        self.blocks = blocks

    def obs(self, model: ElastostaticModel) -> FloatArray:
        e_lat, e_norm = self.samples.predict(model, self.reference)
        return np.concatenate([e_lat] + ([e_norm] if self.n_comp == 2 else []))


def _fd_jacobian(prob: _Problem, cand: _Candidate, theta: FloatArray, base: FloatArray
                 ) -> FloatArray:
    cols = []
    for i in range(theta.size):
        h = 1e-3 * max(abs(float(theta[i])), abs(float(cand.theta0[i])), 1e-9)
        th = theta.copy()
        th[i] += h
        cols.append((prob.obs(cand.build(th)) - base) / h)
    return np.stack(cols, axis=1)


def _lower_bounds(cand: _Candidate) -> FloatArray:
    """Physical lower bounds of a candidate's parameters (compliances are >= 0)."""
    if cand.lower is not None:
        return cand.lower
    name = cand.label.split(":")[0]
    if name in ("joint_compliance", "tilting_compliance", "complementary_stiffness"):
        return np.zeros(cand.theta0.size)
    return np.full(cand.theta0.size, -np.inf)


def _fit(prob: _Problem, cand: _Candidate) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Bounded nonlinear least squares of a candidate (scipy ``least_squares``, trust region
    reflective; compliances >= 0): (theta*, residual at theta*, d(obs)/d(theta) at theta*)."""
    from scipy.optimize import least_squares

    lb = _lower_bounds(cand)
    x0 = np.maximum(cand.theta0, np.where(np.isfinite(lb), lb, -np.inf))
    scale = np.where(x0 != 0, np.abs(x0), 1.0)

    def fun(z: FloatArray) -> FloatArray:
        out: FloatArray = prob.y - prob.obs(cand.build(z * scale))
        return out

    z0 = x0 / scale
    lbz = np.where(np.isfinite(lb), lb / scale, -np.inf)
    z0 = np.where(z0 <= lbz, lbz + 1e-9, z0)
    sol = least_squares(fun, z0, bounds=(lbz, np.inf), method="trf", x_scale="jac",
                        diff_step=1e-4, max_nfev=60 * (z0.size + 1))
    theta = sol.x * scale
    pred = prob.obs(cand.build(theta))
    J = _fd_jacobian(prob, cand, theta, pred)
    return theta, prob.y - pred, J


def _heldout(prob: _Problem, r: FloatArray, J: FloatArray | None,
             room: FloatArray | None = None) -> FloatArray:
    """Held-out residual by blocks of s: one least-squares step on the other blocks, clipped
    to the physical bounds (``room`` = lower bound - theta*, <= 0)."""
    if J is None:
        return r
    out = np.empty_like(r)
    for b in range(prob.blocks):
        te = prob.block == b
        tr = ~te
        scale = np.linalg.norm(J[tr], axis=0)
        scale[scale == 0] = 1.0
        d = np.linalg.lstsq(J[tr] / scale, r[tr], rcond=1e-8)[0] / scale
        if room is not None:
            d = np.maximum(d, room)
        out[te] = r[te] - J[te] @ d
    return out


def _rms(x: FloatArray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def _ftest(sse0: float, sse1: float, p: int, n: int) -> tuple[float, float]:
    dof = max(n - p, 1)
    if sse1 <= 0:
        return float("inf"), 0.0
    F = ((sse0 - sse1) / max(p, 1)) / (sse1 / dof)
    return float(F), float(stats.f.sf(F, max(p, 1), dof)) if F > 0 else 1.0


def _admissible(cand: _Candidate, theta: FloatArray) -> bool:
    if cand.label.startswith("joint_compliance:"):
        return bool(theta[0] > 0)
    name = cand.label.split(":")[0]
    if name in ("tilting_compliance", "complementary_stiffness"):
        return bool(np.all(theta >= 0))
    return True


@dataclass(frozen=True)
class Identifiability:
    """What one weld can identify.

    Attributes:
        joint_singular_values: Of the joint-stiffness regressor (column j: the track's change
            for a PARAM_CHANGE change of joint j's stiffness) [m], descending, shape (n,).
        joints_identifiable: Joints whose stiffness the weld fixes together with all others:
            the part of the joint's column orthogonal to the other joints' columns moves the
            track by at least IDENT_RATIO sigma (standard error below 1/IDENT_RATIO of a
            PARAM_CHANGE change).
        joints_not: The other joints.
        singular_values: Of the regressor of every candidate parameter [m], descending.
        n_directions: Of those, how many are >= IDENT_RATIO sigma.
        n_params: Candidate parameters stacked.
        identifiable: Candidates whose every parameter the weld fixes when fitted alone.
        combination_only: Candidates the weld sees only as a combination of parameters.
        invisible: Candidates the track does not see (a 20 % change moves it less than
            IDENT_RATIO sigma).
    """

    joint_singular_values: FloatArray
    joints_identifiable: tuple[int, ...]
    joints_not: tuple[int, ...]
    singular_values: FloatArray
    n_directions: int
    n_params: int
    identifiable: tuple[str, ...]
    combination_only: tuple[str, ...]
    invisible: tuple[str, ...]

    def text(self) -> str:
        """Two lines for the summary."""
        sv = ", ".join(f"{x * 1e3:.3g}" for x in self.joint_singular_values)

        def js(j: tuple[int, ...]) -> str:
            return ", ".join(f"j{k + 1}" for k in j) or "none"

        return (f"joint stiffnesses this weld identifies together: {js(self.joints_identifiable)}"
                f"; not identifiable from it: {js(self.joints_not)} (singular values of the "
                f"joint-stiffness regressor {sv} mm for a {100 * PARAM_CHANGE:g} % change)\n"
                f"effects it sees only as a combination of their parameters: "
                f"{', '.join(self.combination_only) or 'none'}; effects it does not see: "
                f"{', '.join(self.invisible) or 'none'}")

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {"joint_singular_values_mm": [float(x) * 1e3 for x in self.joint_singular_values],
                "joints_identifiable": [f"j{k + 1}" for k in self.joints_identifiable],
                "joints_not_identifiable": [f"j{k + 1}" for k in self.joints_not],
                "singular_values_mm": [float(x) * 1e3 for x in self.singular_values],
                "n_directions": self.n_directions, "n_params": self.n_params,
                "identifiable_alone": list(self.identifiable),
                "combination_only": list(self.combination_only),
                "invisible": list(self.invisible),
                "criterion": f"a parameter or direction counts when a {100 * PARAM_CHANGE:g} %"
                f" change is at least {IDENT_RATIO:g} x its standard error (noise floor)"}


def _joint_identifiability(columns: FloatArray, sigma: float) -> tuple[FloatArray, list[bool]]:
    """Singular values of the joint columns (m, n) and, per joint, whether its column's part
    orthogonal to the others is >= IDENT_RATIO sigma."""
    sv: FloatArray = np.asarray(np.linalg.svd(columns, compute_uv=False), dtype=float)
    ok = []
    for j in range(columns.shape[1]):
        others = np.delete(columns, j, axis=1)
        a = columns[:, j]
        if others.shape[1]:
            coef = np.linalg.lstsq(others, a, rcond=None)[0]
            a = a - others @ coef
        ok.append(bool(np.linalg.norm(a) >= IDENT_RATIO * sigma))
    return sv, ok


@dataclass(frozen=True)
class WeldDiagnosis:
    """Verdict on a weld, with the candidates and what the weld can identify."""

    verdict: Verdict
    message: str
    sigma: float
    rms: float
    heldout_rms: float
    candidates: tuple[CandidateScore, ...]
    ties: tuple[str, ...]
    identifiability: Identifiability
    skipped: tuple[tuple[str, str], ...] = ()

    @property
    def best(self) -> CandidateScore | None:
        """The candidate with the lowest held-out RMS (None if none was fitted)."""
        return self.candidates[0] if self.candidates else None

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {"verdict": self.verdict, "message": self.message,
                "noise_floor_mm": self.sigma * 1e3, "rms_mm": self.rms * 1e3,
                "heldout_rms_mm": self.heldout_rms * 1e3,
                "indistinguishable_from_best": list(self.ties),
                "identifiability": self.identifiability.to_json(),
                "candidates": [c.to_json() for c in self.candidates],
                "skipped": [{"label": a, "reason": b} for a, b in self.skipped]}


def diagnose_weld(
    model: ElastostaticModel, samples: WeldSamples, track: TrackOnSeam, reference: str,
    labels: Sequence[str] | None = None, blocks: int = DEFAULT_BLOCKS,
) -> WeldDiagnosis:
    """Which candidate explains the residual (module docstring, steps 3 and 4).

    Raises:
        InputError: Fewer than 2 blocks or fewer points than 4 per block.
    """
    if blocks < 2:
        raise InputError("--blocks", "", f"{blocks}", "at least 2")
    if track.s.size < 4 * blocks:
        raise InputError("track", "", f"{track.s.size} points on the seam",
                         f"at least {4 * blocks} for {blocks} blocks of s")
    from rfsw_plan.progress import progress

    prob = _Problem(samples, track, reference, blocks)
    base = prob.obs(model)
    r0 = prob.y - base
    n_obs = r0.size
    sigma = float(np.sqrt(np.mean([noise_floor(track.s, r0[k * prob.n_points:(k + 1)
                                                            * prob.n_points]) ** 2
                                   for k in range(prob.n_comp)])))
    labels = list(labels) if labels is not None else candidate_labels(model)
    fitted: list[tuple[CandidateScore, FloatArray, int]] = []
    columns: list[FloatArray] = []
    col_owner: list[str] = []
    change_of: dict[str, FloatArray] = {}
    skipped: list[tuple[str, str]] = []
    for label in progress(labels, desc="candidates", unit="cand"):
        try:
            cand = candidate(model, label)
            theta, r, J = _fit(prob, cand)
        except (InputError, IdentificationError, np.linalg.LinAlgError, ValueError) as exc:
            skipped.append((label, str(exc)))
            continue
        if not np.all(np.isfinite(r)):
            skipped.append((label, "the fit diverged"))
            continue
        size = np.maximum(np.where(cand.theta0 != 0, np.abs(cand.theta0), np.abs(theta)),
                          1e-300)
        change = J * (PARAM_CHANGE * size)
        vis = bool(np.linalg.norm(change) >= IDENT_RATIO * sigma)
        rse = sigma * np.sqrt(np.clip(np.diag(np.linalg.pinv(J.T @ J)), 0.0, None)) / size
        alone = bool(vis and np.all(rse < PARAM_CHANGE / IDENT_RATIO))
        columns += list(change.T)
        change_of[label] = change[:, 0]
        col_owner += [label] * change.shape[1]
        held = _heldout(prob, r, J, _lower_bounds(cand) - theta)
        F, p = _ftest(float(r0 @ r0), float(held @ held), cand.theta0.size, n_obs)
        sc = CandidateScore(
            label=label, params=dict(zip(cand.names, map(float, theta), strict=True)),
            prior=dict(zip(cand.names, map(float, cand.theta0), strict=True)), rms=_rms(r),
            heldout_rms=_rms(held), F=F, p_value=p, significant=False, visible=vis,
            identifiable=alone, relative_std=dict(zip(cand.names, map(float, rse), strict=True)),
            physical=_admissible(cand, theta),
            note="" if _admissible(cand, theta) else "fitted value is not physical")
        fitted.append((sc, held, cand.theta0.size))
    n_tests = max(len(fitted), 1)
    scored = []
    for sc, held, p in fitted:
        from dataclasses import replace

        scored.append((replace(sc, significant=bool(sc.p_value < ALPHA / n_tests
                                                    and sc.physical)), held, p))
    floor = NOISE_TOLERANCE * sigma

    def explains(sc: CandidateScore) -> bool:
        return sc.physical and sc.significant and sc.heldout_rms <= floor

    # Among the candidates that reach the noise floor the simplest (fewest parameters, then
    # identifiable) comes first: a richer effect that also fits is no evidence for itself.
    scored.sort(key=lambda x: (not explains(x[0]), x[2] if explains(x[0]) else 0,
                               not x[0].identifiable if explains(x[0]) else False,
                               not x[0].physical, x[0].heldout_rms))
    ties: list[str] = []
    cands_l: list[CandidateScore] = []
    for i, (sc, _, _) in enumerate(scored):
        from dataclasses import replace

        tie = i > 0 and explains(sc) and explains(scored[0][0])
        if tie:
            ties.append(sc.label)
        cands_l.append(replace(sc, distinguishable=not tie))
    cands = tuple(cands_l)
    if columns:
        A = np.stack(columns, axis=1)
        sv = np.asarray(np.linalg.svd(A, compute_uv=False), dtype=float)
    else:
        sv = np.zeros(0)
    jcols = [change_of[f"joint_compliance:j{j + 1}"] for j in range(model.robot.nq)
             if f"joint_compliance:j{j + 1}" in change_of]
    jsv, jok = (_joint_identifiability(np.stack(jcols, axis=1), sigma) if
                len(jcols) == model.robot.nq else (np.zeros(0), [False] * model.robot.nq))
    ident = Identifiability(
        jsv, tuple(j for j, o in enumerate(jok) if o), tuple(j for j, o in enumerate(jok) if not o),
        sv, int(np.sum(sv >= IDENT_RATIO * sigma)), len(col_owner),
        tuple(c.label for c in cands if c.identifiable),
        tuple(c.label for c in cands if c.visible and not c.identifiable),
        tuple(c.label for c in cands if not c.visible))
    rms0 = _rms(r0)
    at_noise = rms0 <= NOISE_TOLERANCE * sigma
    chi_p = float(stats.chi2.sf(float(r0 @ r0) / max(sigma, 1e-15) ** 2, n_obs))
    verdict: Verdict
    if at_noise or chi_p >= ALPHA:
        verdict = "adequate"
        msg = (f"adequate: RMS {rms0 * 1e3:.4f} mm against a noise floor of {sigma * 1e3:.4f} mm"
               " (the model explains the weld)")
    elif cands and cands[0].significant and cands[0].heldout_rms <= NOISE_TOLERANCE * sigma:
        verdict = "missing"
        b = cands[0]
        what = _describe(b)
        msg = (f"missing: {what} brings the held-out RMS from {rms0 * 1e3:.4f} to "
               f"{b.heldout_rms * 1e3:.4f} mm (noise floor {sigma * 1e3:.4f} mm)")
        if ties:
            msg += (f"; this weld cannot tell it from {', '.join(ties[:6])}"
                    f"{' ...' if len(ties) > 6 else ''} (they explain it as well)")
    else:
        verdict = "unexplained"
        msg = (f"unexplained: RMS {rms0 * 1e3:.4f} mm, noise floor {sigma * 1e3:.4f} mm; ")
        if cands and cands[0].significant:
            msg += (f"the best candidate {_describe(cands[0])} lowers the held-out RMS only to "
                    f"{cands[0].heldout_rms * 1e3:.4f} mm")
        else:
            msg += "no library effect or joint stiffness explains it significantly"
    return WeldDiagnosis(verdict, msg, sigma, rms0, rms0, cands, tuple(ties), ident,
                         tuple(skipped))


def _describe(c: CandidateScore) -> str:
    k = c.stiffness_scale
    if k is not None:
        return f"{c.label} (joint {c.label.split(':j')[1]} stiffness x{k:.3f})"
    return c.label + " (" + ", ".join(f"{n} {v:.4g}" for n, v in c.params.items()) + ")"


# --------------------------------------------------------------------------------------------
# Re-identification


@dataclass(frozen=True)
class WeldAddResult:
    """``--add``: the candidates fitted jointly to the weld.

    Attributes:
        labels: What was added.
        model: The re-identified model.
        params: Fitted parameters by label [SI].
        rms_before / rms_after: RMS residual [m].
        heldout_before / heldout_after: Held-out RMS by blocks of s [m].
    """

    labels: tuple[str, ...]
    model: ElastostaticModel
    params: dict[str, dict[str, float]]
    rms_before: float
    rms_after: float
    heldout_before: float
    heldout_after: float

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {"added": list(self.labels), "params": self.params,
                "rms_before_mm": self.rms_before * 1e3, "rms_after_mm": self.rms_after * 1e3,
                "heldout_rms_before_mm": self.heldout_before * 1e3,
                "heldout_rms_after_mm": self.heldout_after * 1e3,
                "stiffness_N_m_per_rad": [float(x) for x in self.model.stiffness]}


def add_and_identify(
    model: ElastostaticModel, samples: WeldSamples, track: TrackOnSeam, reference: str,
    labels: Sequence[str], blocks: int = DEFAULT_BLOCKS,
) -> WeldAddResult:
    """Add the candidates and fit their parameters jointly to the weld.

    Raises:
        InputError: Unknown or duplicated label, a label already in the model.
        IdentificationError: The fit gives a non-physical value (e.g. negative compliance).
    """
    if len(set(labels)) != len(labels):
        raise InputError("--add", ", ".join(labels), "duplicated", "each effect once")
    cands = [candidate(model, lab) for lab in labels]
    sizes = [c.theta0.size for c in cands]
    theta0 = np.concatenate([c.theta0 for c in cands])

    def build(theta: FloatArray) -> ElastostaticModel:
        m = model.copy()
        i = 0
        for c, p in zip(cands, sizes, strict=True):
            part = theta[i:i + p]
            i += p
            if c.label.startswith("joint_compliance:"):
                j = int(c.label.split(":j")[1]) - 1
                cc = np.array(m.joint_compliance.params, dtype=float)
                cc[j] = part[0]
                m.joint_compliance.params = cc
            else:
                m = m.with_effect(c.label)
                m.effects[-1].params = np.array(part, dtype=float)
        return m

    joint = _Candidate("+".join(labels), build, theta0,
                       tuple(f"{c.label}.{n}" for c in cands for n in c.names),
                       np.concatenate([_lower_bounds(c) for c in cands]))
    prob = _Problem(samples, track, reference, blocks)
    r0 = prob.y - prob.obs(model)
    theta, r, J = _fit(prob, joint)
    for c, ok in zip(cands, _split_admissible(cands, sizes, theta), strict=True):
        if not ok:
            raise IdentificationError(
                f"--add {c.label}: the weld fits a non-physical value (negative compliance); "
                "this effect does not explain the weld")
    params: dict[str, dict[str, float]] = {}
    i = 0
    for c, p in zip(cands, sizes, strict=True):
        params[c.label] = dict(zip(c.names, map(float, theta[i:i + p]), strict=True))
        i += p
    held = _heldout(prob, r, J, _lower_bounds(joint) - theta)
    return WeldAddResult(tuple(labels), build(theta), params, _rms(r0), _rms(r), _rms(r0),
                         _rms(held))


def _split_admissible(cands: list[_Candidate], sizes: list[int], theta: FloatArray
                      ) -> list[bool]:
    out, i = [], 0
    for c, p in zip(cands, sizes, strict=True):
        out.append(_admissible(c, theta[i:i + p]))
        i += p
    return out


# --------------------------------------------------------------------------------------------
# The whole validation


@dataclass(frozen=True)
class WeldValidation:
    """Outcome of :func:`validate_weld`.

    Attributes:
        plan: The plan that was run.
        model: The current robot model.
        track: The measured track on the seam.
        samples: The executed plan at the track points.
        predicted_lat / predicted_norm: Prediction at the track points [m].
        residual_lat: measured - predicted lateral [m].
        residual_norm: measured - predicted normal [m], or None.
        diagnosis: The diagnosis.
        add: The re-identification (``--add``), or None.
        predicted_after: Lateral prediction of the re-identified model [m], or None.
        forces_source: The force log file, or ``planned``.
    """

    plan: PlanRecord
    model: ElastostaticModel
    track: TrackOnSeam
    samples: WeldSamples
    predicted_lat: FloatArray
    predicted_norm: FloatArray
    residual_lat: FloatArray
    residual_norm: FloatArray | None
    diagnosis: WeldDiagnosis
    add: WeldAddResult | None
    predicted_after: FloatArray | None
    forces_source: str
    notes: tuple[str, ...] = field(default=())

    def inside_fraction(self, e: FloatArray) -> float:
        """Share of the measured length (gaps excluded) with e inside the window."""
        w = self.plan.problem.window
        s = self.track.s
        ds = np.gradient(s) if s.size > 1 else np.ones(1)
        ds = np.minimum(ds, 2.0 * float(np.median(ds)))
        inside = (e >= w.lower) & (e <= w.upper)
        return float(np.sum(ds * inside) / np.sum(ds))

    def to_json(self) -> dict[str, Any]:
        """``validate_weld.json`` (mm, s)."""
        w = self.plan.problem.window
        out: dict[str, Any] = {
            "plan_dir": str(self.plan.folder), "problem": self.plan.problem.name,
            "robot": self.model.robot.name, "effects": self.model.labels,
            "forces": self.forces_source,
            "window_mm": [w.lower * 1e3, w.upper * 1e3],
            "track": {"points": int(self.track.s.size), "gaps": self.track.gaps,
                      "outside_seam": self.track.dropped,
                      "overlap_mm": [self.track.overlap[0] * 1e3, self.track.overlap[1] * 1e3],
                      "seam_length_mm": self.track.seam_length * 1e3,
                      "normal_measured": self.track.e_norm is not None},
            "measured_inside_window_fraction": self.inside_fraction(self.track.e_lat),
            "predicted_inside_window_fraction": self.inside_fraction(self.predicted_lat),
            "residual_lat": _stats_mm(self.residual_lat),
            "residual_norm": None if self.residual_norm is None else _stats_mm(
                self.residual_norm),
            "diagnosis": self.diagnosis.to_json(),
            "add": None if self.add is None else self.add.to_json(),
            "notes": list(self.notes),
            "samples": {"s_mm": (self.track.s * 1e3).tolist(),
                        "t_s": self.samples.t.tolist(),
                        "measured_lat_mm": (self.track.e_lat * 1e3).tolist(),
                        "predicted_lat_mm": (self.predicted_lat * 1e3).tolist(),
                        "residual_lat_mm": (self.residual_lat * 1e3).tolist()},
        }
        if self.predicted_after is not None:
            out["samples"]["predicted_after_lat_mm"] = (self.predicted_after * 1e3).tolist()
        return out


def _stats_mm(r: FloatArray) -> dict[str, float]:
    return {"rms_mm": _rms(r) * 1e3, "max_abs_mm": float(np.max(np.abs(r))) * 1e3,
            "mean_mm": float(np.mean(r)) * 1e3}


def validate_weld(
    plan: PlanRecord, track: WeldTrack, series: ForceSeries | None = None,
    model: ElastostaticModel | None = None, add: Sequence[str] = (),
    blocks: int = DEFAULT_BLOCKS, smooth_s: float = 0.25,
) -> WeldValidation:
    """Predict the executed weld, compare with the track, diagnose, optionally re-identify.

    Args:
        plan: The plan that was run (:func:`read_plan_dir`).
        track: The measured weld.
        series: The force log of the weld (None: the planned forces).
        model: The current robot model (default: the plan's robot).
        add: Candidates to add and fit (``joint_compliance:jN`` or effect labels).
        blocks: Blocks of s of the cross-validation.
        smooth_s: Running-mean window of the force log [s].

    Raises:
        InputError: Track off the seam or in wrong units; bad labels.
    """
    from rfsw_plan.robot.kinematics import load_robot

    problem = plan.problem
    model = model or ElastostaticModel(load_robot(problem.robot))
    on = track_on_seam(track, problem)
    notes: list[str] = []
    if series is not None:
        from rfsw_plan.planning.force_log import check_axial

        check_axial(series, problem, problem.planning.tool_rotation)
    else:
        notes.append("no force log: the prediction uses the planned forces, so force drift "
                     "along the seam shows up in the residual")
    if on.s.size > MAX_POINTS:
        idx = np.unique(np.round(np.linspace(0, on.s.size - 1, MAX_POINTS)).astype(int))
        on = TrackOnSeam(on.s[idx], on.e_lat[idx], None if on.e_norm is None else on.e_norm[idx],
                         on.overlap, on.seam_length, on.dropped, on.gaps)
        notes.append(f"diagnosis on {idx.size} of the track points (evenly spread)")
    samples = weld_samples(problem, plan.waypoints, on.s, series, smooth_s)
    ref = problem.seam_reference
    e_lat, e_norm = samples.predict(model, ref)
    res_lat = on.e_lat - e_lat
    res_norm = None if on.e_norm is None else on.e_norm - e_norm
    diag = diagnose_weld(model, samples, on, ref, blocks=blocks)
    added = None
    after = None
    if add:
        added = add_and_identify(model, samples, on, ref, list(add), blocks)
        after = samples.predict(added.model, ref)[0]
    return WeldValidation(plan, model, on, samples, e_lat, e_norm, res_lat, res_norm, diag,
                          added, after, series.source if series is not None else "planned",
                          tuple(notes))


def next_command(result: WeldValidation, plan_dir: str, track: str, forces: str | None,
                 saved: Path | None) -> str:
    """The command to run next (printed and in the report)."""
    pb = result.plan.problem
    problem = str(pb.path) if pb.path else pb.name
    f = f" --forces {forces}" if forces else ""
    if saved is not None:
        return f"rfsw-plan plan {problem}{f} --robot {saved} -o {plan_dir.rstrip('/')}_2"
    dg = result.diagnosis
    if dg.verdict == "missing" and dg.best is not None:
        from rfsw_plan.robot.description import derived_name

        new = derived_name(result.model.robot.name, [dg.best.label])
        return (f"rfsw-plan validate-weld {plan_dir} --track {track}{f} --add "
                f"{dg.best.label} --save-robot {shlex.quote(new + '.toml')}")
    if dg.verdict == "adequate":
        return f"rfsw-plan plan {problem}{f} -o {plan_dir.rstrip('/')}_2  (the model holds)"
    return ("measure more (another weld at a different pose or direction separates the "
            "candidates), or rfsw-plan validate with a load campaign")


__all__ = ["CandidateScore", "Identifiability", "PlanRecord", "TrackOnSeam", "WeldAddResult",
           "WeldDiagnosis", "WeldSamples", "WeldValidation", "add_and_identify",
           "candidate_labels", "diagnose_weld", "next_command", "noise_floor", "read_plan_dir",
           "track_on_seam", "validate_weld", "weld_samples"]
