"""How much force uncertainty a plan tolerates, and the options the NLP pursues it with.

The plan's claim covers the whole weld envelope (lateral error, depth, tilt, pin speed at the
vertices of the force box: :func:`rfsw_plan.planning.verify.robust_claim`); the NLP pursues the
lateral error's part of it, below. The lateral error's tolerated force uncertainty of joint
values q on a task is the largest uniform u for which
the worst case of the lateral pin error over the force box |delta f_i| <= u |f_i| (seam-frame
components) stays in the weld window: e_k +- u R_k with R_k = sum_i |f_i| |l^T C_tt b_i|
(deflection linear in F; seed 000 eq. 11), so u = min_k dist_k / R_k, dist_k the distance of
e_k to the nearest window bound (:func:`rfsw_plan.planning.verify.tolerated_uncertainty`).

Robust first (``robust_first = true``, the default). The NLP's robust rows hold a share rho in
[0, 1] of the uncertainty it is given (:mod:`rfsw_plan.planning.nlp`). Given the requested u,
the NLP stops at rho = 1: once the request is held at the waypoints, stiffness, smoothness and
proximity spend the rest of the window, and the nominal error drifts toward a bound. That is
why, on zk500_table6_seam at +-10 %, the plan held +-10 % at its waypoints and +-9.68 % at the
written samples in between, while the mirror baseline (nominal error 0) held +-12 %; and why
+-10 % gave a less robust plan than +-20 % (+-16.7 %: there rho < 1 and the NLP maximised it).
Robust first gives the NLP ``ROBUST_CEILING`` instead, whatever is requested: rho u is then
maximised (lexicographically before stiffness, by the weight ``w_robust``), the plan does not
depend on the request below the ceiling (so asking for less never gives a less robust plan),
and the request decides only the verdict (:mod:`rfsw_plan.planning.verdict`).

Lexicographic in two stages (:func:`rfsw_plan.planning.api.plan_task`): the first stage
maximises the tolerated uncertainty x*; its mean-excess term also pushes every waypoint toward
the ceiling, which on kr600_curved_seam's offset head swung the tool about its axis by 12.8 deg
between 1.2 mm waypoints and put the pin 46 % off the weld speed between them. The second stage
holds x* (less ``SECOND_STAGE_SLACK``) and spends the rest of the window on stiffness,
smoothness and proximity: 3.5 deg, 2.9 %, and +-16.7 % instead of +-10.7 % for the old planner.
"""

from __future__ import annotations

from dataclasses import replace

from rfsw_plan.process.plan_options import PlanOptions

#: The force uncertainty the robust-first NLP pursues (1.0 = +-100 %): above it the window's
#: worst case is no longer what limits a weld, so the NLP stops buying robustness there.
ROBUST_CEILING = 1.0
#: The second stage holds the first stage's tolerated uncertainty less this share (1 %), so
#: the written samples between waypoints stay above it.
SECOND_STAGE_SLACK = 0.01
#: A plan may tolerate this much less force uncertainty than a baseline before the planner
#: falls back to the baseline (0.1 percentage point; the NLP's smooth |x| and the written
#: samples between waypoints account for less).
DOMINANCE_TOL = 1e-3


def nlp_options(opts: PlanOptions) -> PlanOptions:
    """The options the NLP is built with: robust first, the requested uncertainty raised to
    :data:`ROBUST_CEILING` with a soft robust window (the requested one is checked after the
    solve, hard with ``robust_hard``); otherwise ``opts`` unchanged."""
    if not opts.robust_first:
        return opts
    return replace(opts, force_uncertainty=max(opts.force_uncertainty, ROBUST_CEILING),
                   robust_hard=False)


__all__ = ["DOMINANCE_TOL", "ROBUST_CEILING", "SECOND_STAGE_SLACK", "nlp_options"]
