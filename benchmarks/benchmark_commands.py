"""Benchmark of every command as a user runs it (issue 41): wall time of whole processes.

Run: ``.venv/bin/python benchmarks/benchmark_commands.py [--runs 5] [--vs OTHER_CHECKOUT]
[--only NAME ...]`` (``make bench`` runs it with the defaults).

Each command runs as its own process, ``python -c 'from rfsw_plan.cli.main import console;
console()' ARGS`` (what the ``rfsw-plan`` script does) with the checkout on ``PYTHONPATH``,
from a temporary folder that receives every output. After one warm-up run (not counted: it
fills the disk cache, the compiled CasADi functions and the fitted penetration law, and writes
the plan the later commands read), each command runs ``--runs`` times, every run into a new
output folder; the table gives the median wall time and the spread (min-max):

* ``import floor``: ``python -c 'import numpy, scipy, casadi, pinocchio, toppra, ruckig'``,
  the time the dependencies alone take to import;
* ``reader floor``: ``python -c 'import numpy, pinocchio'``, what ``export`` and ``check``
  import at least (they need neither CasADi, TOPPRA nor Ruckig; their rotations add SciPy's
  rotation backend, ``rfsw_plan.robot.rotation``);
* ``plan zk500``: ``plan zk500_table6_seam -q``;
* ``export zk500``: that plan's programs in 4 formats (``krl,fanuc_tp,rapid,stream``);
* ``check zk500``: ``check`` of its KRL ``.src`` against the plan;
* ``plan kr600 --export``: ``plan kr600_curved_seam --export krl,fanuc_tp,rapid``;
* ``plan kr600``: the same plan alone.

Each command's ratio to the import floor says how much of its time is the tool's own work (a
ratio of 1 is a command that costs no more than its imports). With ``--vs OTHER_CHECKOUT`` the
same commands run with that tree on ``PYTHONPATH`` (the same interpreter), interleaved run by
run (this tree, the other, this tree, ...) so both see the same machine load, and the table adds
the other's median and the median of the pairwise ratios this/other: before and after a change
in one run. Timings depend on the machine and its load; they are never part of the tests.

Disk cache: each tree has its own (``RFSW_PLAN_CACHE`` in the scratch folder), empty at the
start, so each runs as its own rule of what to compile leaves it after a first run: the
counted runs of a command begin once the compiler processes its warm-up left in the
background are done (``planning/casadi_.py``, ``compile_in_background``), and neither tree
runs a library only the other compiled.

Bytecode: each tree's commands run with Python's bytecode cache (``PYTHONPYCACHEPREFIX`` in the
scratch folder, filled by the warm-up), as an installed package runs (pip compiles it at
install), even where the environment sets ``PYTHONDONTWRITEBYTECODE`` (then every start
compiles the package's sources again, which no installed package does). ``--no-bytecode`` keeps
the environment's setting. The table gives the median CPU time (user + system, from the
operating system's accounting of the finished child) next to the wall time: on a busy machine
the CPU time is the steadier figure.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLI = "import sys; from rfsw_plan.cli.main import console; sys.argv[0] = 'rfsw-plan'; console()"
IMPORTS = "import numpy, scipy, casadi, pinocchio, toppra, ruckig"
#: What ``export`` and ``check`` cannot start without: NumPy and Pinocchio (the kinematics);
#: their rotations add SciPy's rotation backend (``rfsw_plan.robot.rotation``).
READER_IMPORTS = "import numpy, pinocchio"
PLAN = "zk500_table6_seam"


@dataclass(frozen=True)
class Command:
    """One benchmarked command: its name and its argument list, where ``{out}`` is a new
    folder for each run and ``{plan}`` / ``{src}`` the plan and the program of the warm-up."""

    name: str
    args: tuple[str, ...]  #: after the interpreter; ("-c", IMPORTS) for the import floor
    label: str  #: the command line as the table shows it


COMMANDS = (
    Command("import floor", ("-c", IMPORTS), f"python -c '{IMPORTS}'"),
    Command("reader floor", ("-c", READER_IMPORTS), f"python -c '{READER_IMPORTS}'"),
    Command("plan zk500", ("-c", CLI, "plan", PLAN, "-q", "-o", "{out}"),
            f"rfsw-plan plan {PLAN} -q"),
    Command("export zk500", ("-c", CLI, "export", "{plan}", "-q", "-o", "{out}", "--format",
                             "krl,fanuc_tp,rapid,stream"),
            "rfsw-plan export PLAN --format krl,fanuc_tp,rapid,stream"),
    Command("check zk500", ("-c", CLI, "check", "{src}", "--plan", "{plan}"),
            f"rfsw-plan check rfsw_{PLAN}.src --plan PLAN"),
    Command("plan kr600 --export", ("-c", CLI, "plan", "kr600_curved_seam", "-q", "-o", "{out}",
                                    "--export", "krl,fanuc_tp,rapid"),
            "rfsw-plan plan kr600_curved_seam --export krl,fanuc_tp,rapid"),
    Command("plan kr600", ("-c", CLI, "plan", "kr600_curved_seam", "-q", "-o", "{out}"),
            "rfsw-plan plan kr600_curved_seam"),
)


class Tree:
    """A checkout the commands run from (on ``PYTHONPATH``), with its own scratch folder."""

    def __init__(self, root: Path, scratch: Path, tag: str, bytecode: bool = True) -> None:
        self.root, self.tag = root, tag
        self.scratch = scratch / tag
        self.scratch.mkdir()
        self.cache = self.scratch / "cache"
        self.env = {**os.environ, "PYTHONPATH": str(root), "RFSW_PLAN_CACHE": str(self.cache)}
        if bytecode:  # as installed: sources compiled once (by the warm-up), then read
            self.env.pop("PYTHONDONTWRITEBYTECODE", None)
            self.env["PYTHONPYCACHEPREFIX"] = str(self.scratch / "pycache")
        self.plan = self.scratch / "plan"
        self.runs = 0

    def argv(self, cmd: Command) -> list[str]:
        self.runs += 1
        out = self.scratch / f"run{self.runs}"
        subs = {"{out}": str(out), "{plan}": str(self.plan),
                "{src}": str(self.plan / "programs" / f"rfsw_{PLAN}.src")}
        return [sys.executable, *(subs.get(a, a) for a in cmd.args)]

    def run(self, cmd: Command) -> tuple[float, float]:
        """Wall and CPU (user + system) time of one run [s]; a failed command stops the
        benchmark with its output."""
        argv = self.argv(cmd)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        p = subprocess.run(argv, cwd=self.scratch, env=self.env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if p.returncode != 0:
            sys.exit(f"{self.tag}: {cmd.label} exited {p.returncode}:\n{p.stderr[-2000:]}")
        return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)

    def settle(self, timeout_s: float = 900.0) -> None:
        """Wait until no build the commands left in the background is running in this tree's
        cache (no ``*.building`` folder)."""
        end = time.monotonic() + timeout_s
        while any(self.cache.glob("*.building")) and time.monotonic() < end:
            time.sleep(0.2)

    def prepare(self) -> None:
        """The plan and the programs ``export`` and ``check`` read (not timed)."""
        env = self.env
        for args in (["plan", PLAN, "-q", "-o", str(self.plan)],
                     ["export", str(self.plan), "-q", "-o", str(self.plan / "programs"),
                      "--format", "krl"]):
            p = subprocess.run([sys.executable, "-c", CLI, *args], cwd=self.scratch, env=env,
                               capture_output=True, text=True)
            if p.returncode != 0:
                sys.exit(f"{self.tag}: rfsw-plan {' '.join(args)} exited {p.returncode}:\n"
                         f"{p.stderr[-2000:]}")


def measure(trees: list[Tree], commands: list[Command], runs: int
            ) -> tuple[dict[str, list[list[float]]], dict[str, list[list[float]]]]:
    """Wall and CPU times per command: one list per tree, interleaved run by run across the
    trees."""
    times: dict[str, list[list[float]]] = {}
    cpus: dict[str, list[list[float]]] = {}
    for cmd in commands:
        for tree in trees:  # warm-up
            tree.run(cmd)
        for tree in trees:
            tree.settle()
        got: list[list[float]] = [[] for _ in trees]
        cpu: list[list[float]] = [[] for _ in trees]
        for _ in range(runs):
            for k, tree in enumerate(trees):
                wall, used = tree.run(cmd)
                got[k].append(wall)
                cpu[k].append(used)
        times[cmd.name], cpus[cmd.name] = got, cpu
        print(f"  {cmd.name}: " + "; ".join(
            f"{t.tag} {statistics.median(g):.2f} s" for t, g in zip(trees, got, strict=True)),
            file=sys.stderr, flush=True)
    return times, cpus


def table(trees: list[Tree], commands: list[Command], times: dict[str, list[list[float]]],
          runs: int, cpus: dict[str, list[list[float]]] | None = None) -> str:
    """The figures: per command the median wall time (min-max), its ratio to the import
    floor, and with a second tree that tree's median and the median pairwise ratio."""
    floor = times.get("import floor")
    head = f"{'command':<22}{'median s':>10}{'min-max s':>14}{'x floor':>9}"
    if len(trees) == 2:
        head += f"{'other s':>10}{'x floor':>9}{'this/other':>12}"
    if cpus is not None:
        head += f"{'cpu s':>8}" + (f"{'other cpu':>10}" if len(trees) == 2 else "")
    lines = [f"median wall time of {runs} runs each (after a warm-up), "
             f"{os.cpu_count()} cores; this = {trees[0].root}"
             + (f", other = {trees[1].root}" if len(trees) == 2 else ""), head]
    for cmd in commands:
        got = times[cmd.name]
        row = f"{cmd.name:<22}"
        for k in range(len(trees)):
            med = statistics.median(got[k])
            ratio = f"{med / statistics.median(floor[k]):.2f}" if floor else "-"
            if k == 0:
                row += f"{med:>10.2f}{f'{min(got[k]):.2f}-{max(got[k]):.2f}':>14}{ratio:>9}"
            else:
                row += f"{med:>10.2f}{ratio:>9}"
        if len(trees) == 2:
            pairs = [a / b for a, b in zip(got[0], got[1], strict=True)]
            row += f"{statistics.median(pairs):>12.2f}"
        if cpus is not None:
            row += "".join(f"{statistics.median(c):>{8 if k == 0 else 10}.2f}"
                           for k, c in enumerate(cpus[cmd.name]))
        lines.append(row)
    lines.append("commands:")
    lines += [f"  {c.name:<22}{c.label}" for c in commands]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0])
    ap.add_argument("--runs", type=int, default=5, help="counted runs per command (5)")
    ap.add_argument("--vs", type=Path, default=None, metavar="CHECKOUT",
                    help="a second checkout to run the same commands with, interleaved")
    ap.add_argument("--no-bytecode", action="store_true",
                    help="keep the environment's PYTHONDONTWRITEBYTECODE (see the docstring)")
    ap.add_argument("--only", nargs="+", default=None, metavar="NAME",
                    choices=[c.name for c in COMMANDS], help="these commands only")
    args = ap.parse_args(argv)
    if args.runs < 1:
        ap.error("--runs must be at least 1")
    if args.vs is not None and not (args.vs / "rfsw_plan" / "__init__.py").is_file():
        ap.error(f"--vs {args.vs}: not a checkout of rfsw_plan (no rfsw_plan/__init__.py)")
    commands = [c for c in COMMANDS if args.only is None or c.name in args.only]
    scratch = Path(tempfile.mkdtemp(prefix="rfsw-bench-"))
    try:
        trees = [Tree(ROOT, scratch, "this", not args.no_bytecode)]
        if args.vs is not None:
            trees.append(Tree(args.vs.resolve(), scratch, "other", not args.no_bytecode))
        for tree in trees:
            tree.prepare()
            tree.settle()
        times, cpus = measure(trees, commands, args.runs)
        print(table(trees, commands, times, args.runs, cpus))
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
