"""The validation report: ``report.html`` (self-contained), PNG plots and ``validate.json``.

The HTML embeds every plot as a base64 PNG and uses no external resource, so it opens in a
browser without network. Matplotlib is imported lazily (Agg backend).
"""

from __future__ import annotations

import html
import json
import math
import shlex
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.files import without_wall_times, write_figure, write_text
from rfsw_plan.validation.engine.diagnosis import Skipped
from rfsw_plan.validation.report.html_page import PAGE_END, figure, page_head, table
from rfsw_plan.validation.workbench import ValidationResult

#: At most this many points are drawn per scatter plot (a seeded random subset).
MAX_POINTS = 4000
#: Width of every PNG plot [px].
PNG_WIDTH_PX = 1200
_OUTSIDE = {"loc": "upper left", "bbox_to_anchor": (1.01, 1.0), "borderaxespad": 0.0}
_AXIS_COLORS = ("tab:red", "tab:green", "tab:blue")


@dataclass(frozen=True)
class ReportFiles:
    """Files written by :func:`write_report`.

    Attributes:
        html: The self-contained report.
        json: ``validate.json``.
        plots: PNG plots by name.
    """

    html: Path
    json: Path
    plots: dict[str, Path]


def _json_default(o: Any) -> Any:
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _clean(o: Any) -> Any:
    """Replace NaN/inf by None so that the JSON is strict."""
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, list | tuple):
        return [_clean(v) for v in o]
    if isinstance(o, float | np.floating) and not math.isfinite(float(o)):
        return None
    return o


def result_json(result: ValidationResult, wall_times: bool = True) -> str:
    """The validation result as one strict JSON object (NaN -> null); ``wall_times`` False:
    without them (``validate.json``, :func:`without_wall_times`)."""
    data = result.to_json()
    return json.dumps(_clean(data if wall_times else without_wall_times(data)), indent=2,
                      default=_json_default, allow_nan=False)


# --------------------------------------------------------------------------------------------
# Plots


def _subset(m: int) -> np.ndarray:
    if m <= MAX_POINTS:
        return np.arange(m)
    return np.sort(np.random.default_rng(0).choice(m, MAX_POINTS, replace=False))


def _scatter_axes(ax: Any, x: np.ndarray, res_mm: np.ndarray, idx: np.ndarray) -> None:
    for a in range(3):
        ok = np.isfinite(res_mm[idx, a])
        if np.any(ok):
            ax.scatter(x[idx][ok], res_mm[idx, a][ok], s=3, alpha=0.5, color=_AXIS_COLORS[a],
                       label="xyz"[a], rasterized=True)
    ax.axhline(0.0, color="k", lw=0.5)


def _histogram(plt: Any, res_mm: np.ndarray, noise_mm: float | None) -> Any:
    """Histogram of the residual per axis, with the +-1 sigma noise floor where known."""
    fig, ax = plt.subplots(figsize=(6, 3.5), layout="constrained")
    for a in range(3):
        v = res_mm[:, a][np.isfinite(res_mm[:, a])]
        if v.size:
            ax.hist(v, bins=60, histtype="step", color=_AXIS_COLORS[a], label="xyz"[a])
    if noise_mm:
        ax.axvline(-noise_mm, color="k", ls="--", lw=0.8, label="+-1 sigma noise floor")
        ax.axvline(noise_mm, color="k", ls="--", lw=0.8)
        lo, hi = ax.get_xlim()
        ax.set_xlim(min(lo, -1.2 * noise_mm), max(hi, 1.2 * noise_mm))
        # two lines: on one, the title was wider than the 6-inch figure and clipped
        ax.set_title(f"Residual distribution\n(dashed: +-1 sigma noise floor, {noise_mm:.3g} mm)")
    else:
        ax.set_title("Residual distribution (noise floor unknown)")
    ax.set_xlabel("residual measured - predicted [mm]")
    ax.set_ylabel("samples")
    ax.legend(**_OUTSIDE)
    return fig


def _vs_time(plt: Any, result: ValidationResult, res_mm: np.ndarray, idx: np.ndarray) -> Any:
    """Residual against time (or sample order) and the extra columns."""
    an = result.analysis
    seq = [k for k in ("time", "sample_order") if k in an.features]
    cols = seq + [k for k in an.features if k in result_extra_names(result)]
    fig, axes = plt.subplots(len(cols), 1, figsize=(7, 2.6 * len(cols)), squeeze=False,
                             layout="constrained")
    for ax, name in zip(axes[:, 0], cols, strict=True):
        _scatter_axes(ax, np.asarray(an.features[name], dtype=float), res_mm, idx)
        ax.set_xlabel("t [s]" if name == "time" else name)
        ax.set_ylabel("residual [mm]")
    axes[0, 0].legend(markerscale=3, **_OUTSIDE)
    axes[0, 0].set_title("Residual against time and extra columns")
    return fig


def _vs_torque(plt: Any, result: ValidationResult, res_mm: np.ndarray, idx: np.ndarray) -> Any:
    """Residual against each joint torque (force, for a prismatic joint)."""
    tau = result.analysis.tau
    prismatic = list(result.model.robot.prismatic)
    n = tau.shape[1]
    ncol = 3
    nrow = math.ceil(n / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(10, 2.8 * nrow), squeeze=False,
                             layout="constrained")
    for j in range(nrow * ncol):
        ax = axes[j // ncol, j % ncol]
        if j >= n:
            ax.axis("off")
            continue
        _scatter_axes(ax, tau[:, j] / 1e3, res_mm, idx)
        pj = j < len(prismatic) and prismatic[j]
        ax.set_xlabel(f"joint {j + 1} {'force [kN]' if pj else 'torque [kN m]'}")
        ax.set_ylabel("residual [mm]")
    axes[0, ncol - 1].legend(markerscale=3, **_OUTSIDE)
    fig.suptitle("Residual against each joint torque J^T F")
    return fig


def _vs_force(plt: Any, result: ValidationResult, res_mm: np.ndarray, idx: np.ndarray) -> Any:
    """Residual against force magnitude and elevation."""
    an = result.analysis
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.5), layout="constrained")
    f = np.asarray(an.features["force_magnitude"], dtype=float)
    u = np.asarray(an.features["force_direction"], dtype=float)
    elev = np.degrees(np.arcsin(np.clip(u[:, 2], -1, 1)))
    _scatter_axes(axes[0], f / 1e3, res_mm, idx)
    axes[0].set_xlabel("|f| [kN]")
    axes[0].set_ylabel("residual [mm]")
    _scatter_axes(axes[1], elev, res_mm, idx)
    axes[1].set_xlabel("force elevation above the base xy plane [deg]")
    axes[1].legend(markerscale=3, **_OUTSIDE)
    fig.suptitle("Residual against force magnitude and direction")
    return fig


def _workspace(plt: Any, result: ValidationResult, res_mm: np.ndarray, idx: np.ndarray) -> Any:
    """|residual| over the TCP positions, two views of the base frame."""
    norm = np.sqrt(np.nansum(res_mm**2, axis=1))
    tcp = result.analysis.tcp
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), layout="constrained")
    for ax, (a, b, la, lb) in zip(axes, ((0, 1, "x", "y"), (0, 2, "x", "z")), strict=True):
        sc = ax.scatter(tcp[idx, a], tcp[idx, b], c=norm[idx], s=8, cmap="viridis",
                        rasterized=True)
        ax.set_xlabel(f"TCP {la} [m]")
        ax.set_ylabel(f"TCP {lb} [m]")
        ax.set_aspect("equal", adjustable="datalim")
        fig.colorbar(sc, ax=ax, label="|residual| [mm]")
    fig.suptitle("Where in the workspace the model fails (base frame)")
    return fig


def _candidates(plt: Any, result: ValidationResult, noise_mm: float | None) -> Any:
    """Held-out RMS of the best candidates against the current model and the floor."""
    dg = result.diagnosis
    cands = dg.candidates[:15]
    if not cands:
        return None
    fig, ax = plt.subplots(figsize=(7, 0.35 * len(cands) + 1.5), layout="constrained")
    y = np.arange(len(cands))
    colors = ["tab:green" if c.significant else "tab:gray" for c in cands]
    ax.barh(y, [c.rms_after * 1e3 for c in cands], color=colors)
    ax.set_yticks(y, [c.label for c in cands])
    ax.invert_yaxis()
    ax.axvline(dg.heldout_rms * 1e3, color="tab:red", label="current model")
    if noise_mm:
        ax.axvline(noise_mm, color="k", ls="--", label="noise floor")
    ax.set_xlabel("held-out RMS with the effect added [mm]")
    ax.set_title("Candidate effects (green: significant)")
    ax.legend(**_OUTSIDE)
    return fig


def _correlations(plt: Any, result: ValidationResult) -> Any:
    """R^2 of the held-out residual against each feature."""
    corr = result.diagnosis.correlations[:12]
    if not corr:
        return None
    fig, ax = plt.subplots(figsize=(7, 0.35 * len(corr) + 1.5), layout="constrained")
    y = np.arange(len(corr))
    ax.barh(y, [c.r2 for c in corr],
            color=["tab:orange" if c.significant else "tab:gray" for c in corr])
    ax.set_yticks(y, [c.feature for c in corr])
    ax.invert_yaxis()
    ax.set_xlim(0, 1)
    ax.set_xlabel("share of the held-out residual explained (R^2)")
    ax.set_title("What the residual correlates with (orange: significant)")
    return fig


def _before_after(plt: Any, result: ValidationResult, noise_mm: float | None) -> Any:
    """Held-out RMS before and after adding effects (log scale), with the noise floor."""
    ad = result.add
    if ad is None:
        return None
    fig, ax = plt.subplots(figsize=(10, 4), layout="constrained")
    labels = ["before", "after\n+" + "\n+".join(ad.added) if ad.added else "after"]
    vals = [ad.before.heldout_rms * 1e3, ad.after.heldout_rms * 1e3]
    bars = ax.bar(labels, vals, color=["tab:red", "tab:green"])
    ax.bar_label(bars, labels=[f"{v:.4g} mm" for v in vals], padding=2)
    # Log scale: the error typically falls by orders of magnitude, and the noise-floor
    # lines (1x and 1.5x) would sit on top of each other near zero on a linear axis.
    ax.set_yscale("log")
    if noise_mm:
        ax.axhline(noise_mm, color="k", ls="--", lw=1.2, label=f"noise floor {noise_mm:.3g} mm")
        ax.axhline(1.5 * noise_mm, color="tab:blue", ls=":", lw=1.6,
                   label=f"1.5 x noise floor {1.5 * noise_mm:.3g} mm (adequate below)")
        ax.legend(**_OUTSIDE)
    else:
        ax.text(0.99, 0.97, "noise floor unknown", transform=ax.transAxes, ha="right",
                va="top")
    lo = min([*vals, noise_mm or min(vals)])
    ax.set_ylim(lo / 3.0, max(vals) * 3.0)
    ax.set_ylabel("held-out RMS [mm] (log scale)")
    ax.set_title("Adding effects: error on data the fit did not see")
    return fig


def make_plots(result: ValidationResult, out_dir: Path) -> dict[str, Path]:
    """Draw the report's PNG plots into ``out_dir``; returns name -> path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dg = result.diagnosis
    res_mm = result.analysis.residual * 1e3
    idx = _subset(res_mm.shape[0])
    noise_mm = None if dg.noise.sigma is None else dg.noise.sigma * 1e3
    figures = {
        "residual_histogram": lambda: _histogram(plt, res_mm, noise_mm),
        "residual_vs_time": lambda: _vs_time(plt, result, res_mm, idx),
        "residual_vs_torque": lambda: _vs_torque(plt, result, res_mm, idx),
        "residual_vs_force": lambda: _vs_force(plt, result, res_mm, idx),
        "workspace_map": lambda: _workspace(plt, result, res_mm, idx),
        "candidates": lambda: _candidates(plt, result, noise_mm),
        "correlations": lambda: _correlations(plt, result),
        "before_after": lambda: _before_after(plt, result, noise_mm),
    }
    plots: dict[str, Path] = {}
    for name, draw in figures.items():
        fig = draw()
        if fig is None:
            continue
        path = out_dir / f"{name}.png"
        # Figures use constrained layout, which keeps the outside legends in the figure in one
        # drawing pass (bbox_inches="tight" draws twice); PNG_WIDTH_PX wide whatever the size.
        write_figure(path, fig, dpi=PNG_WIDTH_PX / fig.get_figwidth())
        plt.close(fig)
        plots[name] = path
    return plots


def result_extra_names(result: ValidationResult) -> list[str]:
    """Names of the extra numeric columns present in the features."""
    n = result.analysis.tau.shape[1]
    known = {"time", "sample_order", "force_magnitude", "force_direction", "tcp_position"}
    known |= {f"q{j + 1}" for j in range(n)} | {f"tau_j{j + 1}" for j in range(n)}
    return [k for k in result.analysis.features if k not in known]


# --------------------------------------------------------------------------------------------
# HTML


def _f(v: float | None, scale: float = 1e3, digits: int = 4) -> str:
    """A length [m] in mm with ``digits`` decimals (0.1 um resolution): fixed point, so a
    vanishing residual reads 0.0000, not 5.6e-13."""
    if v is None or not math.isfinite(v):
        return "-"
    return f"{v * scale:.{digits}f}"


def _num(v: float) -> str:
    """A parameter value: plain decimals between 1e-3 and 1e6, else scientific."""
    if not math.isfinite(v):
        return "-"
    if v == 0.0 or 1e-3 <= abs(v) < 1e6:
        return f"{v:.5g}"
    return f"{v:.4e}"


def engineering(value: float, unit: str) -> str:
    """The engineering reading of an SI parameter value, or "" when SI is what users read.

    A compliance c [rad/(N m)] reads as the stiffness k = 1/c in N m/rad and kN m/deg (a
    linear one [m/N], of a prismatic joint, in N/m and kN/mm); an angle [rad] in mrad and
    degrees; a length [m] in mm.
    """
    if not math.isfinite(value):
        return ""
    if unit == "rad/(N m)":
        if value <= 0.0:
            return "rigid"
        k = 1.0 / value
        return f"k = {k:.4g} N m/rad = {k * math.pi / 180.0 / 1e3:.4g} kN m/deg"
    if unit == "m/N":
        if value <= 0.0:
            return "rigid"
        k = 1.0 / value
        return f"k = {k:.4g} N/m = {k / 1e6:.4g} kN/mm"
    if unit == "rad":
        return f"{value * 1e3:.4g} mrad = {math.degrees(value):.4g} deg"
    if unit == "m":
        return f"{value * 1e3:.4g} mm"
    return ""


def next_command(result: ValidationResult, argv: list[str] | None) -> str:
    """The command to run next, ready to copy, from the command line that made ``result``.

    ``missing``: the same command with ``--add`` for the named effects and ``--save-robot``;
    ``undetermined``: the same command with ``--noise-mm`` (the measuring device's 1-sigma);
    ``adequate``: nothing to add; ``unexplained``: no library effect helps (see the
    correlations). Returns "" when the command line is unknown (API use).
    """
    if not argv:
        return ""
    dg = result.diagnosis
    base = [a for a in argv if a not in ("--json",)]
    if dg.verdict == "missing":
        labels = [st.label for st in dg.chain] or [dg.candidates[0].label]
        extra: list[str] = []
        for lab in labels:
            extra += ["--add", lab]
        from rfsw_plan.robot.description import derived_file

        stem = result.robot.replace("/", "_").removesuffix(".toml")
        extra += ["--save-robot", derived_file(f"{stem}+{'+'.join(labels)}")]
        return "rfsw-plan " + " ".join(shlex.quote(a) for a in [*base, *extra])
    if dg.verdict == "undetermined":
        return ("rfsw-plan " + " ".join(shlex.quote(a) for a in base)
                + " --noise-mm SIGMA   # your measuring device's 1-sigma noise [mm]")
    return ""


def model_title(result: ValidationResult) -> str:
    """The evaluated model in words: the robot, and the effects added to it if any
    (``zk500 + payload_gravity (added and re-identified)``)."""
    added = () if result.add is None else result.add.added
    if not added:
        return result.robot
    return f"{result.robot} + {' + '.join(added)} (added and re-identified)"


def render_html(result: ValidationResult, plots: dict[str, Path],
                argv: list[str] | None = None) -> str:
    """The report as one self-contained HTML string (plots inline).

    Args:
        result: The validation result.
        plots: PNG plots by name (:func:`make_plots`).
        argv: The command line (without the program name) that made ``result``, to print the
            next command ready to copy; None for API use.
    """
    dg = result.diagnosis
    an = result.analysis
    title = model_title(result)
    parts: list[str] = [
        *page_head(f"rfsw-plan validate: {title}"),
        f"<h1>Model against measurement: {html.escape(title)}</h1>",
        f"<p>Data: {html.escape(result.data_source)} ({an.n_samples} samples, "
        f"{an.n_observations} measured values). Model effects: "
        f"{html.escape(', '.join(result.model.labels))}. {dg.folds}-fold cross-validation "
        "grouped by pose.</p>",
        f"<p class='verdict {dg.verdict}'><b>{dg.verdict.upper()}</b>: "
        f"{html.escape(dg.message.removeprefix(f'{dg.verdict}: '))}</p>",
        *_next_step_html(result, argv),
        *_summary_html(result),
        *_add_html(result, plots),
        *_candidates_html(result, plots),
        *_correlations_html(result, plots),
        *_where_html(result),
        *_residual_3d_html(result),
    ]
    for name, alt in (
        ("residual_histogram", "residual histogram"),
        ("workspace_map", "workspace map"),
        ("residual_vs_torque", "residual against joint torques"),
        ("residual_vs_force", "residual against force"),
        ("residual_vs_time", "residual against time"),
    ):
        if name in plots:
            parts.append(figure(plots[name], alt))
    parts.append(PAGE_END)  # no wall time: the same input writes the same bytes
    return "\n".join(parts)


def _summary_html(result: ValidationResult) -> list[str]:
    dg = result.diagnosis
    an = result.analysis
    return ["<h2>Summary</h2>", table(
        ["quantity", "value [mm]"],
        [
            ["RMS residual of the model (all samples)", _f(result.rms)],
            ["held-out RMS (model re-identified per fold)", _f(dg.heldout_rms)],
            ["RMS after re-identifying on all samples", _f(result.identification.rms_after)],
            [f"noise floor (1 sigma, {dg.noise.source})", _f(dg.noise.sigma)],
            ["max |residual|", _f(an.max_abs)],
            *[[f"{p:g}th percentile of |residual|", _f(v)] for p, v in an.percentiles.items()],
        ],
    )]


def _add_html(result: ValidationResult, plots: dict[str, Path]) -> list[str]:
    if result.add is None:
        return []
    ad = result.add
    units = _param_units(result)
    parts = [
        "<h2>Adding effects and re-identifying</h2>",
        table(
            ["model", "held-out RMS [mm]", "RMS all samples [mm]"],
            [
                [", ".join(ad.before.labels), _f(ad.before.heldout_rms), _f(ad.rms_before)],
                [", ".join(ad.after.labels), _f(ad.after.heldout_rms), _f(ad.rms_after)],
            ],
        ),
    ]
    if ad.not_added:
        parts.append("<p>Not fitted: " + html.escape(
            "; ".join(f"{s.label}: {s.reason}" for s in ad.not_added)) + "</p>")
    parts.append(table(
        ["effect", "parameter", "value [SI]", "unit", "engineering", "std error",
         "prior [SI]", "note"],
        [[e.effect, e.name, _num(e.value), units.get((e.effect, e.name), ""),
          engineering(e.value, units.get((e.effect, e.name), "")),
          _num(e.std_error), _num(e.prior), e.note] for e in ad.after.fit.estimates],
    ))
    if "before_after" in plots:
        parts.append(figure(plots["before_after"], "held-out RMS before and after"))
    return parts


def _candidates_html(result: ValidationResult, plots: dict[str, Path]) -> list[str]:
    dg = result.diagnosis
    parts = [
        "<h2>Diagnosis: candidate effects</h2>",
        "<p>Each effect is added to the current model, all parameters are re-identified on "
        "the training folds and the model is scored on the held-out fold. Significant = the "
        "held-out improvement passes an F test at the strict level (noise alone does not) "
        "and the fitted values lie in the effect's physical range.</p>",
        table(
            ["effect", "joint", "held-out RMS after [mm]", "explained fraction", "p-value",
             "significant", "note"],
            [[c.effect, "-" if c.joint is None else str(c.joint), _f(c.rms_after),
              f"{c.explained_fraction:.3f}", f"{c.p_value:.2g}",
              "yes" if c.significant else "no",
              "; ".join(x for x in ("indistinguishable from the best" if c.tied_with_best
                                    else "", c.implausible) if x)]
             for c in dg.candidates],
        ),
    ]
    if "candidates" in plots:
        parts.append(figure(plots["candidates"], "candidates"))
    parts += selection_html(result)
    if dg.skipped:
        parts += ["<h3>Not identifiable from this data (not fitted)</h3>",
                  "<p>For a reason of identifiability only: the data do not move the TCP "
                  "with it (rank), its parameters cannot be told apart (conditioning, "
                  "correlation with a named effect, with the number), or too few samples on "
                  "each side of a play.</p>",
                  table(["reason", "effects"], [[why, ", ".join(labels)] for why, labels
                                                in skipped_by_reason(dg.skipped).items()])]
    if dg.not_supported:
        parts += ["<h3>Not supported by this data</h3>",
                  "<p>Identifiable, but the fit puts them outside their physical range (a "
                  "negative play or compliance): the data give no evidence for them.</p>",
                  table(["reason", "effects"], [[why, ", ".join(labels)] for why, labels
                                                in skipped_by_reason(dg.not_supported).items()])]
    if dg.indeterminate:
        parts += ["<h3>Readings of unknown state</h3>",
                  "<p>Nothing before them in the data sets their state (the side of a play): "
                  "the held-out score measures them against the model's stated spread, never "
                  "against a state read from themselves.</p>",
                  "<ul>" + "".join(f"<li>{html.escape(x.line())}</li>"
                                   for x in dg.indeterminate) + "</ul>"]
    if dg.advice:
        parts += ["<h3>What the next campaign should add</h3>",
                  "<ul>" + "".join(f"<li>{html.escape(a)}</li>" for a in dg.advice) + "</ul>"]
    return parts


def selection_html(result: ValidationResult) -> list[str]:
    """The forward selection's steps: effect added, held-out RMS, share explained."""
    dg = result.diagnosis
    if not dg.chain:
        return ["<h3 id='selection'>Forward selection</h3>",
                f"<p>No effect added: {html.escape(dg.stop)}.</p>"]
    floor = _f(dg.noise.sigma)
    return [
        "<h3 id='selection'>Forward selection</h3>",
        "<p>Each step tests every effect the model still lacks (re-identifying all "
        "parameters on the training folds), adds the one named by the held-out F test and "
        "starts the next step from it. Share explained: of the held-out mean square of the "
        f"model the selection started from. Noise floor {floor} mm. Stopped: "
        f"{html.escape(dg.stop)}.</p>",
        table(
            ["step", "effect added", "held-out RMS before [mm]", "after [mm]",
             "this step explains", "share explained", "after / floor", "p-value",
             "the data cannot tell it from"],
            [[str(i + 1), s.label, _f(s.rms_before), _f(s.rms_after),
              f"{100 * s.explained_fraction:.1f} %", f"{100 * s.share_explained:.2f} %",
              "-" if dg.noise.sigma is None else f"{s.rms_after / dg.noise.sigma:.3g}",
              f"{s.p_value:.2g}", ", ".join(s.ties) or "-"]
             for i, s in enumerate(dg.chain)],
        ),
    ]


def skipped_by_reason(skipped: Sequence[Skipped]) -> dict[str, list[str]]:
    """The candidates not fitted, grouped by their reason (one row per reason, not one
    sentence repeated for every joint)."""
    out: dict[str, list[str]] = {}
    for s in skipped:
        out.setdefault(s.reason, []).append(s.label)
    return out


def _correlations_html(result: ValidationResult, plots: dict[str, Path]) -> list[str]:
    dg = result.diagnosis
    parts = [
        "<h2>What the residual correlates with</h2>",
        "<p>Share of the held-out residual explained by each feature (cubic fit for a "
        "scalar, quadratic for a vector). A strong feature outside the library (time, "
        "temperature) points at physics the model lacks.</p>",
        table(
            ["feature", "R^2", "adjusted R^2", "p-value", "significant", "what"],
            [[c.feature, f"{c.r2:.3f}", f"{c.adj_r2:.3f}", f"{c.p_value:.2g}",
              "yes" if c.significant else "no", c.description] for c in dg.correlations],
        ),
    ]
    if "correlations" in plots:
        parts.append(figure(plots["correlations"], "correlations"))
    return parts


def _where_html(result: ValidationResult) -> list[str]:
    an = result.analysis
    prismatic = list(result.model.robot.prismatic)

    def trange(j: int, lo: float, hi: float) -> str:
        unit = "kN" if j - 1 < len(prismatic) and prismatic[j - 1] else "kN m"
        return f"{lo / 1e3:.3g} .. {hi / 1e3:.3g} {unit}"

    return [
        "<h2>Where the model fails</h2>",
        "<h3>Per axis and per direction</h3>",
        table(
            ["axis", "n", "RMS [mm]", "mean [mm]", "max |r| [mm]"],
            [[a.name, str(a.n), _f(a.rms), _f(a.mean), _f(a.max_abs)]
             for a in (*an.per_axis, *an.per_direction)],
        ),
        "<h3>Per joint</h3>",
        table(
            ["joint", "torque (force) range", "R^2 torque", "R^2 angle", "R^2 joint motion",
             "RMS tau>0 [mm]", "RMS tau<0 [mm]"],
            [[str(j.joint), trange(j.joint, j.tau_min, j.tau_max),
              f"{j.r2_torque:.3f}", f"{j.r2_angle:.3f}", f"{j.r2_joint_motion:.3f}",
              _f(j.rms_tau_pos), _f(j.rms_tau_neg)] for j in an.per_joint],
        ),
    ]


def _residual_3d_html(result: ValidationResult) -> list[str]:
    """The residual per pose in 3-D (issue 35): arrows from the nominal TCP, magnified, before
    and after the named effect (held-out residuals of both forms) when effects were added,
    else the residual of the model."""
    from rfsw_plan.planfiles.page3d import residual_section

    ad = result.add
    if ad is not None:
        after = "+".join(ad.added) if ad.added else "nothing added"
        sets = [("before: " + "+".join(ad.before.labels), ad.before.heldout_residual * 1e3,
                 f"held-out RMS {ad.before.heldout_rms * 1e3:.4f} mm"),
                (f"after: + {after}", ad.after.heldout_residual * 1e3,
                 f"held-out RMS {ad.after.heldout_rms * 1e3:.4f} mm")]
        note = ("One arrow per measured sample, at its nominal TCP (base frame), along its "
                "held-out residual (measured - predicted, predicted by the fit of the other "
                "folds), before and after the named effect.")
    else:
        sets = [("model: " + ", ".join(result.model.labels), result.analysis.residual * 1e3,
                 f"RMS {result.rms * 1e3:.4f} mm")]
        note = ("One arrow per measured sample, at its nominal TCP (base frame), along its "
                "residual (measured - predicted).")
    return [residual_section(result.analysis.tcp * 1e3, sets, "Residual per pose in 3-D", note)]


def _next_step_html(result: ValidationResult, argv: list[str] | None) -> list[str]:
    cmd = next_command(result, argv)
    dg = result.diagnosis
    if cmd:
        return ["<h2>Next step</h2>", "<p>Run, ready to copy:</p>",
                f"<pre>{html.escape(cmd)}</pre>"]
    if dg.verdict == "adequate":
        return ["<h2>Next step</h2>", "<p>None needed: the model explains the data to its "
                "noise floor. Plan with this robot description.</p>"]
    if dg.verdict == "unexplained":
        part = ("" if not dg.chain else
                f" ({html.escape(' + '.join(s.label for s in dg.chain))} explain "
                f"{100 * dg.chain[-1].share_explained:.1f} % of it, see the forward selection)")
        return ["<h2>Next step</h2>", "<p>No effect in the library brings the residual to "
                f"the noise floor{part}; see what it correlates with below (time, a pose "
                "region, a joint torque, an extra column) for the physics the model lacks.</p>"]
    return []


def _param_units(result: ValidationResult) -> dict[tuple[str, str], str]:
    """(effect label, parameter name) -> SI unit, from the effects of the evaluated model."""
    out: dict[tuple[str, str], str] = {}
    for eff in getattr(result.model, "effects", ()):
        for name in eff.param_names():
            out[(eff.label, name)] = eff.param_unit(name)
    # The base compliance of a prismatic joint (a torso lift) is a linear one.
    base = result.model.joint_compliance
    for name, prismatic in zip(base.param_names(), result.model.robot.prismatic, strict=True):
        if prismatic:
            out[(base.label, name)] = "m/N"
    return out


def write_report(result: ValidationResult, out_dir: str | Path,
                 argv: list[str] | None = None) -> ReportFiles:
    """Write report.html, validate.json and the PNG plots into ``out_dir``.

    Args:
        result: The validation result.
        out_dir: Output folder (created if needed).
        argv: The command line that made ``result`` (the report prints the next command).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plots = make_plots(result, out)
    json_path = out / "validate.json"
    write_text(json_path, result_json(result, wall_times=False) + "\n")
    html_path = out / "report.html"
    write_text(html_path, render_html(result, plots, argv=argv))
    return ReportFiles(html=html_path, json=json_path, plots=plots)
