"""``tradeoff.png``: tolerated force uncertainty against the weakest lateral stiffness.

One point per strategy on the same waypoints (the plan, the mirror fake targets, no
compensation) and the requested point, all from :meth:`PlanResult.tradeoff` (the numbers of the
CLI table and of ``plan.json``). The dashed line is the plan's nominal errors on a robot
uniformly stiffer or softer: the worst case e +- u R has R proportional to the compliance
(seed 000 eq. 11), so the tolerated uncertainty grows in proportion to the stiffness,
u = x k / k_plan; it runs through the requested point, which says how much stiffer the robot
(placement) must be to hold the request with the plan's errors.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from rfsw_plan.files import write_figure
from rfsw_plan.planning.result import PlanResult

#: Marker and colour of each trade-off point.
STYLE = {"plan": ("o", "tab:blue", "plan (written)"), "mirror": ("s", "tab:orange",
                                                                   "mirror fake targets"),
         "none": ("v", "tab:red", "no compensation"), "requested": ("*", "k", "requested")}


def plot_tradeoff(path: str | Path, result: PlanResult) -> Path:
    """Draw ``tradeoff.png`` (1000 x 650 px) atomically; points with an infinite tolerated
    uncertainty (no lateral force) are left out and said so in the title."""
    from matplotlib.figure import Figure  # the object API; Agg draws it when saved

    from rfsw_plan.planfiles.waypoints import tight_layout

    pts = result.tradeoff()
    by = {p.name: p for p in pts}
    plan = by["plan"]
    fig = Figure(figsize=(10, 6.5), dpi=100)
    ax = fig.subplots()
    finite = [p for p in pts if np.isfinite(p.tolerated) and np.isfinite(
        p.min_lateral_stiffness)]
    ks = [p.min_lateral_stiffness * 1e-3 for p in finite]
    if np.isfinite(plan.tolerated) and plan.tolerated > 0 and ks:
        k = np.linspace(0.0, 1.15 * max(ks), 50)
        ax.plot(k, 100 * plan.tolerated * k / (plan.min_lateral_stiffness * 1e-3), "--",
                color="tab:blue", lw=1,
                label="the plan's nominal errors on a uniformly stiffer/softer robot")
    req = by["requested"]
    ax.axhline(100 * req.tolerated, color="k", lw=0.8, ls=":",
               label=f"requested +-{100 * req.tolerated:.3g} %")
    unwritten = {b.name: b.unwritten for b in result.baselines if b.unwritten}
    for p in finite:
        marker, colour, label = STYLE.get(p.name, ("x", "0.3", p.name))
        x, y = p.min_lateral_stiffness * 1e-3, 100 * p.tolerated
        held = (f"+-{y:.3g} %" if y > 0 else "holds none: cannot be written"
                if unwritten.get(p.name) else "holds none (nominal error outside)")
        ax.plot(x, y, marker, color=colour, ms=14 if marker == "*" else 9, clip_on=False,
                label=f"{label}: {held} at {x:.0f} N/mm", ls="none")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=-0.03 * ax.get_ylim()[1])
    ax.set_xlabel("weakest lateral stiffness 1 / (l^T C_tt l) [N/mm]")
    ax.set_ylabel("tolerated force uncertainty [+- %]")
    ax.grid(True, alpha=0.3)
    missing = [p.name for p in pts if p.tolerated == np.inf]
    note = f" (no lateral force: {', '.join(missing)} hold any)" if missing else ""
    title = f"{result.problem_name}: robustness against stiffness{note}. {result.verdict().line}"
    ax.set_title(textwrap.fill(title, 120), fontsize=10)
    ax.legend(loc="upper left", fontsize=9)
    tight_layout(fig)  # Figure.tight_layout(), saved with one draw
    out = Path(path)
    write_figure(out, fig, dpi=100)
    return out


__all__ = ["plot_tradeoff"]
