"""The reliability campaign of issue 25: ``rfsw-plan`` tried as a careless or unlucky user would.

Each *kind* of input (output paths, CLI numbers, URDF, measurement CSV, force logs, weld tracks,
column maps, damaged plan folders handed to ``export``) has a seeded generator of cases. A case
is a command line and the files it reads, with what a user expects: ``refuse`` (the input is
wrong: one line, exit 2 or 3) or ``any`` (a legitimate or harmless edit: exit 0 is fine, and the
output must hold no null or NaN where a number belongs).

Every case runs in this process through the CLI's ``main()`` (the 3 s of imports are paid once),
with stderr and stdout captured and a time limit. The outcome of each is one of:

* ``traceback``: an exception escaped ``main()`` or a traceback reached stderr;
* ``hang``: the time limit passed;
* ``crash``: an exit code other than 0, 2, 3, or an error that is not exactly one line;
* ``silent accept``: exit 0 on a case that must be refused;
* ``null/NaN output``: exit 0 with null or NaN where the output promises a number;
* ``ok``.

Run ``python tests/fuzz_campaign.py [--cases N] [--seed S]`` for the acceptance table (kind x runs
/ traceback / hang / crash / silent accept / null-NaN output); ``tests/test_fuzz_campaign.py``
runs a bounded sample of every kind in the default test run and a longer one under ``-m slow``.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import math
import os
import random
import re
import shutil
import signal
import sys
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
KINDS = ("output paths", "CLI numbers", "URDF", "measurement CSV", "force logs", "weld tracks",
         "column maps", "plan folders -> export")
OUTCOMES = ("traceback", "hang", "crash", "silent accept", "null/NaN output")
PROBLEM = "zk500_table6_seam"
#: Time limit of one case [s] (a refusal takes milliseconds; an accepted case seconds).
TIME_LIMIT_S = 120.0


@dataclass
class Case:
    """One run of the CLI.

    Attributes:
        kind: One of :data:`KINDS`.
        label: What was done to the input (for the report).
        argv: The command line after ``rfsw-plan``; ``{d}`` is replaced by the case folder.
        expect: ``refuse`` or ``any``.
        files: File name -> bytes written into the case folder first (``None``: a folder).
        setup: Extra preparation of the case folder (symlink loops, read-only folders).
        numbers: JSON keys of the ``--json`` output that must hold finite numbers.
    """

    kind: str
    label: str
    argv: list[str]
    expect: str = "refuse"
    files: dict[str, bytes | None] = field(default_factory=dict)
    setup: Callable[[Path], None] | None = None
    numbers: tuple[str, ...] = ()


class _Hang(BaseException):
    """The time limit of a case passed (a BaseException: no ``except Exception`` eats it)."""


@contextlib.contextmanager
def _time_limit(seconds: float) -> Iterator[None]:
    def fire(signum: int, frame: object) -> None:
        raise _Hang

    previous = signal.signal(signal.SIGALRM, fire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def run_case(case: Case, folder: Path, limit: float = TIME_LIMIT_S) -> tuple[str, str]:
    """Run one case in a fresh ``folder``; returns (outcome, detail)."""
    from rfsw_plan.cli.main import main

    if folder.exists():
        shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    for name, data in case.files.items():
        path = folder / name
        if data is None:
            path.mkdir(parents=True, exist_ok=True)
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
    if case.setup is not None:
        case.setup(folder)
    argv = ["-q", *(a.replace("{d}", str(folder)) for a in case.argv)]
    out, err = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(folder)  # a default output folder lands in the case folder, not the repository
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
                _time_limit(limit):
            code = main(argv)
    except _Hang:
        return "hang", f"{limit:g} s"
    except BaseException:  # anything that escapes main() is a traceback for the user
        return "traceback", traceback.format_exc(limit=-3).strip().splitlines()[-1]
    finally:
        os.chdir(cwd)
    return _classify(case, code, out.getvalue(), err.getvalue())


def _classify(case: Case, code: int, out: str, err: str) -> tuple[str, str]:
    if "Traceback" in err:
        return "traceback", err.strip().splitlines()[-1]
    if code not in (0, 2, 3):
        return "crash", f"exit {code}: {err.strip()[:200]}"
    if code != 0:
        lines = err.strip().splitlines()
        if len(lines) != 1 or not lines[0].startswith("rfsw-plan"):
            return "crash", f"exit {code}, {len(lines)} lines: {err.strip()[:200]}"
        return "ok", lines[0]
    if case.expect == "refuse":
        return "silent accept", f"exit 0: {out.strip()[:160]}"
    if case.numbers:
        try:
            data = json.loads(out)
        except ValueError:
            return "null/NaN output", f"not JSON: {out[:120]!r}"
        for key in case.numbers:
            vals = data.get(key)
            flat = vals if isinstance(vals, list) else [vals]
            if not flat or any(not isinstance(v, int | float) or not math.isfinite(v)
                               for v in flat):
                return "null/NaN output", f"{key} = {vals}"
    return "ok", "accepted"


# -- the inputs the cases start from -------------------------------------------------------------


class Bases:
    """The valid inputs every kind mutates, made once (seconds) in ``folder``."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        folder.mkdir(parents=True, exist_ok=True)

    @cached_property
    def measurements(self) -> bytes:
        from rfsw_plan.cli.main import main

        path = self.folder / "m.csv"
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(["-q", "simulate-campaign", "--robot", "zk500", "--poses", "6",
                         "--loads-per-pose", "4", "-o", str(path)]) == 0
        return path.read_bytes()

    @cached_property
    def force_log(self) -> bytes:
        """The problem's own planned forces, seam frame, every 0.05 s, with 1 % noise."""
        import numpy as np

        from rfsw_plan.process.problem import load_problem

        pb = load_problem(PROBLEM)
        sch = pb.process.schedule(pb.frames(), 0.05)
        rng = np.random.default_rng(0)
        f = sch.force_seam * (1 + 0.01 * rng.normal(size=sch.force_seam.shape))
        rows = ["t_s,fx_N,fy_N,fz_N,frame"] + [
            f"{t:.3f},{a:.2f},{b:.2f},{c:.2f},seam" for t, (a, b, c) in zip(sch.t, f,
                                                                              strict=True)]
        return ("\n".join(rows) + "\n").encode()

    @cached_property
    def plan_dir(self) -> Path:
        from rfsw_plan.cli.main import main

        out = self.folder / "plan"
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(["-q", "plan", PROBLEM, "-o", str(out), "--spacing-mm", "20"]) == 0
        return out

    @cached_property
    def track(self) -> bytes:
        import numpy as np

        s = np.linspace(0.0, 300.0, 61)
        rows = ["s_mm,e_lat_mm"] + [f"{v:.3f},{0.2 * np.sin(v / 50):.4f}" for v in s]
        return ("\n".join(rows) + "\n").encode()

    @cached_property
    def urdf(self) -> bytes:
        return (ROOT / "robots" / "tiago_arm.urdf").read_bytes()

    @cached_property
    def urdf_robot(self) -> bytes:
        return (ROOT / "robots" / "tiago_arm.toml").read_bytes()


def _csv_rows(data: bytes) -> list[list[str]]:
    return list(csv.reader(io.StringIO(data.decode())))


def _csv_bytes(rows: list[list[str]], delim: str = ",") -> bytes:
    buf = io.StringIO()
    csv.writer(buf, delimiter=delim, lineterminator="\n").writerows(rows)
    return buf.getvalue().encode()


def _scaled(rows: list[list[str]], cols: tuple[str, ...], factor: float) -> list[list[str]]:
    idx = [rows[0].index(c) for c in cols if c in rows[0]]
    out = [list(rows[0])]
    for r in rows[1:]:
        r = list(r)
        for i in idx:
            if r[i] != "":
                r[i] = f"{float(r[i]) * factor:.9g}"
        out.append(r)
    return out


BAD_CELLS = ("nan", "inf", "-inf", "", "abc", "1e308", "-1e308", "1" * 140_000, "1,5", "0x1F")


def csv_mutations(rng: random.Random, data: bytes, numeric: list[str]) -> tuple[str, bytes, str]:
    """One mutation of a CSV: (label, bytes, expect). Structure, names and cells."""
    rows = _csv_rows(data)
    header = list(rows[0])
    op = rng.choice(["ragged_short", "ragged_long", "bad_cell", "typo", "upper", "drop",
                     "dup_header", "empty", "header_only", "crlf", "bom", "semicolon",
                     "truncate", "junk_bytes"])
    r = rng.randrange(1, len(rows))
    j = rng.randrange(len(header))
    if op == "ragged_short":
        rows[r] = rows[r][:-1]
        return f"row {r + 1} one cell short", _csv_bytes(rows), "refuse"
    if op == "ragged_long":
        rows[r] = [*rows[r], "7"]
        return f"row {r + 1} one cell extra", _csv_bytes(rows), "refuse"
    if op == "bad_cell":
        col = rng.choice(numeric)
        bad = rng.choice(BAD_CELLS)
        rows[r][header.index(col)] = bad
        # An empty position cell is "not measured", an empty track cell a gap.
        gap = bad == "" or (bad == "nan" and col.startswith(("e_", "s_")))
        expect = "any" if gap and re.fullmatch(r"[xyz]_mm|s_mm|e_lat_mm|e_norm_mm", col) \
            else "refuse"
        return f"row {r + 1} {col}={bad[:12]}", _csv_bytes(rows), expect
    if op == "typo":
        col = rng.choice(numeric)
        rows[0][header.index(col)] = col.replace("_", "__", 1)
        return f"{col} -> {rows[0][header.index(col)]}", _csv_bytes(rows), "refuse"
    if op == "upper":
        col = rng.choice(numeric)
        rows[0][header.index(col)] = col.upper()
        return f"{col} -> {col.upper()}", _csv_bytes(rows), "refuse"
    if op == "drop":
        col = rng.choice(numeric)
        i = header.index(col)
        # One measured axis less is a legitimate file (positions: at least one axis).
        expect = "any" if col in ("x_mm", "y_mm", "z_mm") and "q1_deg" in header else "refuse"
        return f"column {col} dropped", _csv_bytes([x[:i] + x[i + 1:] for x in rows]), expect
    if op == "dup_header":
        rows[0][j] = rows[0][(j + 1) % len(header)]
        return f"header {header[j]} duplicated", _csv_bytes(rows), "refuse"
    if op == "empty":
        return "empty file", b"", "refuse"
    if op == "header_only":
        return "header only", _csv_bytes(rows[:1]), "refuse"
    if op == "crlf":
        return "CRLF", data.replace(b"\n", b"\r\n"), "any"
    if op == "bom":
        return "BOM", b"\xef\xbb\xbf" + data, "any"
    if op == "semicolon":
        return "semicolon-separated", _csv_bytes(rows, ";"), "any"
    if op == "truncate":
        cut = rng.randrange(len(data) // 3, len(data) - 2)
        text = data[:cut]
        # A cut inside the last row leaves a short row (refused) or a shorter number (legit).
        return f"truncated at byte {cut}", text, "any"
    junk = bytes(rng.randrange(256) for _ in range(64))
    return "junk bytes", data[:200] + junk, "refuse"


# -- the kinds -----------------------------------------------------------------------------------


def output_path_cases(rng: random.Random, b: Bases) -> Case:
    cmd = rng.choice(["simulate", "deviation", "plan", "identify"])
    how = rng.choice(["loop", "loop_sub", "under_file", "long", "proc", "sys", "dir_target",
                      "empty"])
    files: dict[str, bytes | None] = {"afile": b"x"}
    setup = None
    if how in ("loop", "loop_sub"):
        def setup(d: Path) -> None:
            (d / "loop").symlink_to(d / "loop")
        target = "{d}/loop" + ("/sub" if how == "loop_sub" else "")
    elif how == "under_file":
        target = "{d}/afile/sub"
    elif how == "long":
        target = "{d}/" + "n" * rng.choice([256, 300, 1000])
    elif how == "proc":
        target = "/proc/self/rfsw"
    elif how == "sys":
        target = "/sys/rfsw"
    elif how == "empty":
        target = ""
    else:  # a folder where the command writes a file
        target = "{d}/out"
        name = {"simulate": "", "identify": "", "deviation": rng.choice(
            ["deviation.json", "deviation.csv", "deviation_time.csv"]),
            "plan": rng.choice(["plan.json", "waypoints.csv"])}[cmd]
        files[f"out/{name}" if name else "out"] = None
    if cmd in ("simulate", "identify") and how in ("loop", "loop_sub", "long", "under_file"):
        target += "/m.csv" if how != "long" else ".csv"
    argv = {
        "simulate": ["simulate-campaign", "--robot", "zk500", "--poses", "2", "-o", target],
        "identify": ["identify", "--robot", "zk500", "--data", "{d}/m.csv", "-o", target],
        "deviation": ["deviation", PROBLEM, "--no-plot", "-o", target],
        "plan": ["plan", PROBLEM, "-o", target],
    }[cmd]
    if cmd == "identify":
        files["m.csv"] = b.measurements
    return Case("output paths", f"{cmd} -o {how}", argv, "refuse", files, setup)


#: (command line, option) -> values a user may type that the physics refuses.
NUMERIC_OPTIONS: list[tuple[list[str], str, tuple[str, ...]]] = [
    (["deviation", PROBLEM, "--no-plot", "-o", "{d}/o"], "--dt",
     ("1e-9", "1e-6", "0", "-0.1", "1e4", "1e308")),
    (["compare", PROBLEM, "--no-plot", "-o", "{d}/o"], "--cycle-ms",
     ("1e-308", "0", "-4", "1e9", "0.01")),
    (["compare", PROBLEM, "--no-plot", "-o", "{d}/o"], "--sensor-rate-hz", ("0", "-1", "1e12")),
    (["compare", PROBLEM, "--no-plot", "-o", "{d}/o"], "--sensor-delay-ms", ("-1", "1e9")),
    (["compare", PROBLEM, "--no-plot", "-o", "{d}/o"], "--sensor-noise-N", ("-1", "1e308")),
    (["compare", PROBLEM, "--no-plot", "-o", "{d}/o"], "--force-drift", ("-0.5", "20")),
    (["compare", PROBLEM, "--no-plot", "-o", "{d}/o"], "--seed000-average", ("-1", "150")),
    (["compare", PROBLEM, "--no-plot", "-o", "{d}/o"], "--maf-samples", ("0", "-3", "1e9", "2.5")),
    (["compare", PROBLEM, "--no-plot", "-o", "{d}/o"], "--truth-stiffness-scale", ("0", "-1")),
    (["compare", PROBLEM, "--no-plot", "-o", "{d}/o"], "--seed", ("-1", "1.5", "2" * 30)),
    (["validate", "--robot", "zk500", "--data", "{d}/m.csv", "--no-report"], "--noise-mm",
     ("1e-308", "0", "-0.01", "1e308")),
    (["validate", "--robot", "zk500", "--data", "{d}/m.csv", "--no-report"], "--force-noise-N",
     ("0", "-1", "1e308")),
    (["validate", "--robot", "zk500", "--data", "{d}/m.csv", "--no-report"], "--folds",
     ("0", "1", "-2", "1e9")),
    (["simulate-campaign", "--robot", "zk500", "-o", "{d}/m2.csv"], "--noise-mm",
     ("1e308", "-1", "1e3")),
    (["simulate-campaign", "--robot", "zk500", "-o", "{d}/m2.csv"], "--poses",
     ("0", "-5", "1e9", "99999999")),
    (["simulate-campaign", "--robot", "zk500", "-o", "{d}/m2.csv"], "--loads-per-pose",
     ("0", "100000")),
    (["plan", PROBLEM, "-o", "{d}/o"], "--force-uncertainty",
     ("20", "5", "1.5", "-0.1", "-5%", "1e308%", "2000 %")),
    (["plan", PROBLEM, "-o", "{d}/o"], "--spacing-mm", ("0", "-1", "1e-9", "1e9")),
    (["plan", PROBLEM, "-o", "{d}/o", "--export", "krl"], "--export-spacing-mm", ("0", "1e9")),
    (["plan", PROBLEM, "-o", "{d}/o", "--export", "stream"], "--stream-cycle-ms",
     ("0", "1e-308", "1e9")),
    (["plan", PROBLEM, "-o", "{d}/o", "--export", "krl"], "--path-tol-mm", ("0", "1e9")),
    (["place", PROBLEM, "-o", "{d}/o"], "--force-uncertainty", ("20", "-1%")),
    (["place", PROBLEM, "-o", "{d}/o"], "--candidates", ("-1", "1e6")),
    (["place", PROBLEM, "-o", "{d}/o"], "--workers", ("0", "-2", "100000")),
    (["map", PROBLEM, "-o", "{d}/o"], "--waypoints", ("0", "1", "1e9")),
    (["validate-weld", "{d}/plan", "--track", "{d}/t.csv"], "--blocks", ("0", "1", "-1")),
    (["predict", "--robot", "zk500", "--q-deg", "0,10,-10,0,80,0"], "--wrench",
     ("1e308,0,0", "0,0,-1e308", "0,0,-5000,1e308,0,0", "nan,0,0", "1,2", "1,2,3,4",
      "0,0,-3e6")),
    (["predict", "--robot", "zk500", "--wrench", "0,0,-5000"], "--q-deg",
     ("1e308,0,0,0,0,0", "nan,0,0,0,0,0", "0,0,0", "0,200,0,0,0,0")),
]
GARBAGE = ("nan", "inf", "-inf", "", "abc", "1e", "--", "1.2.3")


def cli_number_cases(rng: random.Random, b: Bases) -> Case:
    base, option, values = rng.choice(NUMERIC_OPTIONS)
    value = rng.choice(values + GARBAGE)
    files: dict[str, bytes | None] = {}
    if "{d}/m.csv" in base:
        files["m.csv"] = b.measurements
    form = rng.choice(["sep", "eq"])
    argv = [*base, option, value] if form == "sep" else [*base, f"{option}={value}"]
    return Case("CLI numbers", f"{base[0]} {option} {value[:14]!r}", argv, "refuse", files)


URDF_BAD = {
    "axis": ("0 0 0", "nan 0 1", "0 0 1 0", "0 1", "a b c", ""),
    "origin": ("nan 0 0", "1e308 0 0", "0 0 0 0", "0 0", "0 inf 0", "x y z"),
    "rpy": ("nan 0 0", "0 0", "1 2 3 4"),
    "limit": ("swap", "nan", "inf"),
    "com": ("1e308 0 0", "nan 0 0", "0 0 0 0", "0 0"),
    "mass": ("nan", "-1", "1e308"),
}


def urdf_cases(rng: random.Random, b: Bases) -> Case:
    text = b.urdf.decode()
    what = rng.choice([*URDF_BAD, "harmless"])
    label = what
    expect = "refuse"
    if what == "harmless":
        choice = rng.choice(["comment", "spaces", "exponent"])
        label = f"harmless {choice}"
        expect = "any"
        if choice == "comment":
            text = text.replace("<robot", "<!-- fuzz -->\n<robot", 1)
        elif choice == "spaces":
            text = text.replace('xyz="0 0 1"', 'xyz="0  0  1"')
        else:
            text = text.replace('xyz="0 0 1"', 'xyz="0 0 1e0"')
    else:
        value = rng.choice(URDF_BAD[what])
        label = f"{what}={value!r}"
        pattern = {"axis": r'(<axis xyz=")([^"]*)(")',
                   "origin": r'(<joint[^>]*>\s*(?:<[^>]*>\s*)*?<origin xyz=")([^"]*)(")',
                   "rpy": r'(<joint[^>]*>\s*(?:<[^>]*>\s*)*?<origin xyz="[^"]*" rpy=")([^"]*)(")',
                   "limit": r'(<limit [^>]*lower=")([^"]*)(")',
                   "com": r'(<inertial>\s*<origin xyz=")([^"]*)(")',
                   "mass": r'(<mass value=")([^"]*)(")'}[what]
        hits = list(re.finditer(pattern, text))
        m = rng.choice(hits)
        if what == "limit" and value == "swap":
            tail = text[m.start():]
            lim = re.match(r'<limit ([^>]*)/>', tail[tail.index("<limit"):])
            assert lim is not None
            attrs = lim.group(1)
            lo = re.search(r'lower="([^"]*)"', attrs)
            hi = re.search(r'upper="([^"]*)"', attrs)
            assert lo and hi
            if float(lo.group(1)) == float(hi.group(1)):
                value = "nan"
            else:
                new = attrs.replace(f'lower="{lo.group(1)}"', f'lower="{hi.group(1)}"', 1)
                new = new.replace(f'upper="{hi.group(1)}"', f'upper="{lo.group(1)}"', 1)
                start = m.start() + tail.index("<limit")
                text = text[:start] + text[start:].replace(attrs, new, 1)
        if not (what == "limit" and value == "swap"):
            text = text[:m.start(2)] + value + text[m.end(2):]
    q = "0,10,10,10,10,10,10,10"
    return Case("URDF", label, ["predict", "--robot", "{d}/tiago_arm.toml", "--q-deg", q,
                                "--wrench", "0,0,-50,0,0,0", "--json"], expect,
                {"tiago_arm.toml": b.urdf_robot, "tiago_arm.urdf": text.encode()},
                numbers=("translation_mm", "rotation_mrad"))


MEAS_NUMERIC = ["q1_deg", "q3_deg", "q6_deg", "fx_N", "fz_N", "mx_Nm", "x_mm", "y_mm", "z_mm"]


def measurement_cases(rng: random.Random, b: Bases) -> Case:
    rows = _csv_rows(b.measurements)
    unit = rng.random() < 0.3
    if unit:
        slip = rng.choice(["kN forces", "kN forces and moments", "m positions", "rad joints",
                           "label kN"])
        if slip == "kN forces":
            data = _csv_bytes(_scaled(rows, ("fx_N", "fy_N", "fz_N"), 1e-3))
        elif slip == "kN forces and moments":
            data = _csv_bytes(_scaled(rows, ("fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm",
                                             "mz_Nm"), 1e-3))
        elif slip == "m positions":
            data = _csv_bytes(_scaled(rows, ("x_mm", "y_mm", "z_mm"), 1e-3))
        elif slip == "rad joints":
            data = _csv_bytes(_scaled(rows, tuple(f"q{j}_deg" for j in range(1, 7)),
                                      math.pi / 180))
        else:  # N data declared kN by its column names
            rows[0] = [c.replace("_N", "_kN") if c.startswith("f") else c for c in rows[0]]
            data = _csv_bytes(rows)
        label, expect = f"unit slip: {slip}", "refuse"
    else:
        label, data, expect = csv_mutations(rng, b.measurements, MEAS_NUMERIC)
    return Case("measurement CSV", label, ["identify", "--robot", "zk500", "--data",
                                           "{d}/m.csv", "--json"], expect, {"m.csv": data})


def force_log_cases(rng: random.Random, b: Bases) -> Case:
    rows = _csv_rows(b.force_log)
    if rng.random() < 0.3:
        slip = rng.choice(["kN", "ms"])
        data = _csv_bytes(_scaled(rows, ("fx_N", "fy_N", "fz_N"), 1e-3) if slip == "kN"
                          else _scaled(rows, ("t_s",), 1e3))
        label, expect = f"unit slip: {slip}", "refuse"
    else:
        label, data, expect = csv_mutations(rng, b.force_log, ["t_s", "fx_N", "fy_N", "fz_N"])
    cmd = rng.choice(["deviation", "plan"])
    argv = (["deviation", PROBLEM, "--forces", "{d}/f.csv", "--no-plot", "--dt", "1",
             "-o", "{d}/o", "--json"] if cmd == "deviation" or expect == "any" else
            ["plan", PROBLEM, "--forces", "{d}/f.csv", "-o", "{d}/o"])
    return Case("force logs", f"{argv[0]}: {label}", argv, expect, {"f.csv": data})


def weld_track_cases(rng: random.Random, b: Bases) -> Case:
    base = b.track if rng.random() < 0.7 else _csv_bytes(
        [["x_mm", "y_mm", "z_mm"], ["1500", "0", "800"], ["1600", "0", "800"],
         ["1700", "0", "800"], ["1800", "0.5", "800"]])
    numeric = _csv_rows(base)[0]
    label, data, expect = csv_mutations(rng, base, numeric)
    if label.endswith("=nan"):  # a documented gap in a track, like an empty cell
        expect = "any"
    if rng.random() < 0.15:  # a coordinate far beyond any cell
        rows = _csv_rows(base)
        rows[2][rng.randrange(len(rows[0]))] = rng.choice(["-1e308", "1e300", "1e9"])
        label, data, expect = "coordinate 1e300", _csv_bytes(rows), "refuse"
    if expect == "any":  # an accepted track runs the whole diagnosis: keep the campaign fast
        expect, data, label = "refuse", b"s_mm,e_lat_mm\n0,0\n", "two rows"
    return Case("weld tracks", label, ["validate-weld", str(b.plan_dir), "--track",
                                       "{d}/t.csv", "-o", "{d}/o"], expect, {"t.csv": data})


def column_map_cases(rng: random.Random, b: Bases) -> Case:
    rows = _csv_rows(b.measurements)
    lab = {"x_mm": "X [m]", "y_mm": "Y [m]", "z_mm": "Z [m]", "fx_N": "Fx", "fy_N": "Fy",
           "fz_N": "Fz"}
    scaled = _scaled(_scaled(rows, ("x_mm", "y_mm", "z_mm"), 1e-3), ("fx_N", "fy_N", "fz_N"),
                     1e-3)  # positions in m, forces in kN
    scaled[0] = [lab.get(c, c) for c in scaled[0]]
    entries = {"x": ("X [m]", "m"), "y": ("Y [m]", "m"), "z": ("Z [m]", "m"),
               "fx": ("Fx", "kN"), "fy": ("Fy", "kN"), "fz": ("Fz", "kN")}
    op = rng.choice(["ok", "N over kN", "mm over m", "unknown quantity", "missing column",
                     "mapped twice", "bad toml", "unknown key", "bad unit", "no columns"])
    expect = "any" if op == "ok" else "refuse"
    extra = ""
    if op == "N over kN":
        entries["fz"] = ("Fz", "N")
        entries["fx"] = ("Fx", "N")
        entries["fy"] = ("Fy", "N")
    elif op == "mm over m":
        entries = {**entries, **{k: (v[0], "mm") for k, v in entries.items() if k in "xyz"}}
    elif op == "unknown quantity":
        entries["temperature"] = ("T_missing", "C")
    elif op == "missing column":
        entries["fz"] = ("Fz_sensor", "kN")
    elif op == "mapped twice":
        entries["fy"] = ("Fx", "kN")
    elif op == "unknown key":
        extra = 'colour = "blue"\n'
    elif op == "bad unit":
        entries["fx"] = ("Fx", "lbf")
    toml = extra + "[columns]\n" + "".join(
        f'{k} = {{ name = "{n}", unit = "{u}" }}\n' for k, (n, u) in entries.items())
    if op == "bad toml":
        toml = toml.replace("}", "", 1)
    if op == "no columns":
        toml = 'frame = "base"\n'
    return Case("column maps", op, ["identify", "--robot", "zk500", "--data", "{d}/m.csv",
                                    "--columns", "{d}/map.toml", "--json"], expect,
                {"m.csv": _csv_bytes(scaled), "map.toml": toml.encode()})


def plan_folder_cases(rng: random.Random, b: Bases) -> Case:
    src = b.plan_dir
    files: dict[str, bytes | None] = {p.name: p.read_bytes() for p in src.iterdir()
                                      if p.is_file()}
    rec = json.loads(files["plan.json"])
    op = rng.choice(["utf16", "random", "empty", "nan", "failed", "nan_joint", "missing_csv",
                     "changed_csv"])
    if op == "utf16":
        files["plan.json"] = files["plan.json"].decode().encode("utf-16")
    elif op == "random":
        files["plan.json"] = bytes(rng.randrange(256) for _ in range(200))
    elif op == "empty":
        files["plan.json"] = b""
    elif op == "nan":
        files["plan.json"] = files["plan.json"].replace(b'"samples"', b'"x": NaN, "samples"',
                                                        1)
    elif op == "failed":
        rec["status"] = "failed"
        files["plan.json"] = json.dumps(rec).encode()
    elif op == "missing_csv":
        files.pop("waypoints.csv")
    else:
        rows = _csv_rows(files["waypoints.csv"])
        r = rng.randrange(1, len(rows))
        j = next(i for i, h in enumerate(rows[0]) if re.fullmatch(r"[A-Za-z]+\d+_deg", h))
        rows[r][j] = "nan" if op == "nan_joint" else "12.5"
        files["waypoints.csv"] = _csv_bytes(rows)
        if op == "nan_joint":  # the record updated to match: only the strict reader sees it
            import hashlib

            rec.setdefault("sha256", {})["waypoints.csv"] = hashlib.sha256(
                files["waypoints.csv"]).hexdigest()
            files["plan.json"] = json.dumps(rec).encode()
    return Case("plan folders -> export", op, ["export", "{d}/p", "--format", "krl"],
                "refuse", {f"p/{k}": v for k, v in files.items()})


GENERATORS: dict[str, Callable[[random.Random, Bases], Case]] = {
    "output paths": output_path_cases, "CLI numbers": cli_number_cases, "URDF": urdf_cases,
    "measurement CSV": measurement_cases, "force logs": force_log_cases,
    "weld tracks": weld_track_cases, "column maps": column_map_cases,
    "plan folders -> export": plan_folder_cases,
}


@dataclass
class Report:
    """Outcome counts per kind, and the first cases of every bad outcome."""

    counts: dict[str, Counter[str]] = field(default_factory=dict)
    examples: list[tuple[str, str, str, str]] = field(default_factory=list)

    def add(self, case: Case, outcome: str, detail: str) -> None:
        self.counts.setdefault(case.kind, Counter())[outcome] += 1
        if outcome != "ok":
            self.examples.append((case.kind, outcome, case.label, detail))

    def bad(self, kinds: tuple[str, ...] = KINDS) -> list[tuple[str, str, str, str]]:
        return [e for e in self.examples if e[0] in kinds]

    def table(self) -> str:
        lines = ["| kind | runs | traceback | hang | crash | silent accept | null/NaN output |",
                 "|---|---|---|---|---|---|---|"]
        total: Counter[str] = Counter()
        for kind in KINDS:
            c = self.counts.get(kind, Counter())
            total.update(c)
            lines.append(f"| {kind} | {sum(c.values())} | "
                         + " | ".join(str(c[o]) for o in OUTCOMES) + " |")
        lines.append(f"| **all** | {sum(total.values())} | "
                     + " | ".join(str(total[o]) for o in OUTCOMES) + " |")
        return "\n".join(lines)


def campaign(n_per_kind: dict[str, int], seed: int, folder: Path | None = None,
             progress: bool = False) -> Report:
    """Run ``n_per_kind[kind]`` seeded cases of each kind; the same cases for the same seed."""
    import logging

    logging.disable(logging.WARNING)  # the library's warnings are not the CLI's one line
    base = Path(tempfile.mkdtemp(prefix="rfsw_fuzz_")) if folder is None else folder
    bases = Bases(base / "bases")
    report = Report()
    try:
        for kind, n in n_per_kind.items():
            rng = random.Random(f"{seed}:{kind}")
            t0 = time.monotonic()
            for _ in range(n):
                case = GENERATORS[kind](rng, bases)
                t1 = time.monotonic()
                outcome, detail = run_case(case, base / "case")
                report.add(case, outcome, detail)
                if progress and time.monotonic() - t1 > 5:
                    print(f"  slow ({time.monotonic() - t1:.0f} s): {case.label} {outcome}",
                          file=sys.stderr, flush=True)
            if progress:
                print(f"{kind}: {n} cases in {time.monotonic() - t0:.0f} s", file=sys.stderr,
                      flush=True)
    finally:
        logging.disable(logging.NOTSET)
        if folder is None:
            shutil.rmtree(base, ignore_errors=True)
    return report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=2100, help="cases in all (default 2100)")
    ap.add_argument("--seed", type=int, default=25, help="campaign seed (default 25)")
    ap.add_argument("--kinds", default=",".join(KINDS), help="comma-separated kinds")
    args = ap.parse_args(argv)
    kinds = [k for k in args.kinds.split(",") if k]
    per = max(1, args.cases // len(kinds))
    t0 = time.monotonic()
    report = campaign({k: per for k in kinds}, args.seed, progress=True)
    print(f"seed {args.seed}, {sum(sum(c.values()) for c in report.counts.values())} cases, "
          f"{time.monotonic() - t0:.0f} s\n")
    print(report.table())
    for kind, outcome, label, detail in report.examples[:60]:
        print(f"- {kind} / {outcome}: {label}: {detail[:220]}")
    return 0 if not report.examples else 1


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    raise SystemExit(main())
