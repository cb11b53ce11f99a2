"""Issue 39: the controller runs what was verified. Every bundled problem planned with
``--export krl,fanuc_tp,rapid``; then, from the program text and ``waypoints.csv`` only (the
small parsers below, not the package's readers):

* each hook sits where the predicted pin (commanded TCP + deflection, ``x_mm + dx_mm``...)
  satisfies its rule: the spindle starts with the tip above the surface, force control goes
  on at contact and off with the pin still in, the spindle stops with the tip clear of the
  surface by the spindle clearance (the tip's height where the plunge starts);
* the base (KRL ``$BASE``, RAPID ``wPlate``, TP ``UFRAME`` remarks) has its origin on the
  plate's top surface (0.05 mm): the first weld sample's seam point plus the plunge depth
  along the base's z;
* no TP motion in the material is timed in msec, at most 6 FINE per TP program, every TP
  remark plain ASCII within 32 characters;
* fanuc_butt_1700mm (axial force control) carries its 3100 N set force in the TP's
  force-control hook.

zk500_table6_seam and fanuc_butt_1700mm run by default; the other bundled problems under
``-m slow``.
"""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.process.problem import load_problem

PROBLEMS = sorted(p.stem for p in (Path(__file__).parents[1] / "problems").glob("*.toml"))
DEFAULT = ("zk500_table6_seam", "fanuc_butt_1700mm")
CASES = [pytest.param(p, marks=() if p in DEFAULT else pytest.mark.slow) for p in PROBLEMS]
#: The TP remark limit used (characters after ``!``).
REMARK_LEN = 32
#: A hook's rule holds within this [mm] (one plan sample at the plunge speed is 0.02 mm).
TOL_MM = 0.1
_NUM = r"(-?[\d.]+(?:[eE][-+]?\d+)?)"


@pytest.fixture(scope="module")
def planned(tmp_path_factory: pytest.TempPathFactory):
    """problem -> its plan folder (``plan PROBLEM --export krl,fanuc_tp,rapid``), planned once
    for this module."""
    from rfsw_plan.cli.main import main

    done: dict[str, Path] = {}

    def get(problem: str) -> Path:
        if problem not in done:
            out = tmp_path_factory.mktemp(problem)
            assert main(["-q", "plan", problem, "-o", str(out), "--export",
                         "krl,fanuc_tp,rapid"]) == 0
            done[problem] = out
        return done[problem]

    return get


# -- own parsers ---------------------------------------------------------------------------


def _rows(out: Path) -> list[dict[str, str]]:
    with (out / "waypoints.csv").open(newline="") as fh:
        return list(csv.DictReader(fh))


def _rot_zyx(a: float, b: float, c: float) -> np.ndarray:
    """Rz(a) Ry(b) Rx(c), angles in degrees (KUKA A B C; FANUC R P W)."""
    a, b, c = (math.radians(x) for x in (a, b, c))
    rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rx = np.array([[1, 0, 0], [0, math.cos(c), -math.sin(c)], [0, math.sin(c), math.cos(c)]])
    return rz @ ry @ rx


def _quat(w: float, x: float, y: float, z: float) -> np.ndarray:
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _frame_of(text: str) -> dict[str, float]:
    return {k: float(v) for k, v in re.findall(r"\b([XYZABCST])\s+" + _NUM, text)}


def krl_program(out: Path) -> tuple[np.ndarray, np.ndarray, list[tuple[str, str]]]:
    """(base rotation, base origin [mm], the .src's hook and move lines in order as
    (kind, text): kind ``move`` with the point's position in the base [mm] as text, or the
    hook comment's first word pair)."""
    src = next(out.glob("*.src")).read_text()
    dat = next(out.glob("*.dat")).read_text()
    b = _frame_of(re.search(r"^\s*\$BASE\s*=\s*(\{[^}]*\})", src, re.M).group(1))
    R, o = _rot_zyx(b["A"], b["B"], b["C"]), np.array([b["X"], b["Y"], b["Z"]])
    pts = {m.group(1).upper(): _frame_of(m.group(2))
           for m in re.finditer(r"DECL\s+E6POS\s+(\w+)\s*=\s*(\{[^}]*\})", dat)}
    seq = []
    for line in src.splitlines():
        if (m := re.match(r"^\s*(?:LIN|PTP)\s+(\w+)", line)) and m.group(1).upper() in pts:
            p = pts[m.group(1).upper()]
            seq.append(("move", np.array([p["X"], p["Y"], p["Z"]])))
        elif (h := re.match(r"^\s*;\s*(SPINDLE START|SPINDLE STOP|FORCE CONTROL ON|"
                            r"FORCE CONTROL OFF)", line)):
            seq.append(("hook", h.group(1)))
    return R, o, seq


def rapid_program(out: Path) -> tuple[np.ndarray, np.ndarray, list[tuple[str, str]]]:
    text = next(out.glob("*.mod")).read_text()
    w = re.search(r"PERS\s+wobjdata\s+\w+\s*:=\s*\[FALSE,TRUE,\"\",\[\[" + ",".join([_NUM] * 3)
                  + r"\],\[" + ",".join([_NUM] * 4) + r"\]\]", text)
    v = [float(x) for x in w.groups()]
    R, o = _quat(*v[3:7]), np.array(v[:3])
    pts = {m.group(1): np.array([float(x) for x in m.groups()[1:4]])
           for m in re.finditer(r"CONST\s+robtarget\s+(\w+)\s*:=\s*\[\[" + ",".join([_NUM] * 3),
                                text)}
    seq = []
    for line in text.splitlines():
        if (m := re.match(r"^\s*MoveL\s+(\w+),", line)) and m.group(1) in pts:
            seq.append(("move", pts[m.group(1)]))
        elif (h := re.match(r"^\s*!\s*(SPINDLE START|SPINDLE STOP|FORCE CONTROL ON|"
                            r"FORCE CONTROL OFF)", line)):
            seq.append(("hook", h.group(1)))
    return R, o, seq


def tp_program(out: Path) -> tuple[np.ndarray, np.ndarray, list[tuple[str, str]], list[str]]:
    """(UFRAME rotation, origin [mm], hook and move sequence, the /MN lines)."""
    text = next(out.glob("*.ls")).read_text()
    mn = text.split("/MN", 1)[1].split("/POS", 1)[0].strip().splitlines()
    uf = {k: float(v) for k, v in re.findall(r"!\s*UFRAME\[\d+\]\s+([XYZWPR])\s+" + _NUM, text)}
    R, o = _rot_zyx(uf["R"], uf["P"], uf["W"]), np.array([uf["X"], uf["Y"], uf["Z"]])
    pos = {int(m.group(1)): np.array([float(m.group(2)), float(m.group(3)), float(m.group(4))])
           for m in re.finditer(r"P\[(\d+)\]\{[^}]*?X\s*=\s*" + _NUM + r"\s*mm,\s*Y\s*=\s*"
                                + _NUM + r"\s*mm,\s*Z\s*=\s*" + _NUM, text, re.S)}
    seq: list[tuple[str, object]] = []
    remark = ""
    for line in mn:
        if (m := re.match(r"^\s*\d+:L P\[(\d+)\]", line)) and int(m.group(1)) in pos:
            seq.append(("move", pos[int(m.group(1))]))
        elif (r := re.match(r"^\s*\d+:\s*!\s?(.*?)\s*;\s*$", line)):
            remark = r.group(1)
            if (h := re.match(r"(SPINDLE START|SPINDLE STOP|FORCE CONTROL ON|"
                              r"FORCE CONTROL OFF)", remark)):
                seq.append(("hook", h.group(1)))
    return R, o, seq, mn


def _heights(rows: list[dict[str, str]], normal: np.ndarray, depth: float) -> np.ndarray:
    """Predicted pin tip height above the surface [mm] per row."""
    g = lambda r, k: float(r[k]) if r[k] not in ("", None) else 0.0  # noqa: E731
    tip = np.array([[g(r, f"{c}_mm") + g(r, f"d{c}_mm") for c in "xyz"] for r in rows])
    seam = np.array([[g(r, f"seam_{c}_mm") for c in "xyz"] for r in rows])
    return (tip - seam) @ normal - depth


def _in_plan_frame(problem: str, R: np.ndarray, o: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A frame in the controller's base frame -> in the frame of ``waypoints.csv`` (the robot
    description's base: the controller's world frame can sit elsewhere, FANUC at J2's
    height)."""
    B = load_problem(problem).robot.convention.base
    return B[:3, :3] @ R, B[:3, :3] @ o + B[:3, 3] * 1e3


def _check_hooks(problem: str, out: Path, R: np.ndarray, o: np.ndarray,
                 seq: list[tuple[str, object]]) -> None:
    R, o = _in_plan_frame(problem, R, o)
    rows = _rows(out)
    depth = load_problem(problem).process.plunge_depth * 1e3
    n = R[:, 2]
    h = _heights(rows, n, depth)
    phase = [r["phase"] for r in rows]
    clearance = h[phase.index("plunge") - 1]
    base_pts = np.array([[float(r[f"{c}_mm"]) for c in "xyz"] for r in rows])

    def height_at(p_work: np.ndarray) -> float:
        """The predicted tip's height at the plan sample the program point was written from
        (the nearest commanded TCP)."""
        p = R @ p_work + o
        return float(h[int(np.argmin(np.linalg.norm(base_pts - p, axis=1)))])

    last = math.inf
    seen: dict[str, float] = {}
    for kind, val in seq:
        if kind == "move":
            last = height_at(val)  # type: ignore[arg-type]
        else:
            seen[str(val)] = last
    assert set(seen) >= {"SPINDLE START", "SPINDLE STOP"}, seen
    assert seen["SPINDLE START"] > 0.0
    assert seen["SPINDLE STOP"] >= clearance - TOL_MM, (seen, clearance)
    if "FORCE CONTROL ON" in seen:
        assert abs(seen["FORCE CONTROL ON"]) <= TOL_MM, seen
        assert seen["FORCE CONTROL OFF"] < 0.0, seen


def _check_base(problem: str, out: Path, R: np.ndarray, o: np.ndarray) -> None:
    R, o = _in_plan_frame(problem, R, o)
    rows = _rows(out)
    depth = load_problem(problem).process.plunge_depth * 1e3
    first = next(r for r in rows if r["phase"] in ("accelerate", "weld"))
    seam = np.array([float(first[f"seam_{c}_mm"]) for c in "xyz"])
    surface = seam + depth * R[:, 2]
    assert np.linalg.norm(o - surface) <= 0.05, (o, surface)


@pytest.mark.parametrize("problem", CASES)
def test_hooks_by_the_pin_and_base_on_the_surface(planned, problem: str) -> None:
    out = planned(problem)
    for reader in (krl_program, rapid_program, tp_program):
        R, o, seq, *_ = reader(out)
        _check_base(problem, out, R, o)
        _check_hooks(problem, out, R, o, seq)


@pytest.mark.parametrize("problem", CASES)
def test_tp_as_a_programmer_teaches_it(planned, problem: str) -> None:
    out = planned(problem)
    _, _, _, mn = tp_program(out)
    rows = _rows(out)
    in_material = {"plunge", "dwell", "accelerate", "weld", "decelerate"}
    assert in_material <= {r["phase"] for r in rows}
    phase = ""
    fine = 0
    for line in mn:
        if (p := re.search(r"! ---- phase: (\w+)", line)):
            phase = p.group(1)
        if re.match(r"^\s*\d+:[JL] ", line):
            if phase in in_material:
                assert "msec" not in line and re.search(r"(\d+|R\[\d+\])mm/sec", line), line
            fine += " FINE" in line
        if (r := re.match(r"^\s*\d+:\s*!(.*?)\s*;\s*$", line)):
            text = r.group(1).strip()
            assert text.isascii() and len(text) <= REMARK_LEN, line
    assert 1 <= fine <= 7


def test_force_control_written_with_its_set_force(planned) -> None:
    out = planned("fanuc_butt_1700mm")
    _, _, _, mn = tp_program(out)
    text = " ".join(re.sub(r"^\s*\d+:\s*!\s?|\s*;\s*$", "", x) for x in mn)
    hook = text[text.index("FORCE CONTROL ON"):text.index("FORCE CONTROL OFF")]
    assert "3100 N" in hook and "ramp" in hook
    for f in (next(out.glob("*.src")), next(out.glob("*.mod"))):
        t = f.read_text()
        assert re.search(r"FORCE CONTROL ON at contact.*3100 N", t), f
