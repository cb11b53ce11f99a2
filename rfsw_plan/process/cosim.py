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
