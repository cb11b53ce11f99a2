"""``rfsw-plan deviation PROBLEM``: predicted uncompensated pin deviation along the seam."""

from __future__ import annotations

import argparse
import csv
import logging
from pathlib import Path

import numpy as np

from rfsw_plan.process.deviation import DeviationResult, problem_deviation
from rfsw_plan.process.problem import Problem, load_problem, with_process

NAME = "deviation"
HELP = "predict the uncompensated lateral/axial/along-track pin deviation of a problem"

log = logging.getLogger(__name__)


def register(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("problem", metavar="PROBLEM",
                        help="problem file or bundled stem (e.g. zk500_table6_seam)")
    parser.add_argument("-o", "--output", metavar="DIR", default=None,
                        help="output folder (default out/<problem>)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--dt", type=float, default=0.1, metavar="S",
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
    from rfsw_plan.exceptions import InputError

    if not (np.isfinite(args.dt) and args.dt > 0):
        raise InputError("--dt", "", f"got {args.dt:g}", "> 0")
    from rfsw_plan.io.files import (
        OutputLock,
        atomic_path,
        prepare_output_dir,
        strict_json,
        write_json,
    )

    problem = load_problem(args.problem)
    out = prepare_output_dir(args.output if args.output else Path("out") / problem.name)
    fit_text = ""
    fit_json = None
    if args.forces is not None:
        problem, fit_text, fit_json = _fit(problem, args.forces, args.forces_frame)
    res = problem_deviation(problem, dt=args.dt, cosim=args.cosim)
    data = {"problem": problem.name, "robot": problem.robot.name, **res.to_dict()}
    if fit_json is not None:
        data["force_fit"] = fit_json
    files = ["deviation.csv", "deviation_time.csv", "deviation.json"]
    with OutputLock(out):
        with atomic_path(out / "deviation.csv") as tmp:
            _write_csv(tmp, res, problem.robot.convention.column_names())
        with atomic_path(out / "deviation_time.csv") as tmp:
            _write_time_csv(tmp, res)
        write_json(out / "deviation.json", data)
        if not args.no_plot:
            with atomic_path(out / "deviation.png") as tmp:
                plot_deviation(res, tmp, title=problem.title or problem.name)
            files.append("deviation.png")
    data["files"] = [str(out / f) for f in files]
    if args.json:
        print(strict_json(data, indent=None), end="")
        return 0
    print(_summary(problem, res))
    if fit_text:
        print(fit_text)
    if res.cosim is not None:
        print(res.cosim.summary())
    print(f"wrote {', '.join(files)} to {out}")
    return 0


def _fit(problem: Problem, path: str, frame: str | None) -> tuple[Problem, str, dict[str, object]]:
    from rfsw_plan.io.force_series import read_force_series
    from rfsw_plan.process.force_fit import fit_process_forces

    series = read_force_series(path, frame)
    fit = fit_process_forces(problem.process, problem.frames(), series,
                             problem.planning.tool_rotation)
    js = {"params": fit.params, "std": fit.std, "fixed": list(fit.fixed),
          "rms_N": fit.rms.tolist(), "r2": [None if not np.isfinite(v) else float(v)
                                            for v in fit.r2],
          "rms_total_N": fit.rms_total, "loss_N2": fit.loss, "notes": list(fit.notes)}
    return with_process(problem, fit.process), fit.summary(), js


def _summary(problem: Problem, res: DeviationResult) -> str:
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
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        nq = res.q.shape[1]
        w.writerow(["s_mm", "x_mm", "y_mm", "z_mm", "f_t_N", "f_l_N", "f_n_N", "lateral_mm",
                    "axial_mm", "along_mm", "inside_window",
                    *joint_columns[:nq]])
        for k in range(len(res.frames)):
            w.writerow([
                f"{res.frames.s[k] * 1e3:.3f}", *(f"{v * 1e3:.3f}" for v in res.frames.p[k]),
                *(f"{v:.2f}" for v in res.force_seam[k]), f"{res.lateral[k] * 1e3:.4f}",
                f"{res.axial[k] * 1e3:.4f}", f"{res.along[k] * 1e3:.4f}",
                int(res.inside[k]), *(f"{v:.4f}" for v in np.rad2deg(res.q[k])),
            ])


def _write_time_csv(path: Path, res: DeviationResult) -> None:
    sch = res.schedule
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t_s", "phase", "s_mm", "depth_mm", "f_t_N", "f_l_N", "f_n_N",
                    "lateral_mm", "axial_mm", "along_mm"])
        F = res.cosim.force_seam if res.cosim is not None else sch.force_seam
        for k in range(len(sch)):
            w.writerow([f"{sch.t[k]:.3f}", sch.phase[k], f"{sch.s[k] * 1e3:.3f}",
                        f"{sch.depth[k] * 1e3:.3f}", *(f"{v:.2f}" for v in F[k]),
                        f"{res.lateral_t[k] * 1e3:.4f}", f"{res.axial_t[k] * 1e3:.4f}",
                        f"{res.along_t[k] * 1e3:.4f}"])


def plot_deviation(res: DeviationResult, path: Path, title: str = "") -> Path:
    """PNG: lateral deviation along the seam with the weld-window band, and the deviation
    over time through the phases (matplotlib, Agg backend, imported here)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mm = 1e3
    w = res.window
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 7), constrained_layout=True)
    s = res.frames.s * mm
    a1.axhspan(w.lower * mm, w.upper * mm, color="tab:green", alpha=0.2, label="weld window")
    a1.axhline(w.target * mm, color="tab:green", ls=":", lw=0.8)
    a1.axhline(-w.target * mm, color="tab:green", ls=":", lw=0.8, label="+-target")
    a1.plot(s, res.lateral * mm, "o-", ms=3, label="lateral (+ advancing)")
    a1.plot(s, res.axial * mm, "s-", ms=2, label="axial (+ up)")
    a1.plot(s, res.along * mm, "^-", ms=2, label="along-track")
    a1.set_xlabel("arc length s [mm]")
    a1.set_ylabel("deviation [mm]")
    a1.set_title(f"{title}\nuncompensated deviation at the waypoints (steady weld force)")
    a1.legend(fontsize=8)
    a1.grid(alpha=0.3)
    sch = res.schedule
    a2.axhspan(w.lower * mm, w.upper * mm, color="tab:green", alpha=0.2)
    a2.plot(sch.t, res.lateral_t * mm, label="lateral")
    a2.plot(sch.t, res.axial_t * mm, label="axial")
    a2.plot(sch.t, res.along_t * mm, label="along-track")
    for ph in ("plunge", "dwell", "weld", "retract"):
        m = sch.mask(ph)
        if m.any():
            t0 = float(sch.t[m][0])
            a2.axvline(t0, color="k", lw=0.5, ls="--")
            a2.text(t0, a2.get_ylim()[1], ph, fontsize=7, va="top")
    a2.set_xlabel("time [s]")
    a2.set_ylabel("deviation [mm]")
    a2.set_title("over time (plunge, dwell, weld, retract)")
    a2.legend(fontsize=8)
    a2.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
