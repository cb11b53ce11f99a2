"""Kill campaign of issue 25: SIGKILL and SIGTERM at random moments of ``plan --export`` and of
``export``, into a folder that holds an earlier complete plan.

After every kill the folder must pass the plan-folder check (:meth:`PlanFolder.open`: a
success record whose every vouched file is there, byte for byte), or hold no success record and
no stray temporary file (no hidden entry: no ``.*.tmp``, no ``.export-*`` staging folder, no
``.rfsw-plan.lock``). A SIGTERM must end with exit 130 (or 0 if the run had finished), never a
traceback. The next plan into a killed folder must succeed and leave a whole plan.

Run ``python tests/kill_campaign.py [--kills 20] [--seed S]`` for the table;
``tests/test_kill_and_concurrency.py`` runs a few of these moments under ``-m slow``.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROBLEM = "zk500_table6_seam"
FORMATS = "krl,fanuc_tp,rapid"
#: The moment of a kill is drawn from [START_S, duration]: before START_S the interpreter itself
#: is starting (no rfsw_plan code has run, nothing is written, and Python's default SIGTERM
#: action applies).
START_S = 0.3


def _command(kind: str, out: Path) -> list[str]:
    argv = (["plan", PROBLEM, "-o", str(out), "--export", FORMATS] if kind == "plan --export"
            else ["export", str(out), "--format", FORMATS])
    # what the rfsw-plan script runs (its console entry point)
    return [sys.executable, "-c", "from rfsw_plan.cli.main import console; console()", "-q",
            *argv]


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}


@dataclass
class Kill:
    """One kill and what it left."""

    kind: str
    sig: str
    at_s: float
    returncode: int
    verdict: str  # "complete plan", "no success record", or what is wrong
    ok: bool


def folder_verdict(out: Path) -> tuple[bool, str]:
    """(acceptable, description) of a folder after a kill."""
    from rfsw_plan.exceptions import InputError
    from rfsw_plan.planfiles.folder import PlanFolder

    hidden = sorted(p.name for p in out.iterdir() if p.name.startswith("."))
    try:
        rec = json.loads((out / "plan.json").read_text())
        status = str(rec.get("status", ""))
    except (OSError, ValueError):
        rec, status = None, "unreadable"
    success = status not in ("incomplete", "infeasible", "failed", "unreadable")
    if success:
        try:
            PlanFolder.open(out)
        except InputError as exc:
            return False, f"success record, check fails: {exc}"
        return True, "complete plan" + (f" (hidden: {', '.join(hidden)})" if hidden else "")
    if hidden:
        return False, f"'{status}' record with stray {', '.join(hidden)}"
    return True, f"no success record ('{status}')"


def run_kills(kind: str, sig: signal.Signals, moments: list[float], old: Path,
              work: Path) -> list[Kill]:
    """Kill ``kind`` at each moment [s] in a copy of the complete plan folder ``old``."""
    kills = []
    for i, at in enumerate(moments):
        out = work / f"{kind.split()[0]}_{sig.name}_{i}"
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.rmtree(out, ignore_errors=True)
        shutil.copytree(old, out)
        proc = subprocess.Popen(_command(kind, out), env=_env(), stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE)
        time.sleep(at)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=600)
        ok, verdict = folder_verdict(out)
        if sig == signal.SIGTERM and (proc.returncode not in (130, 0) or b"Traceback" in err):
            ok = False
            verdict += f"; SIGTERM ended with {proc.returncode}: {err.decode()[-200:]}"
        kills.append(Kill(kind, sig.name, at, proc.returncode, verdict, ok))
    return kills


def duration(kind: str, old: Path, work: Path) -> float:
    """Wall time of one uninterrupted run [s]."""
    out = work / f"timing_{kind.split()[0]}"
    shutil.rmtree(out, ignore_errors=True)
    shutil.copytree(old, out)
    t0 = time.monotonic()
    subprocess.run(_command(kind, out), env=_env(), check=True, capture_output=True)
    return time.monotonic() - t0


def old_plan(work: Path) -> Path:
    """A complete plan with its programs (``plan --export``): the folder every run starts in."""
    out = work / "old"
    if not (out / "plan.json").exists():
        subprocess.run(_command("plan --export", out), env=_env(), check=True,
                       capture_output=True)
    return out


def campaign(kills: int, seed: int, work: Path,
             kinds: tuple[str, ...] = ("plan --export", "export"),
             signals: tuple[signal.Signals, ...] = (signal.SIGKILL, signal.SIGTERM),
             verbose: bool = False) -> list[Kill]:
    old = old_plan(work)
    out: list[Kill] = []
    for kind in kinds:
        total = duration(kind, old, work)
        for sig in signals:
            rng = random.Random(f"{seed}:{kind}:{sig.name}")
            moments = sorted(rng.uniform(START_S, total) for _ in range(kills))
            for at in moments:
                k = run_kills(kind, sig, [at], old, work / f"{sig.name}_{at:.3f}")[0]
                if verbose:
                    print(f"{k.kind} | {k.sig} | {k.at_s:.2f} of {total:.1f} s | exit "
                          f"{k.returncode} | {'ok' if k.ok else 'NOT OK'} | {k.verdict}",
                          flush=True)
                out.append(k)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--kills", type=int, default=20, help="kills per command and signal")
    ap.add_argument("--seed", type=int, default=25)
    ap.add_argument("--kinds", default="plan --export,export")
    ap.add_argument("--signals", default="SIGKILL,SIGTERM")
    ap.add_argument("--old", default=None, help="a complete plan --export folder to start from")
    args = ap.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="rfsw_kill_"))
    if args.old:
        shutil.copytree(args.old, work / "old")
    try:
        result = campaign(args.kills, args.seed, work, tuple(args.kinds.split(",")),
                          tuple(signal.Signals[s] for s in args.signals.split(",")),
                          verbose=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print("| command | signal | kills | folder acceptable | SIGTERM exit 130 (or 0) |")
    print("|---|---|---|---|---|")
    for kind in ("plan --export", "export"):
        for sig in ("SIGKILL", "SIGTERM"):
            ks = [k for k in result if k.kind == kind and k.sig == sig]
            good = sum(k.ok for k in ks)
            codes = ("-" if sig == "SIGKILL" else
                     str(sum(k.returncode in (130, 0) for k in ks)))
            print(f"| {kind} | {sig} | {len(ks)} | {good} | {codes} |")
    for k in result:
        if not k.ok:
            print(f"- {k.kind} {k.sig} at {k.at_s:.2f} s (exit {k.returncode}): {k.verdict}")
    states: dict[str, int] = {}
    for k in result:
        key = k.verdict.split(" (")[0]
        states[key] = states.get(key, 0) + 1
    print("states left:", ", ".join(f"{v} x {s}" for s, v in sorted(states.items())))
    return 0 if all(k.ok for k in result) else 1


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    raise SystemExit(main())
