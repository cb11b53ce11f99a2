"""Force/deflection co-simulation (seed 001 §2.3.3, Fig. 8) with the elastostatic robot model.

Seed 001 couples an FEA model of the weld (force from the tool position) with the robot's
stiffness model (deflection from the force) and iterates segment by segment. Here the FEA
model is replaced by a penetration law for the axial force, and per time step the force and
the deflection that agree with each other are found by an under-relaxed fixed point::

    penetration  p = d_c - delta_n(F)            (d_c commanded depth, delta_n = dX . n,
                                                  the robot's deflection up the tool axis)
    axial force  f_n = max(0, F_ref + k_p (p - p_ref))         (penetration law)
    iterate      f_n <- f_n + omega (law(d_c - delta_n(f_n)) - f_n)   until |step| < tol

delta_n comes from :meth:`ElastostaticModel.deflection_batch` (all effects of the robot file
apply) with the traverse and lateral forces of the load schedule held fixed. For a linear
robot model the map is affine, f -> k_p (d_c - a - c f), and converges for
0 < omega < 2 / (1 + k_p c); the fixed point is f = k_p (d_c - a) / (1 + k_p c).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.model import ElastostaticModel, SeamReference
from rfsw_plan.exceptions import InputError
from rfsw_plan.process.frames import FloatArray, LoadSchedule


@dataclass(frozen=True)
class PenetrationLaw:
    """Axial force as a function of the actual penetration (linear, no tension).

    f_n = max(0, ref_force + stiffness (p - ref_penetration)).

    Attributes:
        stiffness: Process stiffness k_p [N/m], > 0.
        ref_penetration: Penetration p_ref at the reference force [m].
        ref_force: Axial force at p_ref [N] (e.g. the measured steady Fd).
    """

    stiffness: float
    ref_penetration: float
    ref_force: float

    def __post_init__(self) -> None:
        if not (np.isfinite(self.stiffness) and self.stiffness > 0):
            raise InputError("process.coupling", "penetration_stiffness_N_per_mm",
                             f"got {self.stiffness * 1e-3:g}", "> 0")

    def force(self, penetration: FloatArray) -> FloatArray:
        """Axial force [N] for penetrations [m]."""
        p = np.asarray(penetration, dtype=float)
        return np.maximum(0.0, self.ref_force + self.stiffness * (p - self.ref_penetration))


@dataclass(frozen=True)
class CosimResult:
    """Converged force and deflection per time step.

    Attributes:
        t: Time [s], shape (N,).
        phase: Phase per sample, shape (N,).
        commanded_depth: Commanded depth d_c [m], shape (N,).
        penetration: Actual penetration d_c - delta_n [m], shape (N,).
        axial_force: Converged axial force f_n [N], shape (N,).
        force_seam: Seam-frame force with the converged f_n [N], shape (N, 3).
        deflection: TCP deflection, base frame [m, rad], shape (N, 6).
        iterations: Fixed-point iterations per step, shape (N,).
        residual: Last |law(p) - f_n| per step [N], shape (N,).
        converged: Per-step convergence flag, shape (N,).
    """

    t: FloatArray
    phase: NDArray[np.str_]
    commanded_depth: FloatArray
    penetration: FloatArray
    axial_force: FloatArray
    force_seam: FloatArray
    deflection: FloatArray
    iterations: NDArray[np.int_]
    residual: FloatArray
    converged: NDArray[np.bool_]

    @property
    def all_converged(self) -> bool:
        """True if every step converged."""
        return bool(np.all(self.converged))

    @property
    def through_weld(self) -> NDArray[np.bool_]:
        """Samples up to the weld's end (not the end stop nor the retract: seed 001 Fig. 10's
        runs end with the weld), shape (N,)."""
        return np.asarray(~np.isin(self.phase, ("stop", "retract")))

    @property
    def largest_penetration(self) -> float:
        """Largest penetration up to the weld's end [m] (:attr:`through_weld`): what seed 001
        Fig. 10 reads. (At the end stop the lateral and traverse forces relax, and the
        robot's give changes with them: on zk500_plunge7mm the pin sinks to 4.60 mm there
        against 4.35 mm in the weld.)"""
        return float(np.max(self.penetration[self.through_weld]))

    @property
    def settled(self) -> NDArray[np.bool_]:
        """Samples up to the weld's end where the penetration is above 90 % of its largest
        value (the tool has settled: seed 001 Fig. 10 reads the penetration there), shape
        (N,)."""
        return self.through_weld & (self.penetration > 0.9 * self.largest_penetration)

    @property
    def steady_axial_force(self) -> float:
        """Median axial force over :attr:`settled` [N]: what seed 001 §3 compares with the
        measured Fd0 (the mean of the stable region of the force curve)."""
        return float(np.median(self.axial_force[self.settled]))

    def summary(self) -> str:
        """One line on convergence."""
        return (f"co-simulation: {int(np.sum(self.converged))}/{len(self.t)} steps converged, "
                f"max {int(np.max(self.iterations))} iterations, max residual "
                f"{float(np.max(self.residual)):.3g} N")


def cosimulate(
    model: ElastostaticModel,
    q: FloatArray,
    schedule: LoadSchedule,
    law: PenetrationLaw,
    commanded_depth: FloatArray | None = None,
    relaxation: float = 0.5,
    tol: float = 1e-3,
    max_iter: int = 200,
    reference: SeamReference = "taught",
) -> CosimResult:
    """Solve force and deflection consistently at every sample of a load schedule.

    Args:
        model: Elastostatic model of the robot.
        q: Commanded (taught) joint values per sample [rad], shape (N, n).
        schedule: Load schedule (frames, traverse/lateral forces, moments; its f_n is only
            the start value of the iteration).
        law: Penetration law of the axial force.
        commanded_depth: Commanded depth per sample [m], shape (N,); default
            ``schedule.depth``.
        relaxation: Under-relaxation omega in (0, 1].
        tol: Convergence tolerance on the force update [N].
        max_iter: Iteration cap per step.
        reference: How the seam was obtained; see
            :meth:`ElastostaticModel.process_deflection`.

    Returns:
        The converged (or last) state per step with iteration counts and residuals.
    """
    if not 0 < relaxation <= 1:
        raise InputError("cosim", "relaxation", f"got {relaxation:g}", "0 < omega <= 1")
    N = len(schedule)
    d_c = schedule.depth if commanded_depth is None else np.asarray(commanded_depth, float)
    batch = model.batch(q)
    fr = schedule.frames
    F = schedule.force_seam.copy()
    f = F[:, 2].copy()
    iters = np.zeros(N, dtype=int)
    done = np.zeros(N, dtype=bool)

    def evaluate(fn: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        Fs = F.copy()
        Fs[:, 2] = fn
        W = np.hstack([fr.to_base(Fs), schedule.moment_base])
        dX = model.process_deflection_batch(batch, W, reference)
        pen = d_c - np.einsum("ki,ki->k", dX[:, :3], fr.n)
        return law.force(pen), pen, dX

    g, pen, dX = evaluate(f)
    for it in range(1, max_iter + 1):
        step = g - f
        newly = ~done & (np.abs(step) < tol)
        iters[~done] = it
        done |= newly
        if done.all():
            break
        f = np.where(done, f, f + relaxation * step)
        g, pen, dX = evaluate(f)
    # Final state consistent with the returned force.
    g, pen, dX = evaluate(f)
    F[:, 2] = f
    return CosimResult(
        t=schedule.t, phase=schedule.phase, commanded_depth=d_c, penetration=pen,
        axial_force=f, force_seam=F, deflection=dX, iterations=iters,
        residual=np.abs(g - f), converged=np.abs(g - f) < tol,
    )


# -- calibration of the penetration law (seed 001 Fig. 10, like eq. 15 for f*) -----------------
@dataclass(frozen=True)
class PenetrationObservation:
    """One commanded plunge and the penetration it gave (seed 001 Fig. 10a-c).

    Attributes:
        commanded_depth: Plunge commanded after surface contact [m].
        penetration: Penetration of the tool when it settled [m].
        at_least: True if the paper gives only a lower bound (``more than``): the fit then
            penalises a predicted penetration below it and nothing above it.
    """

    commanded_depth: float
    penetration: float
    at_least: bool = False


@dataclass(frozen=True)
class PenetrationFit:
    """A penetration law fitted to observed plunges through the robot's compliance.

    Attributes:
        law: The fitted law.
        observations: The observations fitted, shape (k,).
        predicted: Co-simulated penetration for each commanded depth [m], shape (k,).
        axial_force: Co-simulated axial force at each commanded depth [N], shape (k,).
        residual: Predicted minus observed penetration [m], shape (k,); for a lower bound
            only the part below it (0 when the bound holds).
        rms_residual: RMS of ``residual`` [m] (the square root of the mean eq. 15-style loss).
        axial_compliance: The robot's deflection up the tool axis per newton of axial force at
            the calibration sample [m/N].
        sample: Index of the schedule sample the law was fitted at.
        intercept: True if the force at zero penetration was a free parameter.
    """

    law: PenetrationLaw
    observations: tuple[PenetrationObservation, ...]
    predicted: FloatArray
    axial_force: FloatArray
    residual: FloatArray
    rms_residual: float
    axial_compliance: float
    sample: int
    intercept: bool

    def summary(self) -> str:
        """One line: the law, the residual and the robot's axial compliance."""
        obs = ", ".join(
            f"{o.commanded_depth * 1e3:g} mm -> {p * 1e3:.2f} mm "
            f"({'>=' if o.at_least else ''}{o.penetration * 1e3:g})"
            for o, p in zip(self.observations, self.predicted, strict=True))
        return (f"penetration law fitted by least squares: k_p "
                f"{self.law.stiffness * 1e-3:.1f} N/mm, {self.law.ref_force:.0f} N at "
                f"{self.law.ref_penetration * 1e3:g} mm; {obs}; RMS residual "
                f"{self.rms_residual * 1e3:.3f} mm; robot axial compliance "
                f"{self.axial_compliance * 1e6:.3f} mm/kN")


def _rows(schedule: LoadSchedule, idx: NDArray[np.int_]) -> LoadSchedule:
    fr = schedule.frames
    return LoadSchedule(
        t=schedule.t[idx], phase=schedule.phase[idx], s=schedule.s[idx],
        depth=schedule.depth[idx],
        frames=type(fr)(s=fr.s[idx], p=fr.p[idx], t=fr.t[idx], l=fr.l[idx], n=fr.n[idx]),
        force_seam=schedule.force_seam[idx], moment_base=schedule.moment_base[idx],
    )


def settled_sample(schedule: LoadSchedule) -> int:
    """Index of the last dwell sample: the tool has settled before travel starts (seed 001
    Fig. 10a-c reads the penetration there, at 12-16 s)."""
    dwell = np.flatnonzero(schedule.mask("dwell"))
    if dwell.size == 0:
        raise InputError("cosim", "schedule", "has no dwell phase",
                         "a process with dwell_s > 0 to calibrate the penetration law")
    return int(dwell[-1])


def fit_penetration_law(
    model: ElastostaticModel,
    q: FloatArray,
    schedule: LoadSchedule,
    observations: tuple[PenetrationObservation, ...],
    sample: int | None = None,
    intercept: bool = False,
    reference: SeamReference = "taught",
) -> PenetrationFit:
    """Fit the penetration law to observed plunges by least squares through the co-simulation.

    For each observation the co-simulation (:func:`cosimulate`, same robot model and wrench
    as the weld) is solved at one schedule sample with the observation's commanded depth; the
    law's parameters minimise the squared penetration error, as seed 001 eq. 15 chooses f*::

        min_theta  sum_i r_i^2,  r_i = p_i(theta) - p_i^obs   (r_i = min(0, .) for a bound)
        law        f_n = max(0, f_0 + k_p p)      theta = (k_p) with f_0 = 0, or (k_p, f_0)

    With ``intercept=False`` the law goes through zero (one parameter for three points, like
    eq. 15's one f* for three forces), so the residual measures how well one compliance
    explains all the plunges.

    Args:
        model: Elastostatic model of the robot.
        q: Taught joint values per schedule sample [rad], shape (N, n).
        schedule: The process's load schedule (traverse/lateral forces and moments held).
        observations: Commanded depth and observed penetration, e.g.
            :data:`rfsw_plan.process.presets.SEED001_FIG10`.
        sample: Schedule sample to fit at; default :func:`settled_sample`.
        intercept: Also fit the force at zero penetration.
        reference: How the seam was obtained; see
            :meth:`ElastostaticModel.process_deflection`.

    Returns:
        The fitted law, per-observation predictions and residuals, RMS residual [m].

    Raises:
        InputError: Fewer observations than parameters, non-positive depths, no dwell phase.
    """
    from scipy.optimize import least_squares

    obs = tuple(observations)
    n_par = 2 if intercept else 1
    if len(obs) < n_par:
        raise InputError("cosim", "calibration", f"{len(obs)} observation(s)",
                         f"at least {n_par} to fit {n_par} parameter(s)")
    if any(not (o.commanded_depth > 0 and o.penetration > 0) for o in obs):
        raise InputError("cosim", "calibration", "a depth or penetration <= 0", "> 0 m")
    i = settled_sample(schedule) if sample is None else int(sample)
    rows = _rows(schedule, np.full(len(obs), i))
    Q = np.repeat(np.asarray(q, dtype=float)[i : i + 1], len(obs), axis=0)
    d_c = np.array([o.commanded_depth for o in obs])
    p_obs = np.array([o.penetration for o in obs])
    bound = np.array([o.at_least for o in obs])
    # Robot axial compliance at the sample (finite difference of the deflection, 1 kN).
    batch = model.batch(Q[:1])
    fr1 = _rows(schedule, np.array([i]))

    def delta_n(fn: float) -> float:
        F = fr1.force_seam.copy()
        F[:, 2] = fn
        W = np.hstack([fr1.frames.to_base(F), fr1.moment_base])
        return float(model.process_deflection_batch(batch, W, reference)[0, :3] @ fr1.frames.n[0])

    f_ref = float(schedule.force_seam[i, 2])
    compliance = (delta_n(f_ref + 500.0) - delta_n(f_ref - 500.0)) / 1000.0
    p_ref = float(np.max(p_obs[~bound])) if (~bound).any() else float(np.max(p_obs))

    def law_of(x: FloatArray) -> PenetrationLaw:
        k = 1e6 * float(np.exp(x[0]))
        f0 = 1e3 * float(x[1]) if intercept else 0.0
        return PenetrationLaw(stiffness=k, ref_penetration=p_ref, ref_force=f0 + k * p_ref)

    def solve(x: FloatArray) -> CosimResult:
        law = law_of(x)
        omega = min(1.0, 1.0 / (1.0 + law.stiffness * max(compliance, 0.0)))
        return cosimulate(model, Q, rows, law, commanded_depth=d_c, relaxation=omega,
                          tol=1e-6, max_iter=500, reference=reference)

    def residual(x: FloatArray) -> FloatArray:
        r = solve(x).penetration - p_obs
        return np.where(bound, np.minimum(r, 0.0), r) * 1e3  # [mm]: well scaled

    x0 = np.array([0.0, 0.0]) if intercept else np.array([0.0])
    sol = least_squares(residual, x0, method="trf", x_scale=1.0, xtol=1e-12, ftol=1e-12)
    best = solve(sol.x)
    r = best.penetration - p_obs
    r = np.where(bound, np.minimum(r, 0.0), r)
    return PenetrationFit(
        law=law_of(sol.x), observations=obs, predicted=best.penetration,
        axial_force=best.axial_force, residual=r, rms_residual=float(np.sqrt(np.mean(r**2))),
        axial_compliance=compliance, sample=i, intercept=intercept,
    )
