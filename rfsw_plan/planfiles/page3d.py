"""``plan.html``: the plan in 3-D, one self-contained page (issue 35).

The page shows the robot posed at a selected sample (its links drawn from the kinematic model:
the joint frames of every shown sample are computed here with Pinocchio), the spindle, the
plate with the seam, the taught seam, the commanded TCP path (the fake targets) and the
predicted pin path with every deviation from the seam magnified by a factor the user sets
(x1 ... x200), the weld window as a band around the seam, the process force and the deflection
as arrows, a time slider with play, a readout of the sample (its number N: data row N of
``waypoints.csv``, the first sample = 1, as in the verdict's "sample N"; t, s, phase, lateral
and depth error, margin) and the worst sample one click away. Samples are
coloured by their margin with :func:`margin_colours`, the colours of the margin panel of
``lateral_error_time.png``.

Technology (docs/guide/plan-3d.md): three.js, vendored from its npm package (``web/``), carried
inline as ``data:`` URLs of an import map, so the page opens from ``file://`` with no server
and no network. The numbers go through :mod:`rfsw_plan.numfmt`: the same plan gives the same
bytes.

The page is built from the written ``waypoints.csv`` (not from the planner's memory), the robot
and the seam, so ``rfsw-plan view PLAN_FOLDER`` rebuilds the same bytes from a plan folder.
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError
from rfsw_plan.numfmt import canonical_quaternion, fixed, fixed_many
from rfsw_plan.process.frames import SeamFrames
from rfsw_plan.process.task import PlanTask
from rfsw_plan.robot.kinematics import Robot

FloatArray = NDArray[np.float64]

#: The vendored three.js release (rfsw_plan/planfiles/web/README.md).
THREE_VERSION = "0.170.0"
#: At most this many samples are carried by the page (every phase's first and last sample and
#: the worst one are always among them).
MAX_SAMPLES = 900
#: Phases in which the pin is in the material (``e_lat_mm`` and ``margin_mm`` are written).
CONTACT = ("plunge", "dwell", "accelerate", "weld", "decelerate", "stop")
#: A depth-error column of ``waypoints.csv`` read when present (else the error is computed).
DEPTH_COLUMNS = ("e_depth_mm", "depth_error_mm", "e_norm_mm")
#: Colour of a sample without a margin (the pin out of the material).
NO_MARGIN_COLOUR = "#9a9a9a"
#: Colour map of the margin (matplotlib name): red at the bound, green at the window's centre.
MARGIN_CMAP = "RdYlGn"
#: Its colours (ColorBrewer's RdYlGn, as matplotlib's ``_cm._RdYlGn_data`` gives them, RGB in
#: [0, 1]), evenly spaced from 0 to 1 (``LinearSegmentedColormap.from_list``).
MARGIN_COLOURS = (
    (0.6470588235294118, 0.0, 0.14901960784313725),
    (0.8431372549019608, 0.18823529411764706, 0.15294117647058825),
    (0.9568627450980393, 0.42745098039215684, 0.2627450980392157),
    (0.9921568627450981, 0.6823529411764706, 0.3803921568627451),
    (0.996078431372549, 0.8784313725490196, 0.5450980392156862),
    (1.0, 1.0, 0.7490196078431373),
    (0.8509803921568627, 0.9372549019607843, 0.5450980392156862),
    (0.6509803921568628, 0.8509803921568627, 0.41568627450980394),
    (0.4, 0.7411764705882353, 0.38823529411764707),
    (0.10196078431372549, 0.596078431372549, 0.3137254901960784),
    (0.0, 0.40784313725490196, 0.21568627450980393),
)
#: Entries of the colour map's lookup table (matplotlib's ``image.lut``: 256).
MARGIN_LUT_SIZE = 256


def margin_lut() -> FloatArray:
    """The lookup table of :data:`MARGIN_CMAP`, (:data:`MARGIN_LUT_SIZE`, 3) RGB in [0, 1]:
    matplotlib's ``_create_lookup_table`` of :data:`MARGIN_COLOURS`, the same operations (so
    the same numbers as ``matplotlib.colormaps["RdYlGn"]``, checked in the tests) without
    importing matplotlib on the plan's critical path: entry i is the linear interpolation of
    the colours at i / (N - 1)."""
    c = np.array(MARGIN_COLOURS, dtype=float)
    n = MARGIN_LUT_SIZE
    x = np.linspace(0, 1, len(c)) * (n - 1)
    xind = (n - 1) * np.linspace(0, 1, n) ** 1.0
    ind = np.searchsorted(x, xind)[1:-1]
    distance = (xind[1:-1] - x[ind - 1]) / (x[ind] - x[ind - 1])
    lut = np.concatenate([c[:1], distance[:, None] * (c[ind] - c[ind - 1]) + c[ind - 1],
                          c[-1:]])
    return np.asarray(np.clip(lut, 0.0, 1.0))


def margin_colours(margin: FloatArray, half_width: float) -> list[str]:
    """Colour of each sample by its margin to the window (hex ``#rrggbb``).

    The one margin colour scale of the plan's pictures: ``plan.html`` colours its samples with
    it and ``lateral_error_time.png`` its margin panel. :data:`MARGIN_CMAP` from margin 0 (on a
    bound, and beyond: outside the window) to ``half_width`` (the window's centre); a sample
    without a margin (NaN: the pin is not in the material) is :data:`NO_MARGIN_COLOUR`. The
    value x in [0, 1] takes the table entry ``int(x N)`` (the last for x = 1), as a matplotlib
    colour map does (:func:`margin_lut`).

    Args:
        margin: Margin to the nearest window bound, any unit, (N,).
        half_width: Half the window's width, same unit, > 0.
    """
    m = np.asarray(margin, dtype=float)
    rgb = _margin_bytes(m, half_width)
    return [NO_MARGIN_COLOUR if not np.isfinite(v) else "#{:02x}{:02x}{:02x}".format(*c)
            for v, c in zip(m, rgb.tolist(), strict=True)]


def margin_rgba(margin: FloatArray, half_width: float) -> FloatArray:
    """:func:`margin_colours` as RGBA numbers in [0, 1], shape (N, 4): each channel the hex
    colour's byte / 255 and alpha 1, the numbers matplotlib reads from the hex text
    (``matplotlib.colors.to_rgba``), without formatting and parsing a text per sample (the
    margin panel of ``lateral_error_time.png`` colours every written sample)."""
    m = np.asarray(margin, dtype=float)
    rgb = _margin_bytes(m, half_width)
    rgb[~np.isfinite(m)] = [int(NO_MARGIN_COLOUR[k:k + 2], 16) for k in (1, 3, 5)]
    return np.column_stack([rgb / 255, np.ones(len(m))])


def _margin_bytes(m: FloatArray, half_width: float) -> NDArray[np.int_]:
    """The colour map's bytes (0..255) of each margin, (N, 3) (:func:`margin_colours`)."""
    x = np.clip(np.nan_to_num(m / half_width, nan=0.0), 0.0, 1.0)
    x *= MARGIN_LUT_SIZE
    x[x == MARGIN_LUT_SIZE] = MARGIN_LUT_SIZE - 1
    return np.rint(margin_lut()[x.astype(int)] * 255).astype(int)


@dataclass(frozen=True)
class CsvTable:
    """``waypoints.csv`` as read for the page: its header and its data lines.

    The page reads two columns of every sample (phase, margin) and a few more of the samples
    it shows (at most :data:`MAX_SAMPLES`), so a line is split at its commas only where a cell
    of it is read: the cells :func:`~rfsw_plan.planfiles.folder.csv_rows` gives, without
    splitting the other lines of a long plan. A text the ``csv`` module must read (quotes,
    other line ends) is held as its rows (``rows``).
    """

    path: Path
    header: list[str]
    lines: list[str]
    rows: list[list[str]] | None = None
    _split: dict[int, list[str]] = field(default_factory=dict, compare=False, repr=False)

    def _row(self, k: int) -> list[str]:
        if self.rows is not None:
            return self.rows[k]
        row = self._split.get(k)
        if row is None:
            row = self._split[k] = self.lines[k].split(",")
        return row

    def _cells(self, name: str, at: NDArray[np.int_] | None) -> list[str]:
        if name not in self.header:
            raise InputError(self.path, "header", f"missing column {name}", "waypoints.csv")
        j = self.header.index(name)
        if at is not None:
            return [self._row(k)[j] for k in at]
        if self.rows is not None:
            return [r[j] for r in self.rows]
        after = len(self.header) - 1 - j  # every line has the header's cells (read_table)
        if j <= after:
            return [line.split(",", j + 1)[j] for line in self.lines]
        return [line.rsplit(",", after + 1)[-after - 1] for line in self.lines]

    def col(self, name: str, at: NDArray[np.int_] | None = None) -> FloatArray:
        """A numeric column (NaN for an empty cell), at the rows ``at`` (default: all)."""
        c = np.array(self._cells(name, at), dtype=str)
        out = np.full(c.shape, np.nan)
        given = c != ""
        try:
            out[given] = c[given].astype(float)
        except ValueError:
            raise InputError(self.path, f"column {name}", "a cell that is not a number",
                             "numbers") from None
        return out

    def text(self, name: str) -> list[str]:
        """A text column."""
        return self._cells(name, None)


def read_table(path: Path) -> CsvTable:
    """The header and cells of a written ``waypoints.csv``
    (:func:`~rfsw_plan.planfiles.folder.csv_rows`: its cells, in the same rows).

    Raises:
        InputError: Fewer than two samples, or a row without the header's number of cells.
    """
    from rfsw_plan.planfiles.folder import csv_rows

    text = path.read_bytes().decode("utf-8")  # its own line ends (CRLF), as csv_rows reads
    if '"' not in text and text.count("\n") == text.count("\r\n") == text.count("\r"):
        lines = text.split("\r\n")  # csv_rows' rows, each still one text
        if lines[-1] == "":  # the last line's end
            lines.pop()
        # a blank line is csv's empty row, of no cell
        cells = [line.count(",") + 1 if line else 0 for line in lines]
        if len(lines) < 3 or any(c != cells[0] for c in cells):
            raise InputError(path, "", "not a table of at least two samples", "a waypoints.csv")
        return CsvTable(path, lines[0].split(","), lines[1:])
    rows = csv_rows(text)
    if len(rows) < 3 or any(len(r) != len(rows[0]) for r in rows):
        raise InputError(path, "", "not a table of at least two samples", "a waypoints.csv")
    return CsvTable(path, rows[0], [], rows[1:])


def shown_samples(phase: Sequence[str], worst: int | None, limit: int = MAX_SAMPLES
                  ) -> NDArray[np.int_]:
    """Indices of the samples the page carries: evenly spread over the plan, with the first and
    last sample of every phase and the worst sample, sorted."""
    n = len(phase)
    keep = set(np.linspace(0, n - 1, min(n, limit)).round().astype(int).tolist())
    for k in range(n):
        if k == 0 or k == n - 1 or phase[k] != phase[k - 1] or phase[k] != phase[k + 1]:
            keep.add(k)
    if worst is not None:
        keep.add(worst)
    return np.array(sorted(keep), dtype=int)


def _nums(a: FloatArray, digits: int) -> str:
    """A JSON array of numbers with ``digits`` decimals (numfmt: no ``-0``); NaN is null."""
    return "[" + ",".join("null" if t is None else t
                          for t in fixed_many(a, digits)) + "]"


@cache
def _asset(name: str) -> bytes:
    return resources.files("rfsw_plan.planfiles").joinpath("web", name).read_bytes()


def _data_url(name: str) -> str:
    return "data:text/javascript;base64," + base64.b64encode(_asset(name)).decode("ascii")


def page_scripts(app: str) -> str:
    """The page's scripts: the import map carrying three.js and its orbit controls inline, the
    licence notice, and ``app`` (a ``web/`` file) as a module."""
    imports = json.dumps({"imports": {"three": _data_url("three.module.min.js"),
                                      "three/OrbitControls": _data_url("OrbitControls.js")}})
    licence = _asset("THREE_LICENSE").decode("utf-8").replace("--", "- -")
    return (f"<!-- three.js {THREE_VERSION} (npm package three), inline below:\n{licence}-->\n"
            f"<script type='importmap'>{imports}</script>\n"
            f"<script type='module'>\n{_asset(app).decode('utf-8')}</script>\n")


def chain_drawing(robot: Robot) -> dict[str, str]:
    """The robot's links as the page draws them (mm): per joint, the corner of its link in the
    parent frame (the joint placement without its part along the joint axis, so that a
    modified-DH link is drawn as its ``a`` then its ``d``), the joint axis in its own frame,
    and the TCP in the last joint frame."""
    g = robot.geometry
    corners, axes = [], []
    for i in range(robot.nq):
        P = g.placements[i]
        p = P[:3, 3]
        ax = P[:3, :3] @ g.axes[i]
        corners.append((p - ax * float(ax @ p)) * 1e3)
        axes.append(g.axes[i])
    return {"corner": _nums(np.array(corners), 1), "axis": _nums(np.array(axes), 4),
            "tcp_pos": _nums(g.tcp[:3, 3] * 1e3, 1),
            "tcp_quat": _nums(_quat(g.tcp[None, :3, :3])[0], 5)}


def _quat(R: FloatArray) -> FloatArray:
    """Quaternions (x, y, z, w) of rotation matrices (m, 3, 3), with a sign rounding cannot
    flip (three.js order)."""
    from scipy.spatial.transform import Rotation

    wxyz = canonical_quaternion(np.roll(Rotation.from_matrix(R).as_quat(), 1, axis=1))
    return np.roll(np.atleast_2d(wxyz), -1, axis=1)


def link_frames(robot: Robot, q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Joint frames of every sample in the base frame, from Pinocchio
    (:meth:`~rfsw_plan.robot.kinematics.Robot.joint_frames`): positions [mm] (m, n, 3) and
    quaternions (x, y, z, w) (m, n, 4)."""
    F = np.stack([robot.joint_frames(qk) for qk in q])
    m, n = F.shape[:2]
    quat = _quat(F[:, :, :3, :3].reshape(-1, 3, 3)).reshape(m, n, 4)
    return F[:, :, :3, 3] * 1e3, quat


def task_frames(task: PlanTask) -> Callable[[FloatArray], SeamFrames]:
    """Seam frames at arc lengths, interpolated between a plan's waypoint frames (its moving
    ones: the stationary start repeats the first)."""
    from rfsw_plan.process.seam import interpolate_frames

    m = task.n_start
    fr = task.frames
    moving = SeamFrames(fr.s[m:], fr.p[m:], fr.t[m:], fr.l[m:], fr.n[m:])
    return lambda s: interpolate_frames(moving, s)


def plan_page(waypoints: str | Path, robot: Robot, frames_at: Callable[[FloatArray], SeamFrames],
              window_mm: tuple[float, float], title: str, verdict: str = "") -> str:
    """The text of ``plan.html`` for a written ``waypoints.csv``.

    Args:
        waypoints: The plan's ``waypoints.csv``.
        robot: The robot the plan was made for (its joint columns, Pinocchio model).
        frames_at: Seam frames at arc lengths [m] (the problem's seam).
        window_mm: Lower and upper lateral bound of the weld window [mm].
        title: The problem's name.
        verdict: The plan's verdict line.

    Raises:
        InputError: A column the page needs is missing from ``waypoints.csv``.
    """
    tab = read_table(Path(waypoints))
    phase = tab.text("phase")
    margin = tab.col("margin_mm")
    contact = np.isfinite(margin)
    worst = int(np.flatnonzero(contact)[np.argmin(margin[contact])]) if contact.any() else None
    idx = shown_samples(phase, worst)
    cols = robot.description.convention.column_names()
    q = np.deg2rad(np.column_stack([tab.col(c, idx) for c in cols]))
    s_mm = tab.col("s_mm", idx)
    fr = frames_at(s_mm * 1e-3)
    seam = np.column_stack([tab.col(f"seam_{a}_mm", idx) for a in "xyz"])
    tcp = np.column_stack([tab.col(f"{a}_mm", idx) for a in "xyz"])
    defl = np.column_stack([tab.col(f"d{a}_mm", idx) for a in "xyz"])
    force = np.column_stack([tab.col(f"f{a}_N", idx) for a in "xyz"])
    pin = tcp + defl
    # The nominal target: the commanded TCP without its fake-target offsets along l, n, t (the
    # seam point, raised along n before and while plunging).
    off = np.column_stack([tab.col(f"off_{a}_mm", idx) for a in ("lat", "norm", "along")])
    target = tcp - (off[:, :1] * fr.l + off[:, 1:2] * fr.n + off[:, 2:] * fr.t)
    ph = [phase[k] for k in idx]
    e_lat = tab.col("e_lat_mm", idx)
    depth_col = next((c for c in DEPTH_COLUMNS if c in tab.header), None)
    if depth_col is not None:
        e_depth = tab.col(depth_col, idx)
        depth_note = f"Depth error: column {depth_col} of waypoints.csv."
    else:
        e_depth = np.where(np.isfinite(margin[idx]),
                           np.einsum("ki,ki->k", fr.n, pin - target), np.nan)
        depth_note = ("Depth error: n . (predicted pin - nominal target) along the tool axis n "
                      "(+ out of the plate), computed from waypoints.csv in the material.")
    # The plate's surface normal: the tool axis without its tilt (normal to the seam tangent).
    # The plate is drawn along the seam's overall direction (its chord; for a closed seam, the
    # first frame's travel direction).
    tangent = seam[-1] - seam[0]
    if np.linalg.norm(tangent) < 1e-3:
        tangent = fr.t[0]
    tangent = tangent / np.linalg.norm(tangent)
    nrm = fr.n.mean(axis=0)
    nrm = nrm - tangent * float(nrm @ tangent)
    if np.linalg.norm(nrm) < 1e-6:
        nrm = fr.n[0] - tangent * float(fr.n[0] @ tangent)
    nrm /= np.linalg.norm(nrm)
    pos, quat = link_frames(robot, q)
    lo, hi = window_mm
    phases = list(dict.fromkeys(ph))
    # The sample number a user sees: data row N of waypoints.csv, the first sample = 1 (the
    # verdict's "sample N", SampleFailure.sample; the file's line is N + 1, below the header).
    rows = idx + 1
    data = {
        "title": json.dumps(title), "verdict": json.dumps(verdict),
        "window": _nums(np.array([lo, hi]), 4), "n": str(len(idx)),
        "row": "[" + ",".join(str(int(r)) for r in rows) + "]",
        "phases": json.dumps(phases),
        "phase": "[" + ",".join(str(phases.index(p)) for p in ph) + "]",
        "t": _nums(tab.col("t_s", idx), 3), "s": _nums(s_mm, 3),
        "e_lat": _nums(e_lat, 4), "e_depth": _nums(e_depth, 4),
        "margin": _nums(margin[idx], 4),
        "colour": json.dumps(margin_colours(margin[idx], 0.5 * (hi - lo))),
        "cbar": json.dumps(margin_colours(np.linspace(0.0, 0.5 * (hi - lo), 7), 0.5 * (hi - lo))),
        "worst": "null" if worst is None else str(int(np.searchsorted(idx, worst))),
        "seam": _nums(seam, 3), "target": _nums(target, 3), "tcp_off": _nums(tcp - target, 4),
        "pin_off": _nums(pin - target, 4),
        "lat": _nums(fr.l, 5), "force": _nums(force, 1), "defl": _nums(defl, 4),
        "normal": _nums(nrm, 5), "tangent": _nums(tangent, 5),
        "link_pos": _nums(pos, 1), "link_quat": _nums(quat, 5),
        "depth_note": json.dumps(depth_note),
        **{f"chain_{k}": v for k, v in chain_drawing(robot).items()},
    }
    # "</" never inside a script element (a name cannot close it): JSON's own escape "<\\/"
    body = ",\n".join(f'"{k}":{v}' for k, v in data.items()).replace("</", "<\\/")
    return "".join([
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>\n",
        f"<title>{html.escape(title)}: plan in 3-D</title>\n",
        f"<style>{_asset('plan_view.css').decode('utf-8')}</style>\n</head><body>\n",
        _asset("plan_view.html").decode("utf-8"),
        f"<script type='application/json' id='plan-data'>{{\n{body}\n}}</script>\n",
        page_scripts("plan_view.js"),
        "</body></html>\n",
    ])


def write_plan_page(folder: str | Path, robot: Robot,
                    frames_at: Callable[[FloatArray], SeamFrames],
                    window_mm: tuple[float, float], title: str, verdict: str = "") -> Path:
    """Write ``plan.html`` into a plan folder beside its ``waypoints.csv``, atomically."""
    from rfsw_plan.files import write_text

    out = Path(folder)
    text = plan_page(out / "waypoints.csv", robot, frames_at, window_mm, title, verdict)
    path = out / "plan.html"
    write_text(path, text)
    return path


#: Largest number of poses the residual view carries (a seeded choice beyond it).
MAX_RESIDUAL_POSES = 3000
#: Colours of the residual views' sets, in order (the reports' before / after bars).
RESIDUAL_COLOURS = ("#d62728", "#2ca02c", "#1f77b4", "#9467bd")


def residual_section(points_mm: FloatArray, sets: Sequence[tuple[str, FloatArray, str]],
                     heading: str, note: str) -> str:
    """An HTML section with a 3-D view of residual arrows, for the validation reports: one
    arrow per pose from its nominal TCP along its residual (measured - predicted), magnified
    by a factor the reader sets; a choice between sets (the model before and after an effect).

    Args:
        points_mm: Where the arrows start (the nominal TCP of each pose) [mm], (m, 3).
        sets: ``(label, residuals [mm] (m, 3), score)`` per model, ``score`` the text the
            readout gives for it (e.g. ``held-out RMS 0.0107 mm``); NaN components are drawn
            as 0.
        heading: The section's heading.
        note: A sentence under it (what the arrows are).
    """
    pts = np.asarray(points_mm, dtype=float)
    keep = np.arange(len(pts))
    if len(pts) > MAX_RESIDUAL_POSES:
        keep = np.sort(np.random.default_rng(0).choice(len(pts), MAX_RESIDUAL_POSES,
                                                       replace=False))
    size = float(np.linalg.norm(np.ptp(pts[keep], axis=0))) if len(keep) else 1.0
    largest = max((float(np.nanmax(np.linalg.norm(np.nan_to_num(v[keep]), axis=1)))
                   for _, v, _ in sets if len(keep)), default=0.0)
    # the largest arrow about a quarter of the cloud, at a round factor (1, 2, 5 x 10^k)
    mag = 1.0
    if largest > 0:
        want = 0.25 * max(size, 100.0) / largest
        steps = [f * 10.0**k for k in range(6) for f in (1.0, 2.0, 5.0)]
        mag = max([m for m in steps if m <= want], default=1.0)
    entries = []
    for j, (label, vec, score) in enumerate(sets):
        v = np.nan_to_num(np.asarray(vec, dtype=float)[keep])
        entries.append(f'{{"label":{json.dumps(label)},"colour":"{RESIDUAL_COLOURS[j % 4]}",'
                       f'"score":{json.dumps(score)},"vectors":{_nums(v, 5)}}}')
    data = (f'{{"points":{_nums(pts[keep], 2)},"mag":{fixed(mag, 0)},'
            f'"sets":[{",".join(entries)}]}}').replace("</", "<\\/")
    return "".join([
        f"<h2>{html.escape(heading)}</h2>\n<p>{html.escape(note)} Drag to turn the view, scroll "
        "to zoom.</p>\n<div class='residual3d'><label>model <select id='residual-set'></select>"
        "</label> <label>arrows magnified &times;<input type='number' id='residual-mag' min='1' "
        "max='100000' step='1'></label>\n<canvas id='residual-scene' style='width:100%;"
        "height:520px;display:block;border:1px solid #ccc'></canvas>\n"
        "<p id='residual-readout'></p></div>\n",
        f"<script type='application/json' id='residual-data'>{data}</script>\n",
        page_scripts("residual_view.js"),
    ])


@dataclass(frozen=True)
class ViewResult:
    """What :func:`rebuild_plan_page` did.

    Attributes:
        path: The page.
        changed: The page's bytes differ from the file that was there (or none was).
        size: Its size [bytes].
    """

    path: Path
    changed: bool
    size: int


def rebuild_plan_page(folder: str | Path, output: str | Path | None = None) -> ViewResult:
    """``rfsw-plan view``: build a plan folder's ``plan.html`` again from its files.

    The folder is read strictly (``plan.json`` a verified plan whose ``waypoints.csv`` is the
    one it vouches for; the robot and the problem it names), the page is built as
    ``rfsw-plan plan`` builds it and written atomically. Into the plan folder (the default), a
    page whose bytes changed (a plan of an older version) is committed in ``plan.json``'s
    ``sha256`` table; the folder is locked while it is written.

    Args:
        folder: A plan folder.
        output: Where to write the page (default: ``plan.html`` in the folder).

    Raises:
        InputError: A damaged folder, or a robot or problem file that cannot be read (exit 2).
        InfeasibleError: The plan is infeasible (exit 3).
    """
    from rfsw_plan.files import OutputLock, sha256_file, write_json, write_text
    from rfsw_plan.planfiles.folder import _check_vouched
    from rfsw_plan.planfiles.record import PlanRecord
    from rfsw_plan.process.problem import load_problem
    from rfsw_plan.robot.kinematics import load_robot

    folder = Path(folder)
    record_path = folder / "plan.json"
    record = PlanRecord.read(record_path).to_json()
    PlanRecord.from_json(record, record_path).check_status(record_path)
    digests = record.get("sha256")
    if not isinstance(digests, dict) or "waypoints.csv" not in digests:
        raise InputError(record_path, "sha256", "does not vouch for waypoints.csv",
                         "the sha256 table rfsw-plan plan writes")
    _check_vouched(folder, "waypoints.csv", digests["waypoints.csv"])
    robot_name = record.get("robot_file") or record.get("robot")
    problem_name = record.get("problem_file") or record.get("problem")
    for key, value in (("robot_file", robot_name), ("problem_file", problem_name)):
        if not isinstance(value, str) or not value.strip():
            raise InputError(record_path, key, "missing", "the file the plan was made with")
    window = record.get("window_mm")
    if (not isinstance(window, list) or len(window) != 2
            or not all(isinstance(v, int | float) for v in window)):
        raise InputError(record_path, "window_mm", f"{window!r}", "[lower, upper] in mm")
    robot = load_robot(str(robot_name))
    problem = load_problem(str(problem_name))
    text = plan_page(folder / "waypoints.csv", robot, problem.seam.frames_at,
                     (float(window[0]), float(window[1])), str(record.get("problem", "plan")),
                     str(record.get("verdict_text") or ""))
    data = text.encode("utf-8")
    target = folder / "plan.html" if output is None else Path(output)
    changed = not target.is_file() or target.read_bytes() != data
    if output is not None:
        if changed:
            write_text(target, text)
        return ViewResult(target, changed, len(data))
    with OutputLock(folder, "PLAN_FOLDER"):
        if changed:
            write_text(target, text)
        if digests.get("plan.html") != sha256_file(target):
            record["sha256"] = {**digests, "plan.html": sha256_file(target)}
            files = record.get("files")
            if isinstance(files, list) and not any(Path(str(f)).name == "plan.html"
                                                   for f in files):
                record["files"] = [*files, target.name]
            write_json(record_path, record)
    return ViewResult(target, changed, len(data))


__all__ = ["ViewResult", "margin_colours", "margin_rgba", "page_scripts", "plan_page",
           "rebuild_plan_page", "residual_section", "task_frames", "write_plan_page"]
