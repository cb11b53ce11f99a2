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


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
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
