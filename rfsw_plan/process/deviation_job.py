"""The ``deviation`` job: predict a problem's uncompensated pin deviation and write its folder.

One library call per command (``rfsw-plan deviation`` is a thin layer over it)::

    run = DeviationRequest(load_problem("zk500_table6_seam"), dt=0.1).run()
    run.write("out/deviation/zk500_table6_seam")   # deviation.csv, deviation_time.csv,
                                                   # deviation.json, deviation.png

Errors name the request's parameters (``dt``, ``cosim``, ``forces``), never a command-line
flag; the CLI maps them to its flags (:mod:`rfsw_plan.cli.params`).
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.files import atomic_path, write_figure, write_json
from rfsw_plan.numfmt import fixed
from rfsw_plan.process.deviation import DeviationResult, problem_deviation
from rfsw_plan.process.force_fit import fit_process_forces
from rfsw_plan.process.force_series import ForceSeries
from rfsw_plan.process.frames import check_samples
from rfsw_plan.process.problem import Problem, load_problem, with_process

#: Most schedule samples of one deviation run.
MAX_DEVIATION_SAMPLES = 100_000
#: The files of a deviation folder (the plot last, unless not drawn).
DEVIATION_FILES = ("deviation.csv", "deviation_time.csv", "deviation.json", "deviation.png")


@dataclass(frozen=True)
class DeviationRequest:
    """What to predict.

    Attributes:
        problem: The problem (or a problem file / bundled name).
        dt: Time step of the load schedule [s] (seed 001 uses 0.1 s).
        cosim: Solve the axial force with the penetration law of ``[process.coupling]``
            (seed 001 Fig. 8 co-simulation).
        forces: A measured force series to fit the process forces to before predicting, or
            None (:func:`rfsw_plan.io.force_series.read_force_series` reads one).
    """

    problem: Problem | str
    dt: float = 0.1
    cosim: bool = False
    forces: ForceSeries | None = None

    def stages(self) -> list[str]:
        """The stages :meth:`run` reports to its ``on_stage`` callback, in order."""
        return [*(["fitting the force log"] if self.forces is not None else []),
                "co-simulation" if self.cosim else "deviation"]

    def run(self, on_stage: Callable[[str], None] | None = None) -> DeviationRun:
        """Predict the deviation (prints nothing, writes nothing).

        Raises:
            InputError: ``dt`` does not fit the process, ``cosim`` without
                ``[process.coupling]``, a force series that cannot be fitted (one line).
            UnreachableError: The seam is not reachable from the problem's q_seed.
        """
        problem = (self.problem if isinstance(self.problem, Problem)
                   else load_problem(self.problem))
        check_samples("dt", self.dt, process_duration(problem),
                      max_samples=MAX_DEVIATION_SAMPLES)
        fit_text, fit_json = "", None
        if self.forces is not None:
            if on_stage is not None:
                on_stage("fitting the force log")
            problem, fit_text, fit_json = _fit(problem, self.forces)
        if on_stage is not None:
            on_stage(self.stages()[-1])
        res = problem_deviation(problem, dt=self.dt, cosim=self.cosim)
        return DeviationRun(problem, res, fit_text, fit_json)


@dataclass(frozen=True)
class DeviationRun:
    """A predicted deviation.

    Attributes:
        problem: The problem predicted (with the fitted forces, if a force series was given).
        result: The deviation along the seam and over time.
        fit_text: The force fit's summary, ``""`` without a force series.
        fit_json: The force fit's ``deviation.json`` entry, or None.
    """

    problem: Problem
    result: DeviationResult
    fit_text: str = ""
    fit_json: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        """``deviation.json`` (file units)."""
        data = {"problem": self.problem.name, "robot": self.problem.robot.name,
                **self.result.to_dict()}
        if self.fit_json is not None:
            data["force_fit"] = self.fit_json
        return data

    def write(self, folder: str | Path, plot: bool = True) -> list[Path]:
        """Write the deviation folder (each file atomically): ``deviation.csv`` (per
        waypoint), ``deviation_time.csv`` (per schedule sample), ``deviation.json`` and, with
        ``plot``, ``deviation.png``. The folder must exist (the CLI prepares and locks it).

        Returns:
            The written paths.
        """
        out = Path(folder)
        res = self.result
        write_deviation_csv(out / "deviation.csv", res,
                            self.problem.robot.convention.column_names())
        write_deviation_time_csv(out / "deviation_time.csv", res)
        write_json(out / "deviation.json", self.to_dict())
        files = [out / n for n in DEVIATION_FILES[:3]]
        if plot:
            files.append(plot_deviation(res, out / "deviation.png",
                                        title=self.problem.title or self.problem.name))
        return files

    def summary(self) -> str:
        """The text the CLI prints: the seam, the steady force, the deviations, the window."""
        problem, res = self.problem, self.result
        mm = 1e3
        w = res.window
        f = res.force_seam[0]
        lines = [
            f"{problem.name}: {problem.title}",
            f"  robot {problem.robot.name}, seam {res.frames.s[-1] * mm:.1f} mm, "
            f"{len(res.frames)} waypoints",
            f"  steady force (seam frame): f_t {f[0]:.1f} N, f_l {f[1]:.1f} N, f_n {f[2]:.1f} N",
            f"  lateral deviation [mm]: start {res.lateral[0] * mm:+.3f}, end "
            f"{res.lateral[-1] * mm:+.3f}, max |.| {res.max_abs_lateral * mm:.3f} "
            f"(+ = advancing side)",
            f"  axial deviation   [mm]: start {res.axial[0] * mm:+.3f}, end "
            f"{res.axial[-1] * mm:+.3f} (+ = up the tool axis)",
            f"  along-track       [mm]: start {res.along[0] * mm:+.3f}, end "
            f"{res.along[-1] * mm:+.3f}",
            f"  weld window [{w.lower * mm:+.2f}, {w.upper * mm:+.2f}] mm: "
            f"{int(np.sum(res.inside))}/{len(res.frames)} waypoints inside without compensation",
        ]
        return "\n".join(lines)


def process_duration(problem: Problem) -> float:
    """Duration of the problem's process, approach to retract [s] (what ``dt`` samples)."""
    frames = problem.frames()
    return float(problem.process.phase_times(float(frames.s[-1] - frames.s[0])).total)


def _fit(problem: Problem, series: ForceSeries) -> tuple[Problem, str, dict[str, Any]]:
    fit = fit_process_forces(problem.process, problem.frames(), series,
                             problem.planning.tool_rotation)
    js = {"params": fit.params, "std": fit.std, "fixed": list(fit.fixed),
          "rms_N": fit.rms.tolist(), "r2": [None if not np.isfinite(v) else float(v)
                                            for v in fit.r2],
          "rms_total_N": fit.rms_total, "loss_N2": fit.loss, "notes": list(fit.notes)}
    return with_process(problem, fit.process), fit.summary(), js


def write_deviation_csv(path: Path, res: DeviationResult, joint_columns: list[str]) -> Path:
    """``deviation.csv``: one row per seam waypoint (mm, N, deg), atomically."""
    with atomic_path(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        nq = res.q.shape[1]
        w.writerow(["s_mm", "x_mm", "y_mm", "z_mm", "f_t_N", "f_l_N", "f_n_N", "lateral_mm",
                    "axial_mm", "along_mm", "inside_window",
                    *joint_columns[:nq]])
        for k in range(len(res.frames)):
            w.writerow([
                fixed(res.frames.s[k] * 1e3, 3), *(fixed(v * 1e3, 3) for v in res.frames.p[k]),
                *(fixed(v, 2) for v in res.force_seam[k]), fixed(res.lateral[k] * 1e3, 4),
                fixed(res.axial[k] * 1e3, 4), fixed(res.along[k] * 1e3, 4),
                int(res.inside[k]), *(fixed(v, 4) for v in np.rad2deg(res.q[k])),
            ])
    return path


def write_deviation_time_csv(path: Path, res: DeviationResult) -> Path:
    """``deviation_time.csv``: one row per schedule sample (s, mm, N), atomically."""
    sch = res.schedule
    with atomic_path(path) as tmp, tmp.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t_s", "phase", "s_mm", "depth_mm", "f_t_N", "f_l_N", "f_n_N",
                    "lateral_mm", "axial_mm", "along_mm"])
        F = res.cosim.force_seam if res.cosim is not None else sch.force_seam
        for k in range(len(sch)):
            w.writerow([fixed(sch.t[k], 3), sch.phase[k], fixed(sch.s[k] * 1e3, 3),
                        fixed(sch.depth[k] * 1e3, 3), *(fixed(v, 2) for v in F[k]),
                        fixed(res.lateral_t[k] * 1e3, 4), fixed(res.axial_t[k] * 1e3, 4),
                        fixed(res.along_t[k] * 1e3, 4)])
    return path


def plot_deviation(res: DeviationResult, path: Path, title: str = "") -> Path:
    """PNG, written atomically: lateral deviation along the seam with the weld-window band (the
    window applies to the lateral direction only), axial and along-track deviation in their own
    panels, and the lateral deviation over time with the phases shaded (matplotlib, Agg
    backend, imported here).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mm = 1e3
    w = res.window
    fig, axes = plt.subplots(2, 2, figsize=(13, 8), constrained_layout=True)
    (a_lat, a_time), (a_ax, a_al) = axes
    s = res.frames.s * mm
    a_lat.axhspan(w.lower * mm, w.upper * mm, color="tab:green", alpha=0.2,
                  label=f"weld window [{w.lower * mm:+.2f}, {w.upper * mm:+.2f}] mm")
    a_lat.plot(s, res.lateral * mm, "o-", ms=3, color="tab:red",
               label="lateral, uncompensated (+ advancing side)")
    a_lat.set_xlabel("arc length s [mm]")
    a_lat.set_ylabel("lateral deviation [mm]")
    a_lat.set_title("lateral deviation at the waypoints (steady weld force)")
    a_lat.legend(fontsize=8, loc="upper left", bbox_to_anchor=(0.0, -0.15), ncol=2)
    a_lat.grid(alpha=0.3)
    a_ax.plot(s, res.axial * mm, "s-", ms=2, color="tab:blue", label="axial (+ up)")
    a_ax.plot(s, res.along * mm, "^-", ms=2, color="tab:purple", label="along-track")
    a_ax.set_xlabel("arc length s [mm]")
    a_ax.set_ylabel("deviation [mm]")
    a_ax.set_title("axial and along-track deviation (no window applies)")
    a_ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(0.0, -0.15), ncol=2)
    a_ax.grid(alpha=0.3)
    sch = res.schedule
    a_time.axhspan(w.lower * mm, w.upper * mm, color="tab:green", alpha=0.2,
                   label="weld window (lateral)")
    a_time.plot(sch.t, res.lateral_t * mm, color="tab:red", label="lateral")
    _shade_phases(a_time, sch)
    a_time.set_xlabel("time [s]")
    a_time.set_ylabel("lateral deviation [mm]")
    a_time.set_title("lateral deviation over time (phases shaded)")
    a_time.legend(fontsize=8, loc="upper left", bbox_to_anchor=(0.0, -0.15), ncol=2)
    a_time.grid(alpha=0.3)
    a_al.plot(sch.t, res.axial_t * mm, color="tab:blue", label="axial")
    a_al.plot(sch.t, res.along_t * mm, color="tab:purple", label="along-track")
    _shade_phases(a_al, sch)
    a_al.set_xlabel("time [s]")
    a_al.set_ylabel("deviation [mm]")
    a_al.set_title("axial and along-track deviation over time")
    a_al.legend(fontsize=8, loc="upper left", bbox_to_anchor=(0.0, -0.15), ncol=2)
    a_al.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    write_figure(path, fig, dpi=100)
    plt.close(fig)
    return path


_PHASE_COLOURS = {"approach": "0.9", "plunge": "tab:orange", "dwell": "tab:olive",
                  "accelerate": "tab:cyan", "weld": "white", "decelerate": "tab:cyan",
                  "stop": "tab:olive", "retract": "0.9"}


def _shade_phases(ax: Any, sch: Any) -> None:
    """Shade each phase's time span and name it once at the bottom, inside its span; spans too
    short to hold their name stay unnamed (no overlapping labels)."""
    t = sch.t
    t_range = float(t[-1] - t[0]) or 1.0
    for ph, colour in _PHASE_COLOURS.items():
        m = sch.mask(ph)
        if not m.any():
            continue
        t0, t1 = float(t[m][0]), float(t[m][-1])
        if colour != "white":
            ax.axvspan(t0, t1, color=colour, alpha=0.15, lw=0)
        if (t1 - t0) / t_range > 0.04:
            ax.text(0.5 * (t0 + t1), 0.02, ph, transform=ax.get_xaxis_transform(),
                    fontsize=8, ha="center", va="bottom",
                    bbox={"facecolor": "white", "alpha": 0.7, "lw": 0, "pad": 1})


__all__ = ["DEVIATION_FILES", "DeviationRequest", "DeviationRun", "plot_deviation",
           "process_duration", "write_deviation_csv", "write_deviation_time_csv"]
