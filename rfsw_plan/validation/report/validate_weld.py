"""Report of ``rfsw-plan validate-weld``: ``report.html``, two PNGs and ``validate_weld.json``.

* ``weld_lateral.png``: measured and predicted lateral offset of the weld along s, with the
  weld-window band (and the re-identified model's prediction after ``--add``);
* ``weld_residual.png``: the residual against s and against time, with the best candidate's
  fit and the noise floor.

Every file is written atomically (:mod:`rfsw_plan.files`); the JSON is strict (no NaN).
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.files import write_figure, write_json, write_text
from rfsw_plan.validation.engine.candidates import PLAUSIBLE_FACTOR
from rfsw_plan.validation.report.html_page import PAGE_END, figure, page_head, table
from rfsw_plan.validation.weld.identifiability import IDENT_RATIO, PARAM_CHANGE
from rfsw_plan.validation.weld.workbench import WeldValidation

#: PNG size: 13 x 7.5 in at 110 dpi = 1430 x 825 px.
FIGSIZE = (13.0, 7.5)
DPI = 110


@dataclass(frozen=True)
class WeldReportFiles:
    """Paths written by :func:`write_weld_report`."""

    html: Path
    json: Path
    plots: dict[str, Path]


def make_weld_plots(result: WeldValidation, out: Path) -> dict[str, Path]:
    """Write the two PNGs (matplotlib, Agg; imported here)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mm = 1e3
    w = result.plan.problem.window
    s = result.track.s * mm
    files: dict[str, Path] = {}

    fig, ax = plt.subplots(figsize=FIGSIZE, constrained_layout=True)
    ax.axhspan(w.lower * mm, w.upper * mm, color="tab:green", alpha=0.15,
               label=f"weld window [{w.lower * mm:g}, {w.upper * mm:g}] mm")
    ax.plot(s, result.track.e_lat * mm, ".", ms=3, color="k", label="measured (track)")
    ax.plot(s, result.predicted_lat * mm, "-", color="tab:blue",
            label=f"predicted, current model ({', '.join(result.model.labels)})")
    if result.predicted_after is not None and result.add is not None:
        ax.plot(s, result.predicted_after * mm, "--", color="tab:red",
                label=f"predicted after adding {', '.join(result.add.labels)}")
    ax.set_xlabel("arc length s from the seam start [mm]")
    ax.set_ylabel("lateral offset of the weld [mm] (+ advancing side)")
    ax.set_title(f"{result.plan.problem.name}: measured vs predicted lateral offset "
                 f"(forces: {result.forces_source})")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=9, loc="best")
    p = out / "weld_lateral.png"
    write_figure(p, fig, dpi=DPI)
    plt.close(fig)
    files["lateral"] = p

    fig, (a1, a2) = plt.subplots(2, 1, figsize=FIGSIZE, constrained_layout=True)
    sig = result.diagnosis.sigma * mm
    for ax, x, lab in ((a1, s, "arc length s [mm]"), (a2, result.samples.t, "time [s]")):
        ax.axhspan(-sig, sig, color="0.85", label=f"+-noise floor {sig:.3f} mm")
        ax.plot(x, result.residual_lat * mm, ".", ms=3, color="k",
                label="lateral residual (measured - predicted)")
        if result.residual_norm is not None:
            ax.plot(x, result.residual_norm * mm, ".", ms=2, color="tab:purple", alpha=0.6,
                    label="normal residual")
        if result.predicted_after is not None:
            ax.plot(x, (result.predicted_after - result.predicted_lat) * mm, "-",
                    color="tab:red", label="fitted correction (the added effects)")
        ax.set_xlabel(lab)
        ax.set_ylabel("residual [mm]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    dg = result.diagnosis
    best = f", best candidate {dg.best.label}" if dg.best is not None else ""
    a1.set_title(f"Lateral residual, measured - predicted, along the seam and in time "
                 f"(verdict {dg.verdict}{best})")
    p = out / "weld_residual.png"
    write_figure(p, fig, dpi=DPI)
    plt.close(fig)
    files["residual"] = p
    return files


def _mm(v: float) -> str:
    return f"{v * 1e3:.4f}" if np.isfinite(v) else "-"


def render_weld_html(result: WeldValidation, plots: dict[str, Path], next_cmd: str) -> str:
    """The report as one self-contained HTML page (plots inline)."""
    dg = result.diagnosis
    js = result.to_json()
    e = html.escape
    parts: list[str] = [
        *page_head(f"rfsw-plan validate-weld: {result.plan.problem.name}"),
        f"<h1>Trial weld against the plan: {e(result.plan.problem.name)}</h1>",
        f"<p>Plan {e(str(result.plan.folder))}, robot {e(result.model.robot.name)} (effects "
        f"{e(', '.join(result.model.labels))}); forces: {e(result.forces_source)}; track: "
        f"{result.track.s.size} points over s = {result.track.overlap[0] * 1e3:.1f}.."
        f"{result.track.overlap[1] * 1e3:.1f} mm of {result.track.seam_length * 1e3:.1f} mm "
        f"({result.track.gaps} gaps). Candidates are scored by cross-validation over "
        "contiguous blocks of s (never random samples).</p>",
        f"<p class='verdict {dg.verdict}'><b>{dg.verdict.upper()}</b>: "
        f"{e(dg.message.removeprefix(f'{dg.verdict}: '))}</p>",
        f"<p><b>Next:</b> <code>{e(next_cmd)}</code></p>",
        "<h2>Measured against predicted</h2>",
        table(["quantity", "value"], [
            ["measured weld inside the window (share of the measured length)",
             f"{100 * js['measured_inside_window_fraction']:.1f} %"],
            ["predicted inside the window",
             f"{100 * js['predicted_inside_window_fraction']:.1f} %"],
            ["lateral residual RMS [mm]", _mm(float(np.sqrt(np.mean(result.residual_lat**2))))],
            ["lateral residual max |.| [mm]", _mm(float(np.max(np.abs(result.residual_lat))))],
            ["noise floor (successive differences) [mm]", _mm(dg.sigma)],
        ]),
        *(figure(p, k) for k, p in plots.items()),
        *_residual_3d_html(result),
        "<h2>What this weld can identify</h2>",
        f"<p>{e(dg.identifiability.text()).replace(chr(10), '<br>')}</p>",
        "<p>A straight weld at one pose sees only a few directions of the compliance: the "
        "candidates listed as explaining it as well cannot be told apart by this track; a "
        "second weld at another pose or direction, or a load campaign (<code>rfsw-plan "
        "validate</code>), separates them.</p>",
        "<h2>Candidates</h2>",
        table(["candidate", "held-out RMS [mm]", "RMS [mm]", "F", "significant",
                "identifiable", "tells from best", "plausible", "fitted"],
               [[c.label + (" (named)" if dg.best is not None and c.label == dg.best.label
                            else ""),
                 _mm(c.rms_after), _mm(c.fit_rms), f"{c.f_stat:.3g}",
                 "yes" if c.significant else "no", "yes" if c.identifiable else "no",
                 "no" if c.label in dg.ties else "yes",
                 "yes" if c.plausible else f"no: {c.implausible}",
                 ", ".join([*(f"{k} {v:.4g}" for k, v in c.params.items()),
                            *([] if c.stiffness_scale is None else
                              [f"stiffness x{c.stiffness_scale:.3f}"])])]
                for c in dg.candidates[:25]]),
        "<p>Sorted by held-out RMS. The named candidate is the simplest (fewest parameters) "
        "among the best and those this weld cannot tell from it; an implausible fit (a joint "
        f"stiffness more than {PLAUSIBLE_FACTOR:g} x off the robot file) is never named.</p>",
        f"<p>Identifiable: every parameter's standard error below "
        f"{100 * PARAM_CHANGE / IDENT_RATIO:.1f} % of its size.</p>",
    ]
    if result.add is not None:
        a = result.add
        parts += ["<h2>Re-identified (the added effects)</h2>", table(
            ["quantity", "value"],
            [["added", ", ".join(a.labels)],
             ["RMS before / after [mm]", f"{_mm(a.rms_before)} / {_mm(a.rms_after)}"],
             ["held-out RMS after [mm]", _mm(a.heldout_after)],
             *[[lab, ", ".join(f"{k} {v:.5g}" for k, v in p.items())]
               for lab, p in a.params.items()]])]
    if result.notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{e(n)}</li>" for n in result.notes)
                     + "</ul>")
    parts.append(PAGE_END)
    return "\n".join(parts)


def _residual_3d_html(result: WeldValidation) -> list[str]:
    """The residual at each track point in 3-D (issue 35): an arrow from the seam point along
    the lateral (and normal, if measured) residual, magnified; before and after ``--add``."""
    from rfsw_plan.planfiles.page3d import residual_section

    sm = result.samples

    def lateral_rms(r: np.ndarray) -> str:
        return f"lateral residual RMS {_mm(float(np.sqrt(np.mean(r**2))))} mm"

    before = result.residual_lat[:, None] * sm.l
    if result.residual_norm is not None:
        before = before + result.residual_norm[:, None] * sm.n
    sets = [("model as given: " + ", ".join(result.model.labels), before * 1e3,
             lateral_rms(result.residual_lat))]
    if result.add is not None and result.predicted_after is not None:
        after = result.track.e_lat - result.predicted_after
        sets.append(("re-identified: + " + ", ".join(result.add.labels), after[:, None] * sm.l
                     * 1e3, lateral_rms(after)))
    return [residual_section(sm.p * 1e3, sets, "Residual along the seam in 3-D",
                             "One arrow per track point, at the seam point (base frame), along "
                             "the measured - predicted lateral offset (and normal offset where "
                             "the track has one).")]


def write_weld_report(result: WeldValidation, out: Path, next_cmd: str,
                      extra: dict[str, Any] | None = None) -> WeldReportFiles:
    """Write the PNGs, ``validate_weld.json`` and ``report.html`` (atomically) into ``out``
    (already checked with :func:`~rfsw_plan.files.prepare_output_dir`)."""
    plots = make_weld_plots(result, out)
    data = result.to_json()
    data["next_command"] = next_cmd
    data.update(extra or {})
    json_path = write_json(out / "validate_weld.json", data)
    html_path = write_text(out / "report.html", render_weld_html(result, plots, next_cmd))
    return WeldReportFiles(html_path, json_path, plots)
