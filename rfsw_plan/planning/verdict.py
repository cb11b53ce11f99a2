"""The verdict on a plan, in words a welding engineer can act on, and the trade-off behind it.

Three verdicts (the first line of ``rfsw-plan plan`` and ``"verdict"`` in ``plan.json``):

* ``GO``: every written in-material sample holds the weld envelope, and every weld quantity
  (lateral error, depth, work and travel angle, pin speed) still holds it under the requested
  force uncertainty (the plan tolerates +-x % >= the requested +-y %: x is the smallest of the
  per-quantity levels of :func:`~rfsw_plan.planning.verify.robust_claim`).
* ``HOLDS NOMINALLY``: every written sample holds the envelope, but under force uncertainty
  only up to +-x % < +-y %. The verdict names the quantity that limits x first, where (sample,
  t, phase, s), and its levers: the quantity's own first (for the depth under position control
  axial force control, with the level the plan would reach under it, measured on the same
  model), then the three that raise the stiffness-limited levels, each with what it must
  achieve and its measured gain where one is known.
* ``NO``: no plan (infeasible window, speed or singularity, exit 3).

Every number comes from the plan's :class:`~rfsw_plan.planning.baselines.BaselineMetrics`
(one computation over waypoints and written samples), so the verdict, the table, ``plan.json``
and the plots cannot disagree.

The trade-off. The worst case of the lateral error scales with the compliance: e +- u R with
R = sum_i |f_i| |l^T C_tt b_i| (seed 000 eq. 11). At the same nominal errors, a robot uniformly
stiffer by a factor s has R / s and tolerates s u. So the requested +-y % needs the weakest
lateral stiffness k_plan y / x: the ``requested`` point of the trade-off table and plot.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from rfsw_plan.planning.baselines import BaselineMetrics
from rfsw_plan.planning.verify import RobustClaim

GO = "GO"
HOLDS_NOMINALLY = "HOLDS NOMINALLY"
NO = "NO"
#: Relative tolerance of "the requested uncertainty is held" (the NLP's and the closed form's
#: rounding).
HELD_RTOL = 1e-9


def pct(u: float) -> str:
    """A relative uncertainty as a percentage for text: ``+-16.7 %``, ``any``, ``none``."""
    if u == np.inf:
        return "any"
    if not np.isfinite(u) or u <= 0:
        return "none"
    return f"+-{100 * u:.3g} %"


@dataclass(frozen=True)
class TradeoffPoint:
    """One point of the robustness/stiffness trade-off.

    Attributes:
        name: ``plan``, ``mirror``, ``none`` or ``requested``.
        tolerated: Tolerated relative force uncertainty (inf: no lateral force).
        min_lateral_stiffness: Weakest lateral stiffness 1 / (l^T C_tt l) [N/m].
    """

    name: str
    tolerated: float
    min_lateral_stiffness: float

    def to_dict(self) -> dict[str, Any]:
        """File units: percent and N/mm."""
        return {"point": self.name, "tolerated_force_uncertainty_pct": self.tolerated * 100,
                "min_lateral_stiffness_N_mm": self.min_lateral_stiffness * 1e-3}


def tradeoff(baselines: tuple[BaselineMetrics, ...], requested: float
             ) -> tuple[TradeoffPoint, ...]:
    """The trade-off points: the plan, the baselines, and the requested point (the stiffness
    the plan's nominal errors need to hold the request: k_plan y / x; NaN if the plan holds
    any or no uncertainty)."""
    by = {b.name: b for b in baselines}
    plan = by["nlp"]
    pts = [TradeoffPoint("plan", plan.tolerated, plan.min_lateral_stiffness)]
    pts += [TradeoffPoint(b.name, b.tolerated, b.min_lateral_stiffness)
            for b in baselines if b.name != "nlp"]
    x = plan.tolerated
    k_need = (plan.min_lateral_stiffness * requested / x
              if np.isfinite(x) and x > 0 else float("nan"))
    pts.append(TradeoffPoint("requested", requested, k_need))
    return tuple(pts)


@dataclass(frozen=True)
class Lever:
    """One way to make a plan hold more force uncertainty.

    Attributes:
        name: ``placement``, ``force_model`` or ``realtime``.
        action: What to do (the command).
        need: What it must achieve, from the plan's numbers.
        gain: Measured gain in tolerated relative uncertainty (None: not measured).
        done: Already done for this plan (then it is reported, not advised).
    """

    name: str
    action: str
    need: str
    gain: float | None = None
    done: bool = False

    def text(self) -> str:
        """One line for the CLI."""
        gain = ("gain not measured by plan" if self.gain is None
                else f"measured gain {100 * self.gain:+.3g} points")
        head = "done: " if self.done else ""
        return f"{head}{self.action}: {self.need} ({gain})"

    def to_dict(self) -> dict[str, Any]:
        """JSON entry (gain in percentage points, null if not measured)."""
        return {"lever": self.name, "action": self.action, "need": self.need,
                "gain_pct_points": None if self.gain is None else 100 * self.gain,
                "done": self.done}


@dataclass(frozen=True)
class Verdict:
    """The verdict on a plan.

    Attributes:
        word: ``GO``, ``HOLDS NOMINALLY`` or ``NO``.
        tolerated: Tolerated relative force uncertainty of the written plan.
        requested: Requested relative force uncertainty.
        mirror: Tolerated uncertainty of the mirror baseline (NaN if unknown).
        robust_first: The plan maximised robustness before stiffness.
        levers: The three levers (HOLDS NOMINALLY), in the order to try them.
        reason: Why there is no plan (NO).
        refused: What is refused (NO): no plan, or the programs of a plan that holds.
    """

    word: str
    tolerated: float
    requested: float
    mirror: float = float("nan")
    robust_first: bool = True
    levers: tuple[Lever, ...] = ()
    reason: str = ""
    claim: RobustClaim | None = None
    position_control: bool = True
    refused: str = "no plan holds the weld envelope"

    @property
    def line(self) -> str:
        """The first line of ``rfsw-plan plan``."""
        if self.word == NO:
            return f"NO: {self.refused}: {self.reason}"
        every = "holds the weld envelope at every written sample"
        if self.word == GO:
            upto = ("under any force uncertainty" if self.tolerated == np.inf
                    else f"up to {pct(self.tolerated)} force uncertainty")
            return f"GO: {every} {upto}; the requested {pct(self.requested)} is held"
        first = ""
        if self.claim is not None:
            lim = self.claim.limiting
            at = f", at {lim.where}" if lim.where else ""
            first = f": {lim.quantity} limits it first{at}"
        return (f"HOLDS NOMINALLY: {every}, but under force uncertainty only up to "
                f"{pct(self.tolerated)}, not the requested {pct(self.requested)}{first}")

    @property
    def held(self) -> str:
        """The level every weld quantity holds, in the order the claim lists them:
        ``held per quantity: lateral +-11.4 %, depth +-2.14 %, tilt +-47.2 %, speed +-5.71 %``
        (empty without a claim); the depth under axial force control is the controller's; with
        the axial force coupled to the penetration the force model follows
        (``held per quantity (coupled axial law, k_p 1056 N/mm): ...``)."""
        if self.claim is None:
            return ""
        parts = [f"{q} {'the force loop' if q == 'depth' and not self.position_control else pct(u)}"
                 for q, u in self.claim.levels.items()]
        model = (f" ({self.claim.force_model})" if self.claim.penetration_stiffness > 0
                 else "")
        return f"held per quantity{model}: " + ", ".join(parts)

    @property
    def depth_note(self) -> str:
        """Where the depth limits under position control: what that means, first (empty
        otherwise)."""
        if (self.word != HOLDS_NOMINALLY or self.claim is None or not self.position_control
                or self.claim.limiting.quantity != "depth"):
            return ""
        return ("the depth limits in position control: the robot's axial deflection under "
                "the force spread moves the pin along the tool axis, and no pose holds it; "
                "under axial force control the set force is exact and the depth is the "
                "material's answer")

    @property
    def traded(self) -> str:
        """A note when the plan tolerates less than the mirror baseline because the user
        traded robustness for stiffness (``robust_first = false``), else empty."""
        if self.robust_first or not self.mirror > self.tolerated:
            return ""
        return (f"robust_first=false traded robustness for stiffness: the mirror baseline "
                f"holds {pct(self.mirror)} on the same waypoints")

    def to_dict(self) -> dict[str, Any]:
        """The ``plan.json`` entries (percent): the verdict, its text, what limits it
        (``limiting``: quantity, level, sample, t, phase, s; null for GO and NO) and the
        levers."""
        lim = None
        if self.claim is not None and self.word == HOLDS_NOMINALLY:
            m = self.claim.limiting
            lim = {"quantity": m.quantity, "tolerated_pct": m.level * 100,
                   m.kind: m.index + 1 if m.index >= 0 else None, "t_s": m.t,
                   "phase": m.phase or None, "s_mm": m.s * 1e3, "note": self.depth_note or None}
        return {"verdict": self.word, "verdict_text": self.line, "limiting": lim,
                "levers": [lv.to_dict() for lv in self.levers]}


#: The levers that raise a quantity's tolerated force uncertainty when it, not the lateral
#: error, limits it (the depth's first lever under position control is axial force control,
#: with its measured gain).
ROBUST_LEVERS = {
    "depth": "a wider depth window ([window] depth_shallow_mm / depth_deep_mm), or a placement "
             "stiffer along the plate normal (rfsw-plan place)",
    "tilt": "a wider [window] tilt_tol_deg, or a placement stiffer in rotation (rfsw-plan "
            "place)",
    "speed": "a wider [window] speed_tol_pct, or a placement stiffer along the seam "
             "(rfsw-plan place)",
}


def levers(plan: BaselineMetrics, requested: float, forces_calibrated: bool = False,
           measured_uncertainty: float | None = None) -> tuple[Lever, ...]:
    """The levers that raise the tolerated force uncertainty x to the requested y.

    First, when another quantity than the lateral error limits x, that quantity's own lever
    (:data:`ROBUST_LEVERS`), and for the depth under position
    control axial force control with the level the other quantities hold with the axial force
    exact (:attr:`~rfsw_plan.planning.verify.RobustClaim.axial_force_control`, its gain
    measured on the plan's model). Then the three that raise the stiffness-limited levels:

    1. a stiffer placement: the weakest lateral stiffness must rise by y / x (the trade-off's
       requested point);
    2. a force model calibrated on a trial weld (``plan --forces``): the real force spread must
       be within +-x %; when it was already used, it is reported as done with the measured
       spread (``measured_uncertainty``);
    3. real-time compensation on top of the plan (hybrid strategy of ``rfsw-plan compare``):
       it must remove the share 1 - x / y of the force-induced error.
    """
    x = plan.tolerated
    k = plan.min_lateral_stiffness
    own: list[Lever] = []
    claim = plan.claim
    if claim is not None and claim.limiting.quantity != "lateral":
        q = claim.limiting.quantity
        if q == "depth" and np.isfinite(claim.axial_force_control):
            fc = claim.axial_force_control
            own.append(Lever("axial_force_control", "axial force control ([process] "
                             "axial_control = \"force\": the set force exact, the depth the "
                             "material's answer)",
                             f"with the axial force exact the other quantities hold {pct(fc)}",
                             gain=fc - x if np.isfinite(fc) else None))
        own.append(Lever(q, f"the {q}'s own lever", ROBUST_LEVERS[q]))
    factor = requested / x if x > 0 else float("inf")
    q = "lateral" if claim is None else claim.limiting.quantity
    if not np.isfinite(factor):
        stiff = "the nominal error must first come inside the window"
    elif q == "lateral":
        stiff = (f"the weakest lateral stiffness must rise from {k * 1e-3:.0f} to "
                 f"{k * factor * 1e-3:.0f} N/mm (x{factor:.2f})")
    else:
        stiff = (f"the {q}'s worst case scales with the compliance: the stiffness behind it "
                 f"must rise x{factor:.2f}")
    out = [Lever("placement", "a stiffer placement (rfsw-plan place)", stiff)]
    if forces_calibrated:
        meas = ("" if measured_uncertainty is None
                else f"; the trial weld measured {pct(measured_uncertainty)}")
        out.append(Lever("force_model", "force model calibrated on a trial weld (plan --forces)",
                         f"planned with the calibrated uncertainty{meas}", done=True))
    else:
        out.append(Lever("force_model",
                         "a force model calibrated on a trial weld (plan --forces LOG.csv)",
                         f"the measured force spread must stay within {pct(x)}"))
    share = 1 - x / requested if requested > 0 else 0.0
    out.append(Lever("realtime", "real-time compensation on top of the plan (rfsw-plan "
                     "compare, hybrid strategy)",
                     f"it must remove {100 * share:.0f} % of the force-induced error"))
    return tuple(own + out)


def verdict_of(baselines: tuple[BaselineMetrics, ...], requested: float,
               robust_first: bool = True, forces_calibrated: bool = False,
               measured_uncertainty: float | None = None, position_control: bool = True
               ) -> Verdict:
    """The verdict on a written plan from its metrics (``nlp`` includes the samples);
    ``position_control``: the axial force is the process's answer to the robot's position
    (else the controller's set force)."""
    by = {b.name: b for b in baselines}
    plan = by["nlp"]
    mirror = by["mirror"].tolerated if "mirror" in by else float("nan")
    if plan.tolerated >= requested * (1 - HELD_RTOL):
        return Verdict(GO, plan.tolerated, requested, mirror, robust_first,
                       claim=plan.claim, position_control=position_control)
    return Verdict(HOLDS_NOMINALLY, plan.tolerated, requested, mirror, robust_first,
                   levers(plan, requested, forces_calibrated, measured_uncertainty),
                   claim=plan.claim, position_control=position_control)


#: What a NO refuses when the plan holds but a program of it, as its controller runs it, does
#: not hold what the plan verified (``export``'s judgement).
PROGRAM_REFUSED = ("the plan holds, but a program written from it does not as its controller "
                   "runs it")


def no_plan(reason: str, requested: float, refused: str = "") -> Verdict:
    """The verdict when the planner refuses (exit 3); ``refused`` says what is refused when
    it is not the plan itself (:data:`PROGRAM_REFUSED`)."""
    v = Verdict(NO, float("nan"), requested, reason=reason)
    return replace(v, refused=refused) if refused else v


__all__ = ["GO", "HOLDS_NOMINALLY", "NO", "PROGRAM_REFUSED", "Lever", "TradeoffPoint", "Verdict",
           "levers", "no_plan", "pct", "tradeoff", "verdict_of"]
