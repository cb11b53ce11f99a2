"""Heat maps of a placement map (matplotlib, imported lazily; files written atomically).

``map.png``: over the table plane (x, y of the seam anchor, robot base frame), the best value
over yaw and height of each index among the feasible placements, with the given placement
(star) and any candidates (numbered circles; candidates at one position share a circle) marked,
units on every colour bar (scaled so outliers do not flatten the informative range; arrows mark
values beyond it), the requested force uncertainty as a dashed contour, and the legend below
the panels, outside the data. ``map_yaw.png``: the tolerated force uncertainty of the
mirror offsets per yaw.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.files import write_figure
from rfsw_plan.placement.map import PlacementMap

FloatArray = NDArray[np.float64]

#: (attribute or callable, title, colour-bar label, scale, best = max or min, colour map)
_PANELS: tuple[tuple[str, str, str, float, str, str], ...] = (
    ("tolerated_mirror", "tolerated force uncertainty, mirror offsets",
     "tolerated uncertainty [%]", 100.0, "max", "viridis"),
    ("tolerated_centred", "tolerated force uncertainty, centred offsets",
     "tolerated uncertainty [%]", 100.0, "max", "viridis"),
    ("stiffness", "smallest lateral stiffness along the seam", "stiffness [N/mm]", 1e-3,
     "max", "viridis"),
    ("compliance_mean", "mean lateral compliance along the seam", "compliance [mm/kN]", 1e6,
     "min", "magma_r"),
    ("deviation", "largest uncompensated lateral deviation", "|e_lat| [mm]", 1e3, "min",
     "magma_r"),
    ("kappa_f", "largest kappa_f along the seam (seed 000 eq. 5)", "kappa_f [-]", 1.0, "min",
     "magma_r"),
    ("nu_p", "largest nu_p (seed 000 eq. 9)", "nu_p [-]", 1.0, "min", "magma_r"),
    ("feasible_share", "feasible yaws and heights", "feasible share [%]", 100.0, "max",
     "cividis"),
)


def _values(m: PlacementMap, key: str) -> FloatArray:
    if key == "stiffness":
        with np.errstate(divide="ignore"):
            return np.asarray(1.0 / m.compliance_max)
    if key == "feasible_share":
        return m.feasible.astype(float)
    return np.asarray(getattr(m, key), dtype=float)


def _reduce(m: PlacementMap, key: str, best: str) -> FloatArray:
    """(nx, ny) best over yaw and height among feasible placements (NaN: none feasible)."""
    v = _values(m, key).copy()
    if key != "feasible_share":
        v[~m.feasible] = np.nan
    V = v.reshape(m.grid.shape)
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            if key == "feasible_share":
                return np.asarray(np.mean(V, axis=(2, 3)))
            out = np.nanmax(V, axis=(2, 3)) if best == "max" else np.nanmin(V, axis=(2, 3))
    return np.asarray(out)


def _extent(m: PlacementMap) -> list[float]:
    g = m.grid

    def edges(a: FloatArray) -> tuple[float, float]:
        h = 0.5 * (a[1] - a[0]) if len(a) > 1 else 0.025
        return float(a[0] - h) * 1e3, float(a[-1] + h) * 1e3

    x0, x1 = edges(g.x)
    y0, y1 = edges(g.y)
    return [x0, x1, y0, y1]


def colour_limits(Z: FloatArray, key: str, requested: float | None = None
                  ) -> tuple[float | None, float | None, str]:
    """Colour-scale limits (vmin, vmax) and the colour bar's ``extend`` of a panel, so a few
    outliers do not turn the informative range into one shade.

    Tolerated uncertainty [%]: 0 .. max(2 x requested, 90th percentile), never above the
    largest value (on kr600 maps a few placements reach 100-140 % while the rest lie at
    10-30 %). Other panels: their 2nd to 98th percentile. Values beyond are drawn in the end
    colour and the colour bar gets an arrow.
    """
    v = Z[np.isfinite(Z)]
    if not v.size:
        return None, None, "neither"
    lo, hi = float(np.min(v)), float(np.max(v))
    if key.startswith("tolerated"):
        top = 90.0 if requested is None else max(2 * requested * 100.0,
                                                 float(np.percentile(v, 90)))
        vmin, vmax = 0.0, min(hi, top)
    elif key == "feasible_share":
        vmin, vmax = 0.0, 100.0
    else:
        vmin, vmax = float(np.percentile(v, 2)), float(np.percentile(v, 98))
    if vmax <= vmin:
        vmin, vmax = lo, max(hi, lo + 1e-12)
    ext = {(False, False): "neither", (True, False): "min", (False, True): "max",
           (True, True): "both"}[(lo < vmin - 1e-12, hi > vmax + 1e-12)]
    return vmin, vmax, ext


def grouped_marks(candidates: Sequence[tuple[str, float, float]], tol: float = 1e-6
                  ) -> list[tuple[str, float, float]]:
    """Candidates at the same table position (they differ in yaw or height) as one mark with
    their labels joined (``1,3``), so no number hides another; first-seen order."""
    out: list[tuple[list[str], float, float]] = []
    for lab, x, y in candidates:
        same = next((o for o in out if abs(o[1] - x) < tol and abs(o[2] - y) < tol), None)
        if same is None:
            out.append(([lab], x, y))
        else:
            same[0].append(lab)
    return [(",".join(labs), x, y) for labs, x, y in out]


def plot_map(path: str | Path, m: PlacementMap,
             candidates: Sequence[tuple[str, float, float]] = (), title: str = "",
             requested: float | None = None) -> Path:
    """Write the table-plane heat maps of a map.

    Args:
        path: PNG file.
        m: The map.
        candidates: (label, x [m], y [m]) of placements to mark (e.g. the place candidates);
            candidates at one position share a mark (:func:`grouped_marks`).
        title: Figure title (default: the problem name and grid).
        requested: The requested force uncertainty (relative): drawn as a contour on the
            tolerated-uncertainty panels and a line on their colour bars.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 4, figsize=(22, 10.5), constrained_layout=True)
    ext = _extent(m)
    handles: list[Any] = []
    marks = grouped_marks(candidates)
    for ax, (key, ttl, unit, scale, best, cmap) in zip(axes.ravel(), _PANELS, strict=True):
        Z = _reduce(m, key, best) * scale
        hs = _panel(fig, ax, m, Z, key, (ttl, unit, cmap), ext, requested, marks)
        if not handles:
            handles = hs
    grey = matplotlib.patches.Patch(color="#d9d9d9", label="no feasible placement")
    fig.legend(handles=[*handles, grey], loc="outside lower center", ncol=5, frameon=False)
    g = m.grid
    fig.suptitle(title or (
        f"{m.name}: {m.grid.size} placements ({len(g.x)} x {len(g.y)} positions, {len(g.yaw)} "
        f"yaws {np.rad2deg(g.yaw[0]):.0f}..{np.rad2deg(g.yaw[-1]):.0f} deg, {len(g.z)} "
        f"height(s)); best over yaw and height per position"), fontsize=13)
    write_figure(path, fig, dpi=100)
    plt.close(fig)
    return Path(path)


def _panel(fig: Any, ax: Any, m: PlacementMap, Z: FloatArray, key: str,
           text: tuple[str, str, str], ext: list[float], requested: float | None,
           marks: list[tuple[str, float, float]]) -> list[Any]:
    """One heat map with its colour bar, the requested contour, the given placement and the
    candidates; returns the legend handles."""
    import matplotlib.pyplot as plt

    ttl, unit, cmap = text
    vmin, vmax, extend = colour_limits(Z, key, requested)
    cm = plt.get_cmap(cmap).with_extremes(bad="#d9d9d9")
    im = ax.imshow(np.ma.masked_invalid(Z.T), origin="lower", extent=ext, cmap=cm,
                   vmin=vmin, vmax=vmax, aspect="equal", interpolation="nearest")
    cb = fig.colorbar(im, ax=ax, shrink=0.85, extend=extend)
    cb.set_label(unit)
    hs: list[Any] = []
    if requested is not None and key.startswith("tolerated"):
        level = 100.0 * requested
        cb.ax.axhline(level, color="white", lw=2)
        cb.ax.axhline(level, color="red", lw=1, ls="--")
        finite = Z[np.isfinite(Z)]
        if finite.size and finite.min() < level < finite.max() and min(Z.shape) > 1:
            xs = np.linspace(ext[0], ext[1], Z.shape[0] + 1)
            ys = np.linspace(ext[2], ext[3], Z.shape[1] + 1)
            ax.contour(0.5 * (xs[1:] + xs[:-1]), 0.5 * (ys[1:] + ys[:-1]),
                       np.ma.masked_invalid(Z.T), levels=[level], colors="red",
                       linestyles="--", linewidths=1.5)
        hs.append(matplotlib_line("red", "--", f"requested +-{level:g} % (contour, colour bar)"))
    ax.set_title(ttl, fontsize=10)
    ax.set_xlabel("anchor x [mm] (robot base frame)")
    ax.set_ylabel("anchor y [mm]")
    gv = m.given
    hs.insert(0, ax.plot(gv["x_mm"], gv["y_mm"], marker="*", ms=16, mfc="red", mec="white",
                         ls="none", label="given placement")[0])
    for i, (lab, x, y) in enumerate(marks):
        h = ax.plot(x * 1e3, y * 1e3, marker="o", ms=12, mfc="none", mec="black", mew=2,
                    ls="none", label="candidates (rank; same position: joined)")[0]
        ax.annotate(lab, (x * 1e3, y * 1e3), xytext=(7, 7), textcoords="offset points",
                    color="black", fontsize=9, fontweight="bold",
                    bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none",
                          "alpha": 0.8})
        if i == 0:
            hs.append(h)
    return hs


def matplotlib_line(colour: str, style: str, label: str) -> Any:
    """A legend handle for a line that is not plotted as such (a contour)."""
    from matplotlib.lines import Line2D

    return Line2D([], [], color=colour, ls=style, label=label)


def plot_yaw(path: str | Path, m: PlacementMap) -> Path:
    """Tolerated uncertainty of the mirror offsets over the table plane, one panel per yaw
    (up to 8 yaws, evenly picked), best over height."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    g = m.grid
    sel = np.unique(np.round(np.linspace(0, len(g.yaw) - 1, min(8, len(g.yaw)))).astype(int))
    ncol = min(4, len(sel))
    nrow = int(np.ceil(len(sel) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.5 * ncol + 1.5, 5 * nrow + 0.8),
                             constrained_layout=True, squeeze=False)
    v = m.tolerated_mirror.copy() * 100.0
    v[~m.feasible] = np.nan
    V = v.reshape(g.shape)
    finite = V[np.isfinite(V)]
    vmax = float(np.max(finite)) if finite.size else 1.0
    ext = _extent(m)
    cm = plt.get_cmap("viridis").with_extremes(bad="#d9d9d9")
    im = None
    for ax, j in zip(axes.ravel(), sel, strict=False):
        with np.errstate(all="ignore"):
            import warnings

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                Z = np.nanmax(V[:, :, j, :], axis=2)
        im = ax.imshow(np.ma.masked_invalid(Z.T), origin="lower", extent=ext, cmap=cm,
                       vmin=0.0, vmax=vmax, aspect="equal", interpolation="nearest")
        ax.plot(m.given["x_mm"], m.given["y_mm"], marker="*", ms=14, mfc="red", mec="white",
                ls="none")
        ax.set_title(f"yaw {np.rad2deg(g.yaw[j]):+.0f} deg")
        ax.set_xlabel("anchor x [mm]")
        ax.set_ylabel("anchor y [mm]")
    for ax in axes.ravel()[len(sel):]:
        ax.set_visible(False)
    if im is not None:
        cb = fig.colorbar(im, ax=axes.ravel().tolist(), shrink=0.8)
        cb.set_label("tolerated force uncertainty, mirror offsets [%]")
    fig.suptitle(f"{m.name}: tolerated force uncertainty per yaw (red star: given placement, "
                 f"grey: infeasible)", fontsize=13)
    write_figure(path, fig, dpi=100)
    plt.close(fig)
    return Path(path)
