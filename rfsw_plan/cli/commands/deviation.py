"""``rfsw-plan deviation PROBLEM``: predicted uncompensated pin deviation along the seam."""

from __future__ import annotations

import argparse
import csv
import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rfsw_plan.cli.numbers import number

NAME = "deviation"
HELP = "predict the uncompensated lateral/axial/along-track pin deviation of a problem"

if TYPE_CHECKING:  # the parser answers before the heavy libraries are imported
    from rfsw_plan.process.deviation import DeviationResult
    from rfsw_plan.process.problem import Problem
    from rfsw_plan.progress import Stages

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("problem", metavar="PROBLEM",
                        help="problem file or bundled stem (e.g. zk500_table6_seam)")
    parser.add_argument("-o", "--output", metavar="DIR", default=None,
                        help="output folder (default out/deviation/<problem>)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--dt", type=number(1e-6, 3600, "s", why="at least 1 us; at most the "
                                            "weld's duration, checked with the problem"),
                        default=0.1, metavar="S",
                        help="time step of the load schedule [s] (default 0.1, seed 001)")
    parser.add_argument("--cosim", action="store_true",
                        help="solve the axial force with the penetration law of "
                        "[process.coupling] (seed 001 Fig. 8 co-simulation)")
    parser.add_argument("--forces", metavar="CSV", default=None,
                        help="measured force series (t_s, fx_N, fy_N, fz_N[, m*_Nm][, frame]) "
                        "to fit the process forces to before predicting")
    parser.add_argument("--forces-frame", choices=("base", "seam", "tool"), default=None,
                        help="frame of the force CSV if it has no 'frame' column")
    parser.add_argument("--no-plot", action="store_true", help="do not write the PNG")


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.progress import Stages

    predict = "co-simulation" if args.cosim else "deviation"
    names = ["reading the problem", *(["fitting the force log"] if args.forces else []),
             predict, "files" if args.no_plot else "files and plot"]
    with Stages(NAME, names) as stages:
        return _run(args, stages, names)


def _run(args: argparse.Namespace, stages: Stages, names: list[str]) -> int:
    from rfsw_plan.cli.numbers import check_samples
    from rfsw_plan.files import (
        OutputLock,
        atomic_path,
        prepare_output_dir,
        strict_json,
        write_json,
    )
    from rfsw_plan.process.deviation import problem_deviation
    from rfsw_plan.process.problem import load_problem

    problem = load_problem(args.problem)
    check_samples("--dt", args.dt, _process_duration(problem), max_samples=100_000)
    out = prepare_output_dir(args.output if args.output else Path("out") / NAME / problem.name)
    fit_text = ""
    fit_json = None
    if args.forces is not None:
        stages.start("fitting the force log")
        problem, fit_text, fit_json = _fit(problem, args.forces, args.forces_frame)
    stages.start(names[-2])
    res = problem_deviation(problem, dt=args.dt, cosim=args.cosim)
    data = {"problem": problem.name, "robot": problem.robot.name, **res.to_dict()}
    if fit_json is not None:
        data["force_fit"] = fit_json
    files = ["deviation.csv", "deviation_time.csv", "deviation.json"]
    stages.start(names[-1])
    with OutputLock(out):
        with atomic_path(out / "deviation.csv") as tmp:
            _write_csv(tmp, res, problem.robot.convention.column_names())
        with atomic_path(out / "deviation_time.csv") as tmp:
            _write_time_csv(tmp, res)
        write_json(out / "deviation.json", data)
        if not args.no_plot:
            plot_deviation(res, out / "deviation.png", title=problem.title or problem.name)
            files.append("deviation.png")
    data["files"] = [str(out / f) for f in files]
    if args.json:
        print(strict_json(data, indent=None), end="")
        return 0
    print(_summary(problem, res))
    if fit_text:
        print(fit_text)
    if res.penetration_fit is not None:
        print(res.penetration_fit.summary())
    if res.cosim is not None:
        print(res.cosim.summary())
        print(res.cosim_summary())
    print(f"wrote {', '.join(files)} to {out}")
    return 0


def _process_duration(problem: Problem) -> float:
    """Duration of the problem's process, approach to retract [s] (what ``--dt`` samples)."""
    frames = problem.frames()
    return float(problem.process.phase_times(float(frames.s[-1] - frames.s[0])).total)


def _fit(problem: Problem, path: str, frame: str | None) -> tuple[Problem, str, dict[str, object]]:
    import numpy as np

    from rfsw_plan.io.force_series import read_force_series
    from rfsw_plan.process.force_fit import fit_process_forces

    series = read_force_series(path, frame)
    fit = fit_process_forces(problem.process, problem.frames(), series,
                             problem.planning.tool_rotation)
    js = {"params": fit.params, "std": fit.std, "fixed": list(fit.fixed),
          "rms_N": fit.rms.tolist(), "r2": [None if not np.isfinite(v) else float(v)
                                            for v in fit.r2],
          "rms_total_N": fit.rms_total, "loss_N2": fit.loss, "notes": list(fit.notes)}
    from rfsw_plan.process.problem import with_process

    return with_process(problem, fit.process), fit.summary(), js


def _summary(problem: Problem, res: DeviationResult) -> str:
    import numpy as np

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
        f"  axial deviation   [mm]: start {res.axial[0] * mm:+.3f}, end {res.axial[-1] * mm:+.3f}"
        " (+ = up the tool axis)",
        f"  along-track       [mm]: start {res.along[0] * mm:+.3f}, end {res.along[-1] * mm:+.3f}",
        f"  weld window [{w.lower * mm:+.2f}, {w.upper * mm:+.2f}] mm: "
        f"{int(np.sum(res.inside))}/{len(res.frames)} waypoints inside without compensation",
    ]
    return "\n".join(lines)


def _write_csv(path: Path, res: DeviationResult, joint_columns: list[str]) -> None:
    import numpy as np

    from rfsw_plan.files import atomic_path
    from rfsw_plan.numfmt import fixed

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


def _write_time_csv(path: Path, res: DeviationResult) -> None:
    from rfsw_plan.files import atomic_path
    from rfsw_plan.numfmt import fixed

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
    from rfsw_plan.files import write_figure

    write_figure(path, fig, dpi=100)
    plt.close(fig)
    return path


_PHASE_COLOURS = {"approach": "0.9", "plunge": "tab:orange", "dwell": "tab:olive",
                  "accelerate": "tab:cyan", "weld": "white", "decelerate": "tab:cyan",
                  "retract": "0.9"}


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
