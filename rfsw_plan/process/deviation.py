"""Uncompensated pin deviation: where the loaded robot puts the pin on the taught path.

The robot is commanded the taught configuration q_k (IK of the seam pose, no fake target).
The process wrench W bends it; the elastostatic model gives the TCP deflection
(seed 000 eq. 11, seed 001 eq. 11: dX = J K^-1 J^T W, plus any effects of the robot file)::

    dX_k = model.process_deflection(q_k, W_k)           (base frame, [m, rad])
    lateral   e_l = dX_k[:3] . l_k   (+ toward the advancing side, the weld-window axis)
    axial     e_n = dX_k[:3] . n_k   (+ up the tool axis: less penetration)
    along     e_t = dX_k[:3] . t_k   (+ ahead along travel)

At the seam waypoints W is the steady weld force; over time W follows the load schedule
through plunge, dwell, weld and retract (stationary phases use the configuration of the seam
start or end, weld samples interpolate the taught joints linearly in arc length).
"""

from __future__ import annotations

import hashlib
import json
import logging
import pickle
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.model import ElastostaticModel, SeamReference
from rfsw_plan.exceptions import InputError, OutputPathError
from rfsw_plan.files import cache_dir, write_text
from rfsw_plan.process.cosim import (
    CosimResult,
    PenetrationFit,
    PenetrationLaw,
    cosimulate,
    fit_penetration_law,
)
from rfsw_plan.process.forces import ProcessModel
from rfsw_plan.process.frames import FloatArray, LoadSchedule, SeamFrames
from rfsw_plan.process.problem import Coupling, Problem
from rfsw_plan.process.taught import joints_at, taught_path
from rfsw_plan.process.window import WeldWindow
from rfsw_plan.robot.description import UrdfChain
from rfsw_plan.robot.kinematics import load_robot

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class DeviationResult:
    """Predicted uncompensated deviation along the seam and over time.

    Attributes:
        frames: Seam waypoint frames (k rows).
        q: Taught joint values at the waypoints [rad], shape (k, n).
        force_seam: Steady weld force per waypoint (f_t, f_l, f_n) [N], shape (k, 3).
        deflection: TCP deflection at the waypoints, base frame [m, rad], shape (k, 6).
        lateral: Lateral deviation per waypoint [m], shape (k,).
        axial: Axial deviation per waypoint [m], shape (k,).
        along: Along-track deviation per waypoint [m], shape (k,).
        schedule: Load schedule over time (N samples).
        deflection_t: TCP deflection over time, base frame [m, rad], shape (N, 6).
        lateral_t: Lateral deviation over time [m], shape (N,); under the co-simulated forces
            when ``cosim`` is given.
        axial_t: Axial deviation over time [m], shape (N,).
        along_t: Along-track deviation over time [m], shape (N,).
        window: Weld window.
        cosim: Co-simulation result over time, or None.
        penetration_fit: The penetration law fitted to the coupling's calibration (seed 001
            Fig. 10), or None if the law was given.
    """

    frames: SeamFrames
    q: FloatArray
    force_seam: FloatArray
    deflection: FloatArray
    lateral: FloatArray
    axial: FloatArray
    along: FloatArray
    schedule: LoadSchedule
    deflection_t: FloatArray
    lateral_t: FloatArray
    axial_t: FloatArray
    along_t: FloatArray
    window: WeldWindow
    cosim: CosimResult | None = None
    penetration_fit: PenetrationFit | None = None

    @property
    def steady_weld(self) -> NDArray[np.bool_]:
        """Weld samples whose traverse and lateral forces have reached their steady values
        (after the start-of-weld ramp), shape (N,)."""
        sch = self.schedule
        steady = self.force_seam[0, :2]
        return sch.mask("weld") & np.all(
            np.abs(sch.force_seam[:, :2] - steady) <= 1e-6 * np.abs(steady).max(), axis=1)

    def cosim_summary(self) -> str:
        """Two lines on the co-simulated weld: penetration, axial force and lateral deviation
        over the steady weld, and the mean lateral deviation of the last ten samples (seed 001
        §4 reports the mean of the final ten iterations); then the three numbers seed 001 gives
        together (largest penetration, steady axial force, largest |lateral| in the weld).
        Empty without a co-simulation."""
        c = self.cosim
        m = self.steady_weld
        if c is None or not m.any():
            return ""
        mm = 1e3
        last = np.flatnonzero(self.schedule.mask("weld"))[-10:]
        return (f"co-simulated steady weld: penetration {c.penetration[m].min() * mm:.2f}"
                f"-{c.penetration[m].max() * mm:.2f} mm, axial force "
                f"{c.axial_force[m].min():.0f}-{c.axial_force[m].max():.0f} N, lateral "
                f"{self.lateral_t[m].min() * mm:.2f}-{self.lateral_t[m].max() * mm:.2f} mm; "
                f"mean lateral of the last 10 samples {self.lateral_t[last].mean() * mm:.2f} mm\n"
                f"co-simulated: largest penetration {c.largest_penetration * mm:.2f} mm, steady "
                f"axial force {c.steady_axial_force:.0f} N (median where the penetration is above "
                f"90 % of its largest), largest |lateral| in the weld "
                f"{np.max(np.abs(self.lateral_t[self.schedule.mask('weld')])) * mm:.2f} mm")

    @property
    def max_abs_lateral(self) -> float:
        """Largest |lateral deviation| over the waypoints [m]."""
        return float(np.max(np.abs(self.lateral)))

    @property
    def worst_waypoint(self) -> int:
        """Index of the waypoint with the smallest window margin."""
        return int(np.argmin([self.window.margin(float(e)) for e in self.lateral]))

    @property
    def inside(self) -> NDArray[np.bool_]:
        """Waypoints whose lateral deviation is inside the window, shape (k,)."""
        return np.array([self.window.contains(float(e)) for e in self.lateral])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (mm, deg, N, s)."""
        mm = 1e3
        sch = self.schedule
        weld = sch.mask("weld")
        out: dict[str, Any] = {
            "max_abs_lateral_mm": self.max_abs_lateral * mm,
            "mean_lateral_mm": float(np.mean(self.lateral)) * mm,
            "max_abs_axial_mm": float(np.max(np.abs(self.axial))) * mm,
            "max_abs_along_mm": float(np.max(np.abs(self.along))) * mm,
            "worst_waypoint": self.worst_waypoint,
            "waypoints_inside_window": int(np.sum(self.inside)),
            "n_waypoints": len(self.frames),
            "window": {"lower_mm": self.window.lower * mm, "upper_mm": self.window.upper * mm,
                       "target_mm": self.window.target * mm},
            "steady_force_seam_N": {"f_t": float(self.force_seam[0, 0]),
                                    "f_l": float(self.force_seam[0, 1]),
                                    "f_n": float(self.force_seam[0, 2])},
            "s_mm": _r(self.frames.s * mm),
            "x_mm": _r(self.frames.p[:, 0] * mm),
            "y_mm": _r(self.frames.p[:, 1] * mm),
            "z_mm": _r(self.frames.p[:, 2] * mm),
            "lateral_mm": _r(self.lateral * mm),
            "axial_mm": _r(self.axial * mm),
            "along_mm": _r(self.along * mm),
            "q_deg": [_r(np.rad2deg(q)) for q in self.q],
            "time": {
                "t_s": _r(sch.t),
                "phase": [str(p) for p in sch.phase],
                "s_mm": _r(sch.s * mm),
                "depth_mm": _r(sch.depth * mm),
                "f_t_N": _r(sch.force_seam[:, 0]),
                "f_l_N": _r(sch.force_seam[:, 1]),
                "f_n_N": _r(sch.force_seam[:, 2]),
                "lateral_mm": _r(self.lateral_t * mm),
                "axial_mm": _r(self.axial_t * mm),
                "along_mm": _r(self.along_t * mm),
                "max_abs_lateral_weld_mm": float(np.max(np.abs(self.lateral_t[weld])) * mm)
                if weld.any() else None,
            },
        }
        if self.cosim is not None:
            c = self.cosim
            out["cosim"] = {
                "all_converged": c.all_converged,
                "max_iterations": int(np.max(c.iterations)),
                "max_residual_N": float(np.max(c.residual)),
                "max_penetration_mm": c.largest_penetration * mm,
                "steady_axial_force_N": c.steady_axial_force,
                "max_abs_lateral_weld_mm": float(np.max(np.abs(self.lateral_t[weld])) * mm)
                if weld.any() else None,
                "axial_force_N": _r(c.axial_force),
                "penetration_mm": _r(c.penetration * mm),
                "lateral_mm": _r(self.lateral_t * mm),
                "axial_mm": _r(self.axial_t * mm),
                "along_mm": _r(self.along_t * mm),
                "iterations": [int(i) for i in c.iterations],
            }
            fit = self.penetration_fit
            if fit is not None:
                out["cosim"]["penetration_fit"] = {
                    "stiffness_N_per_mm": fit.law.stiffness * 1e-3,
                    "reference_penetration_mm": fit.law.ref_penetration * mm,
                    "reference_force_N": fit.law.ref_force,
                    "commanded_depth_mm": [o.commanded_depth * mm for o in fit.observations],
                    "observed_penetration_mm": [o.penetration * mm for o in fit.observations],
                    "observed_is_lower_bound": [o.at_least for o in fit.observations],
                    "predicted_penetration_mm": _r(fit.predicted * mm),
                    "axial_force_N": _r(fit.axial_force),
                    "rms_residual_mm": fit.rms_residual * mm,
                    "axial_compliance_mm_per_kN": fit.axial_compliance * 1e6,
                    "time_s": float(sch.t[fit.sample]),
                }
        return out


def _r(a: FloatArray) -> list[float]:
    return [round(float(v), 6) for v in np.asarray(a)]


def _components(dX: FloatArray, fr: SeamFrames) -> tuple[FloatArray, FloatArray, FloatArray]:
    d = dX[:, :3]
    return (np.einsum("ki,ki->k", d, fr.l), np.einsum("ki,ki->k", d, fr.n),
            np.einsum("ki,ki->k", d, fr.t))


def schedule_joints(schedule: LoadSchedule, frames: SeamFrames, Q: FloatArray) -> FloatArray:
    """Taught joint values at each schedule sample [rad], shape (N, n).

    Stationary phases at the seam start/end use the first/last waypoint configuration (the
    few-mm plunge offset along the tool axis changes the compliance negligibly).
    """
    return joints_at(frames.s[0] + schedule.s, frames.s, Q)


def predict_deviation(
    model: ElastostaticModel,
    frames: SeamFrames,
    process: ProcessModel,
    Q: FloatArray,
    window: WeldWindow | None = None,
    dt: float = 0.1,
    coupling: Coupling | None = None,
    reference: SeamReference = "taught",
) -> DeviationResult:
    """Uncompensated deviation at the waypoints (steady force) and over time.

    Args:
        model: Elastostatic model (robot-file effects apply).
        frames: Seam waypoint frames (k rows), base frame.
        process: Process with the force model.
        Q: Taught joint values at the waypoints [rad], shape (k, n).
        window: Weld window (default seed 000's).
        dt: Time step of the schedule [s] (seed 001 Table 6: 0.1 s).
        coupling: Optional co-simulation settings (penetration law, commanded depth); the
            time series then uses the converged axial force. A coupling with a calibration
            instead of a law has its law fitted first, at the last dwell sample
            (:func:`~rfsw_plan.process.cosim.fit_penetration_law`).
        reference: How the seam was obtained (``taught`` or ``absolute``); see
            :meth:`ElastostaticModel.process_deflection`.
    """
    window = WeldWindow() if window is None else window
    k = len(frames)
    F = np.tile(process.steady_force_seam(), (k, 1))
    sigma = np.sign(np.linalg.det(frames.rotation()))
    M = (sigma * process.forces.spindle_torque)[:, None] * frames.n
    W = np.hstack([frames.to_base(F), M])
    dX = model.process_deflection(Q, W, reference)
    lat, ax, al = _components(dX, frames)
    sch = process.schedule(frames, dt)
    Qt = schedule_joints(sch, frames, Q)
    dXt = model.process_deflection(Qt, sch.wrench_base, reference)
    cos = None
    fit = None
    if coupling is not None:
        law = coupling.law
        if law is None:
            fit = fit_penetration_law(model, Qt, sch, coupling.calibration,
                                      reference=reference)
            law = fit.law
        d_c = sch.depth * (coupling.commanded_depth / process.plunge_depth)
        cos = cosimulate(model, Qt, sch, law, commanded_depth=d_c, reference=reference)
        dXt = cos.deflection
    lat_t, ax_t, al_t = _components(dXt, sch.frames)
    return DeviationResult(
        frames=frames, q=Q, force_seam=F, deflection=dX, lateral=lat, axial=ax, along=al,
        schedule=sch, deflection_t=dXt, lateral_t=lat_t, axial_t=ax_t, along_t=al_t,
        window=window, cosim=cos, penetration_fit=fit,
    )


def problem_deviation(problem: Problem, dt: float = 0.1, cosim: bool = False) -> DeviationResult:
    """:func:`predict_deviation` for a problem (taught path from its q_seed).

    Raises:
        UnreachableError: The seam is not reachable from the problem's q_seed.
    """
    robot = load_robot(problem.robot)
    model = ElastostaticModel(robot)
    frames = problem.frames()
    Q = taught_path(robot, frames, problem.q_seed(), problem.planning.tool_rotation)
    if cosim and problem.coupling is None:
        raise InputError(problem.path or problem.name, "process.coupling",
                         "no co-simulation settings", "a [process.coupling] table")
    return predict_deviation(model, frames, problem.process, Q, problem.window, dt,
                             problem.coupling if cosim else None, problem.seam_reference)


def problem_penetration_law(problem: Problem) -> PenetrationLaw:
    """The penetration law of a problem's ``[process.coupling]``: the explicit one, or the one
    fitted to its calibration as ``rfsw-plan deviation --cosim`` fits it (the taught path
    from the problem's q_seed, the load schedule every 0.1 s, the last dwell sample:
    :func:`~rfsw_plan.process.cosim.fit_penetration_law`; k_p 1056 N/mm on
    ``zk500_table6_seam``).

    Raises:
        InputError: The problem has no ``[process.coupling]``.
        UnreachableError: The seam is not reachable from the problem's q_seed.
    """
    coupling = problem.coupling
    if coupling is None:
        raise InputError(problem.path or problem.name, "process.coupling",
                         "no co-simulation settings", "a [process.coupling] table")
    if coupling.law is not None:
        return coupling.law
    key = _law_key(problem)
    if key is not None and key in _LAW_CACHE:
        return _LAW_CACHE[key]
    law = _read_law(key) if key is not None else None
    if law is None:
        law = _fit_problem_law(problem, coupling)
        if key is not None:
            _write_law(key, law)
    if key is not None:
        _LAW_CACHE[key] = law
        while len(_LAW_CACHE) > _LAW_CACHE_SIZE:
            _LAW_CACHE.popitem(last=False)
    return law


#: Penetration laws fitted in this process (:func:`problem_penetration_law`), by
#: :func:`_law_key`, oldest first: rebuilding a task (``check``, ``validate-weld``, the
#: placement map, the tests) refitted the law every time (issue 41).
_LAW_CACHE: OrderedDict[bytes, PenetrationLaw] = OrderedDict()
_LAW_CACHE_SIZE = 16


def _law_key(problem: Problem) -> bytes | None:
    """The SHA-256 of everything the fitted law depends on, or None for a problem that does
    not pickle (then the law is not cached):

    * the pickled problem (robot description, seam, process, coupling, options: every input
      of the fit, as values);
    * the bytes of the files the robot is built from at fit time: the robot file and its
      URDF (effect plugin files are named in the description with their SHA-256, which
      loading them checks);
    * the version of the code that fits it (:func:`_fit_code_version`).

    Pickling is a faithful serialisation, so two problems with one key hold the same inputs;
    two equal problems with different keys only miss the cache."""
    try:
        h = hashlib.sha256(pickle.dumps(problem, protocol=5))
    except (pickle.PicklingError, TypeError, AttributeError):
        return None
    robot = problem.robot
    urdf = robot.chain.path if isinstance(robot.chain, UrdfChain) else None
    for f in (robot.path, urdf):
        h.update(b"\0file\0")
        if f is not None:
            try:
                h.update(Path(f).read_bytes())
            except OSError:
                return None
    h.update(_fit_code_version())
    return h.digest()


#: The packages whose code the fit runs (the problem, the robot and its kinematics, the
#: elastostatic model and its effects, the taught path, the schedule, the co-simulation and
#: the fit itself), relative to the package; the package's top-level modules too.
LAW_CODE = ("process", "elastostatics", "robot")
_CODE_VERSION: list[bytes] = []


def _fit_code_version() -> bytes:
    """:func:`code_digest` of this installation of the package (computed once per process, a
    few milliseconds)."""
    if not _CODE_VERSION:
        _CODE_VERSION.append(code_digest(Path(__file__).resolve().parents[1]))
    return _CODE_VERSION[0]


def code_digest(root: Path) -> bytes:
    """SHA-256 of the code that fits the law: the source of every module of :data:`LAW_CODE`
    and the top-level modules of the package in ``root`` (path and bytes, in path order), and
    the versions of Python, NumPy, Pinocchio and SciPy (its ``version.py``, found without
    importing SciPy). Any change of that code is a new key, so a cached law is never one an
    older fit gave."""
    import importlib.util
    import sys

    import pinocchio

    files = sorted([*root.glob("*.py"), *(f for d in LAW_CODE for f in (root / d).rglob("*.py"))])
    h = hashlib.sha256(f"{sys.version}\0{np.__version__}\0{pinocchio.__version__}".encode())
    spec = importlib.util.find_spec("scipy")
    if spec is not None and spec.origin is not None:
        files.append(Path(spec.origin).parent / "version.py")
    for f in files:
        h.update(f"\0{f.relative_to(root) if f.is_relative_to(root) else f.name}\0".encode())
        try:
            h.update(f.read_bytes())
        except OSError:
            h.update(b"\0missing")
    return h.digest()


#: What a cache file of a fitted law says it is (a file that does not is ignored).
LAW_CACHE_FORMAT = "rfsw_plan penetration law"


def _law_file(key: bytes) -> Path:
    """The cache file of the law with ``key``: ``penetration_law_<hash>.json`` in
    :func:`rfsw_plan.files.cache_dir`."""
    return cache_dir() / f"penetration_law_{key.hex()[:32]}.json"


def _read_law(key: bytes) -> PenetrationLaw | None:
    """The law cached on disk under ``key``, or None: no file, or one that is not a whole
    cache file of this key (damaged, truncated, another key's, another format) is ignored and
    the law fitted again. The floats are stored in hexadecimal, bit for bit."""
    path = _law_file(key)
    try:
        rec = json.loads(path.read_bytes())
        if (not isinstance(rec, dict) or rec.get("format") != LAW_CACHE_FORMAT
                or rec.get("key") != key.hex()):
            return None
        return PenetrationLaw(*(float.fromhex(rec[k]) for k in _LAW_FIELDS))
    except (OSError, ValueError, TypeError, KeyError, InputError):
        return None


_LAW_FIELDS = ("stiffness", "ref_penetration", "ref_force")


def _write_law(key: bytes, law: PenetrationLaw) -> None:
    """Keep a fitted law on disk under ``key`` (written atomically; a cache that cannot be
    written is only a cache: the law is returned all the same)."""
    path = _law_file(key)
    rec = {"format": LAW_CACHE_FORMAT, "key": key.hex(),
           **{k: float(getattr(law, k)).hex() for k in _LAW_FIELDS}}
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text(path, json.dumps(rec, indent=1) + "\n")
    except (OSError, OutputPathError) as exc:
        log.info("penetration law not cached in %s (%s)", path, exc)


def _fit_problem_law(problem: Problem, coupling: Coupling) -> PenetrationLaw:
    """The law fitted to the coupling's calibration (see :func:`problem_penetration_law`)."""
    robot = load_robot(problem.robot)
    model = ElastostaticModel(robot)
    frames = problem.frames()
    Q = taught_path(robot, frames, problem.q_seed(), problem.planning.tool_rotation)
    sch = problem.process.schedule(frames, 0.1)
    Qt = schedule_joints(sch, frames, Q)
    return fit_penetration_law(model, Qt, sch, coupling.calibration,
                               reference=problem.seam_reference).law
