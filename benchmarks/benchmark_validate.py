"""Benchmark: time and peak memory of a full ``validate`` on 10^4 / 10^5 / 10^6 samples.

Simulates a zk500 load campaign (poses x loads) with hidden effects, then times the steps of
``rfsw-plan validate``: reading is skipped (in memory), the validation itself (noise floor,
cross-validation of the model, residual analysis, diagnosis of every candidate effect on every
joint) and the report (plots on a subsample, HTML, JSON). Every size runs in its own process so
that its peak resident memory (VmHWM) is its own. Where it is affordable (``--old-max``)
the same case is also run on the old path (the stacked regressor of all samples,
``_cross_validate_stacked``) in another process, and the ratio is printed. The verdicts of the
two paths are printed side by side; they must be the same. Asserts nothing.

Run: ``.venv/bin/python benchmarks/benchmark_validate.py [--sizes 10000,100000,1000000]
[--cases one,two,add] [--old-max 10000] [--folds 5]``

``--real [--vs OTHER_CHECKOUT]`` instead times the commands of issue 40 as a user runs them
(wall and user CPU time of the whole command, imports and worker processes included, in a
fresh process):
``calibrate`` on the FANUC R-2000iC/165F set, ``calibrate`` on UR10 Series A + B (all poses),
and ``validate`` on the guide's 320-row campaign (docs/guide/validate.md), with the figure each
prints; with ``--vs`` the same commands also run on another checkout (e.g.
``git worktree add /tmp/base main``), before and after side by side, then before -> after
of each against issue 40's target (:data:`TARGET_S`). The shared data sets live in
``../shared/data`` of either checkout (``--data-dir``).
"""

from __future__ import annotations

import argparse
import gc
import json
import subprocess
import sys
import tempfile
import time
from typing import Any

#: Distinct poses at most (zk500 has about 70000 tool-down poses in front of it).
MAX_POSES = 25_000
#: name -> (title, hidden effects, effects given with --add)
CASES: dict[str, tuple[str, list[str], list[str]]] = {
    "one": ("one hidden effect", ["tilting_compliance:j2"], []),
    "two": ("two hidden effects (greedy chain)", ["payload_gravity", "joint_backlash:j3"], []),
    "add": ("one hidden effect, --add it", ["tilting_compliance:j2"], ["tilting_compliance:j2"]),
}


def _peak_mb() -> float:
    """Peak resident memory of this process since the last reset (VmHWM) [MB]."""
    with open("/proc/self/status") as f:
        return next(int(ln.split()[1]) for ln in f if ln.startswith("VmHWM")) / 1024


def _reset_peak() -> float:
    """Reset VmHWM to the current resident memory (Linux clear_refs 5); return it [MB]."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    return _peak_mb()


def child(samples: int, case: str, folds: int, old: bool) -> dict[str, Any]:
    """Run one case on one size in this process; return its figures."""
    import rfsw_plan.validation.engine.crossval as crossval
    import rfsw_plan.validation.engine.diagnosis as diagnosis
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.robot.kinematics import load_robot
    from rfsw_plan.validation import workbench
    from rfsw_plan.validation.campaign.simulation import run_campaign
    from rfsw_plan.validation.report.validate import write_report

    if old:  # the stacked regressor of all samples (before the fit in blocks)
        @crossval.single_thread_numpy_blas
        def stacked(model: Any, data: Any, folds_: Any, batch: Any = None) -> Any:
            k = int(folds_.max()) + 1
            obs = folds_[:, None].repeat(data.measured.shape[1], 1)[data.measured]
            min_train = min(int((obs != f).sum()) for f in range(k))
            return crossval._cross_validate_stacked(
                model, data, folds_, model.batch(data.q) if batch is None else batch, min_train)

        diagnosis.cross_validate = stacked  # type: ignore[assignment]
        workbench.cross_validate = stacked  # type: ignore[attr-defined]
    title, hidden, add = CASES[case]
    robot = load_robot("zk500")
    model = ElastostaticModel(robot)
    # 4 loads per pose up to MAX_POSES poses (a campaign); beyond, more samples per pose (a
    # 1 kHz log dwells at each pose: 10^6 samples = 25000 poses x 40 samples).
    poses = max(min(samples // 4, MAX_POSES), folds)
    loads = max(samples // poses, 1)
    t0 = time.perf_counter()
    camp = run_campaign(robot, hidden, poses=poses, loads_per_pose=loads, noise_mm=0.01, seed=1)
    data = camp.data
    del camp
    gc.collect()
    simulate_mb = _peak_mb()
    base_mb = _reset_peak()  # (also resets ru_maxrss on Linux)
    t1 = time.perf_counter()
    result = workbench.validate(model, data, add=add, folds=folds)
    validate_mb = _peak_mb()
    t2 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        write_report(result, tmp)
    t3 = time.perf_counter()
    dg = result.diagnosis
    return {
        "samples": poses * loads, "case": case, "title": title, "old": old,
        "simulate_s": t1 - t0, "validate_s": t2 - t1, "report_s": t3 - t2,
        "total_s": t3 - t1, "diagnosis_s": dg.seconds,
        "candidates": len(dg.candidates) + len(dg.skipped), "chain": len(dg.chain),
        "verdict": dg.message,
        "peak_MB": max(simulate_mb, _peak_mb()),
        "validate_peak_MB": validate_mb, "data_MB": base_mb,
    }


def run_child(samples: int, case: str, folds: int, old: bool) -> dict[str, Any]:
    """The case in a fresh process (its own peak memory)."""
    cmd = [sys.executable, __file__, "--child", str(samples), "--cases", case,
           "--folds", str(folds)] + (["--old"] if old else [])
    out = subprocess.run(cmd, check=False, capture_output=True, text=True)
    if out.returncode:
        last = (out.stderr.strip().splitlines() or ["no output"])[-1]
        raise SystemExit(f"benchmark_validate: {samples} samples, case {case}: {last}")
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


#: Issue 40's wall-time target of each real command on this 2-core machine [s].
TARGET_S = {"fanuc": 20.0, "ur10": 120.0, "guide": 2.0}

#: name -> (title, command after ``rfsw-plan``, JSON key of the figure, its label); {data} is
#: the shared data folder, {tmp} a scratch folder.
REAL: dict[str, tuple[str, list[str], str, str]] = {
    "fanuc": ("FANUC calibrate (240 readings, 3 reflectors)",
              ["calibrate", "--robot", "fanuc_r2000ic_165f", "--data",
               "{data}/fanuc_r2000ic_165f/calibration_dataset.mat", "--columns",
               "examples/fanuc_r2000ic_165f/columns.toml", "--frame", "device", "--json"],
              "heldout_rms_mm", "held out (LOPO) mm"),
    "ur10": ("UR10 A + B calibrate (13,405 poses)",
             ["calibrate", "--robot", "ur10", "--data",
              "{data}/ur10_ipa/Series_A/measurements_grid.csv", "--data",
              "{data}/ur10_ipa/Series_B/measurements_joint_configurations.csv", "--columns",
              "examples/ur10_ipa/columns.toml", "--frame", "device", "--json"],
             "heldout_rms_mm", "held out (10 folds) mm"),
    "guide": ("validate, the guide's 320-row campaign",
              ["validate", "--robot", "zk500", "--data", "{tmp}/campaign.csv", "--json",
               "--no-report"], "verdict", "verdict"),
}


def _real(root: str, name: str, data: str, tmp: str, timeout: float
          ) -> tuple[float, float, str]:
    """Wall time and user CPU time [s] of one command on the checkout ``root`` and the figure
    it printed."""
    import os
    import resource

    _, cmd, key, _ = REAL[name]
    env = dict(os.environ, PYTHONPATH=root)
    args = [a.format(data=data, tmp=tmp) for a in cmd]
    t0 = time.perf_counter()
    u0 = resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
    try:
        out = subprocess.run([sys.executable, "-m", "rfsw_plan.cli.main", *args], cwd=root,
                             env=env, capture_output=True, text=True, timeout=timeout,
                             check=False)
    except subprocess.TimeoutExpired:
        return time.perf_counter() - t0, float("nan"), f"not finished in {timeout:.0f} s"
    wall = time.perf_counter() - t0
    user = resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime - u0
    if out.returncode:
        return wall, user, "failed: " + (out.stderr.strip().splitlines() or ["?"])[-1]
    j = json.loads(out.stdout)
    value = j.get(key, j.get("diagnosis", {}).get(key))
    shown = f"{value:.3f}" if isinstance(value, float) else str(value)
    return wall, user, shown


def real(names: list[str], roots: list[str], data: str, timeout: float) -> None:
    """Print the wall time and figure of each real command on each checkout."""
    import os

    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "rfsw_plan.cli.main", "simulate-campaign",
                        "--robot", "zk500", "--hidden", "payload_gravity=m:150,m_rz:-37.5",
                        "--hidden", "joint_backlash:j2", "--poses", "40", "--loads-per-pose",
                        "8", "--noise-mm", "0.01", "--seed", "1", "-o", f"{tmp}/campaign.csv"],
                       cwd=roots[0], env=dict(os.environ, PYTHONPATH=roots[0]), check=True,
                       capture_output=True)
        print(f"{'command':<44} {'checkout':<28} {'wall s':>8} {'user s':>8}  figure")
        got: dict[str, list[tuple[float, float, str]]] = {}
        for name in names:
            title, _, _, label = REAL[name]
            for root in roots:
                wall, user, shown = _real(root, name, data, tmp, timeout)
                got.setdefault(name, []).append((wall, user, shown))
                print(f"{title:<44} {root:<28} {wall:>8.1f} {user:>8.2f}  {label}: {shown}",
                      flush=True)
    if len(roots) < 2:
        return
    print(f"\nbefore ({roots[1]}) -> after ({roots[0]}); user = CPU time of the command and "
          "its worker processes")
    for name in names:
        (wa, ua, fa), (wb, ub, fb) = got[name]
        title, _, _, label = REAL[name]
        print(f"{title:<44} wall {wb:7.1f} -> {wa:7.1f} s (target <= {TARGET_S[name]:g} s: "
              f"{'holds' if wa <= TARGET_S[name] else 'not met'}), user {ub:7.2f} -> "
              f"{ua:7.2f} s, {label} {fb} -> {fa}")


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--real", nargs="?", const="fanuc,ur10,guide", default=None,
                        help="time the real commands instead (of fanuc, ur10, guide)")
    parser.add_argument("--vs", default=None, help="another checkout to time too (--real)")
    parser.add_argument("--data-dir", default=None,
                        help="shared data folder (default ../shared/data of this checkout)")
    parser.add_argument("--timeout", type=float, default=3600.0,
                        help="seconds before a real command is given up (--real)")
    parser.add_argument("--sizes", default="10000,100000,1000000",
                        help="comma-separated numbers of samples")
    parser.add_argument("--cases", default="one,two,add", help=f"of {', '.join(CASES)}")
    parser.add_argument("--folds", type=int, default=5, help="cross-validation folds")
    parser.add_argument("--old-max", type=int, default=10_000,
                        help="also run the old (stacked) path up to this many samples")
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--old", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        print(json.dumps(child(args.child, args.cases, args.folds, args.old)))
        return
    if args.real is not None:
        from pathlib import Path

        here = str(Path(__file__).resolve().parents[1])
        roots = [here] + ([str(Path(args.vs).resolve())] if args.vs else [])
        near = [Path(r).parent / "shared" / "data" for r in roots]  # a worktree: the other's
        data = args.data_dir or str(next((d for d in near if d.is_dir()), near[0]))
        real(args.real.split(","), roots, data, args.timeout)
        return
    print(f"zk500, 4 loads per pose up to {MAX_POSES} poses, {args.folds} folds; validate = "
          "cross-validation, residual analysis and diagnosis; report = plots, HTML, JSON; "
          "peak = the process's peak resident memory (campaign simulation included); "
          "val. MB = peak resident memory during validate alone (VmHWM reset after the "
          "simulation; the data in memory included)")
    print(f"{'samples':>8} {'case':<34} {'path':<7} {'validate s':>10} {'report s':>9} "
          f"{'total s':>8} {'peak MB':>8} {'val. MB':>8} {'old/new':>8}")
    for size in (int(s) for s in args.sizes.split(",")):
        for case in args.cases.split(","):
            new = run_child(size, case, args.folds, old=False)
            rows = [new]
            if size <= args.old_max:
                rows.append(run_child(size, case, args.folds, old=True))
            for r in rows:
                ratio = (f"{rows[1]['total_s'] / new['total_s']:8.2f}"
                         if len(rows) > 1 and r is new else "")
                print(f"{r['samples']:>8} {r['title']:<34} {'old' if r['old'] else 'blocks':<7} "
                      f"{r['validate_s']:>10.2f} {r['report_s']:>9.2f} {r['total_s']:>8.2f} "
                      f"{r['peak_MB']:>8.0f} {r['validate_peak_MB']:>8.0f} {ratio:>8}", flush=True)
                print(f"{'':>8}   verdict: {r['verdict']}", flush=True)
            if len(rows) > 1 and rows[0]["verdict"] != rows[1]["verdict"]:
                print(f"{'':>8}   VERDICTS DIFFER between the two paths", flush=True)


if __name__ == "__main__":
    main()
