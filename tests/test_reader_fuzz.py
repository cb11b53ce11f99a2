"""Mutation fuzzing of the input readers: robot TOML, problem TOML and seam CSV (issue 9 §4-5).

Every mutated file goes through the real CLI (``rfsw_plan.cli.main.main``, in process) and must
end with exit 0, 2 or 3 and no traceback: an exit 2 is exactly one line on stderr, and nothing at
all reaches the process's stdout (file descriptor 1, where LAPACK would print) except the
command's own JSON. A mutated robot file that is accepted must predict the same deflection as
the original unless the mutation was a legitimate edit (an in-range number, an optional key
deleted, a truncation that leaves a complete file); a renamed or unknown key is never accepted.

The cases are drawn by hypothesis with ``derandomize=True`` (the same cases on every run). The
default run draws a bounded sample (a few seconds); ``-m slow`` draws many more.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import tomllib
from collections import Counter
from collections.abc import Callable, Iterator
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from _mutations import (
    Mutation,
    harmless_mutations,
    key_mutations,
    text_mutations,
    value_mutations,
)
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rfsw_plan.cli.main import main
from rfsw_plan.robot.description import load_robot_description

ROOT = Path(__file__).resolve().parents[1]
ROBOTS = ("kuka_kr600_r2830", "fanuc_s900ib_400", "zk500")
PROBLEM = "zk500_table6_seam"
WRENCH = "800,-1300,-4800,10,-20,5"

#: Robot-file keys whose deletion is a legitimate edit (the format gives them a default).
OPTIONAL_ROBOT_KEYS = {"title", "euler", "source", "tool", "xyz_mm", "rpy_deg", "theta0_deg",
                       "convention", "jerk_deg_s3", "coupling", "effects", "params", "controller",
                       "axes", "sign", "offset_deg", "base_xyz_mm", "base_rpy_deg",
                       "flange_xyz_mm", "flange_rpy_deg"}
#: Mutation families that can never be a legitimate edit of the model.
NEVER_CHANGE = ("rename", "unknown", "retype", "harmless", "junk")


# -- running the CLI --------------------------------------------------------------------------


@contextlib.contextmanager
def _fd1_captured() -> Iterator[list[str]]:
    """Capture what reaches file descriptor 1 (C libraries such as LAPACK write there)."""
    out: list[str] = []
    sys.stdout.flush()
    saved = os.dup(1)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 1)
        try:
            yield out
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            tmp.seek(0)
            out.append(tmp.read().decode("utf-8", "replace"))


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """Run the CLI in process: (exit code, stdout, stderr); asserts nothing leaked on fd 1."""
    out, err = io.StringIO(), io.StringIO()
    with _fd1_captured() as fd1, contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    assert fd1[0] == "", f"{argv}: printed on the process stdout: {fd1[0][:200]!r}"
    return code, out.getvalue(), err.getvalue()


def check_outcome(m: Mutation, code: int, out: str, err: str) -> None:
    """Exit 0, 2 or 3; no traceback; an error is one line with no stdout."""
    label = f"{m.kind} {m.where}"
    assert code in (0, 2, 3), (label, code, err)
    assert "Traceback" not in err, (label, err)
    if code != 0:
        assert err.count("\n") == 1 and err.startswith("rfsw-plan "), (label, err)
        assert out == "", (label, out)


# -- robot files ------------------------------------------------------------------------------


def _pose(name: str) -> str:
    d = load_robot_description(name)
    q = (d.lower + d.upper) / 2 + 0.15 * (d.upper - d.lower) * np.array([1, -1, 1, -1, 1, -1])
    return ",".join(f"{v:.3f}" for v in np.degrees(q))


@cache
def robot_cases(name: str) -> tuple[Mutation, ...]:
    text = (ROOT / "robots" / f"{name}.toml").read_text()
    n = len(text)
    cases = [*key_mutations(text), *value_mutations(text), *harmless_mutations(text),
             *text_mutations(text, [n // 7, n // 3, n // 2, 2 * n // 3, n - 5])]
    return tuple(cases)


@cache
def robot_baseline(name: str) -> np.ndarray:
    code, out, err = run_cli(["predict", "--robot", name, f"--q-deg={_pose(name)}",
                              "--wrench", WRENCH, "--json"])
    assert code == 0, err
    d = json.loads(out)
    return np.array(d["translation_mm"] + d["rotation_mrad"])


def _deleted_key(m: Mutation) -> str:
    return re.sub(r"\[\d+\]|\.\d+", "", m.where).split(".")[-1]


def check_robot_case(name: str, m: Mutation, folder: Path) -> str:
    """Run ``predict`` on the mutated robot file; returns the outcome family for counting."""
    path = folder / f"{name}.toml"
    path.write_text(m.text, encoding="latin-1" if m.kind == "junk" else "utf-8")
    code, out, err = run_cli(["predict", "--robot", str(path), f"--q-deg={_pose(name)}",
                              "--wrench", WRENCH, "--json"])
    check_outcome(m, code, out, err)
    if code != 0:
        return "rejected"
    got = json.loads(out)
    dx = np.array(got["translation_mm"] + got["rotation_mrad"])
    same = bool(np.allclose(dx, robot_baseline(name), rtol=1e-12, atol=1e-12))
    label = f"{name}: {m.kind} {m.where} accepted"
    empty_optional = (m.kind == "retype" and m.where.endswith("=[]")
                      and m.where.split("=")[0].split(".")[-1] in OPTIONAL_ROBOT_KEYS)
    if m.kind in NEVER_CHANGE and not empty_optional:  # `effects = []`: no effects, legitimately
        assert same, f"{label} and changed the deflection {robot_baseline(name)} -> {dx}"
    elif m.kind == "number":
        value = float(m.where.rsplit("=", 1)[1])
        assert math.isfinite(value) and abs(value) < 1e30, f"{label}"
    elif m.kind == "delete" and not same:
        # An effect parameter left out takes the effect's prior (the format's default).
        optional = _deleted_key(m) in OPTIONAL_ROBOT_KEYS or ".params." in m.where
        assert optional, f"{label} and changed the deflection"
    return "accepted, same model" if same else "accepted, legitimate edit"


# -- problem files and seam CSVs --------------------------------------------------------------


@cache
def problem_cases() -> tuple[Mutation, ...]:
    text = (ROOT / "problems" / f"{PROBLEM}.toml").read_text()
    n = len(text)
    return (*key_mutations(text), *value_mutations(text), *harmless_mutations(text),
            *text_mutations(text, [n // 5, n // 2, 4 * n // 5]))


def _seam_problem_text() -> str:
    text = (ROOT / "problems" / f"{PROBLEM}.toml").read_text()
    data = tomllib.loads(text)
    data["seam"].pop("points_mm")
    data["seam"].pop("surface_normal", None)
    data["seam"]["csv"] = "seam.csv"
    import tomli_w

    return tomli_w.dumps(data)


def _seam_csv_text() -> str:
    pts = tomllib.loads((ROOT / "problems" / f"{PROBLEM}.toml").read_text())["seam"]["points_mm"]
    rows = ["x_mm,y_mm,z_mm,nx,ny,nz"] + [f"{x},{y},{z},0,0,1" for x, y, z in pts]
    return "\n".join(rows) + "\n"


def _csv_mutations(text: str) -> list[Mutation]:
    lines = text.splitlines()
    header = lines[0].split(",")
    out: list[Mutation] = []
    for j, col in enumerate(header):
        rest = [c for i, c in enumerate(header) if i != j]
        out.append(Mutation("csv_dup_column", col, "\n".join(
            [",".join([*header[:j], header[(j + 1) % len(header)], *header[j + 1:]]),
             *lines[1:]])))
        out.append(Mutation("csv_drop_column", col, "\n".join(
            [",".join(rest)] + [",".join(c for i, c in enumerate(r.split(",")) if i != j)
                                for r in lines[1:]])))
        out.append(Mutation("csv_rename_column", col, "\n".join(
            [",".join([*header[:j], col.upper(), *header[j + 1:]]), *lines[1:]])))
        for bad in ("nan", "inf", "-inf", "1e30", "1e300", "", "x", "1" * 140000):
            cells = lines[1].split(",")
            cells[j] = bad
            out.append(Mutation("csv_cell", f"{col}={bad[:12]}", "\n".join(
                [lines[0], ",".join(cells), *lines[2:]])))
    for delim in (";", "\t", " "):
        out.append(Mutation("csv_delimiter", repr(delim), text.replace(",", delim)))
    out.append(Mutation("csv_extra_column", "note", "\n".join(
        [lines[0] + ",note", *(r + ",x" for r in lines[1:])])))
    out.append(Mutation("csv_ragged", "row 3",
                        "\n".join([*lines[:2], lines[2] + ",5", *lines[3:]])))
    out.append(Mutation("csv_empty", "", ""))
    out.append(Mutation("csv_header_only", "", lines[0] + "\n"))
    # Column order, CRLF line ends, a BOM and blank lines do not change the seam.
    order = [3, 4, 5, 0, 1, 2]
    out.append(Mutation("harmless", "reordered columns", "\n".join(
        ",".join(r.split(",")[i] for i in order) for r in lines)))
    out.append(Mutation("harmless", "CRLF", text.replace("\n", "\r\n")))
    out.append(Mutation("harmless", "BOM", "\ufeff" + text))
    out.append(Mutation("harmless", "blank lines", text.replace("\n", "\n\n")))
    out.extend(text_mutations(text, [len(text) // 3, len(text) - 4]))
    return out


@cache
def seam_cases() -> tuple[Mutation, ...]:
    return tuple(_csv_mutations(_seam_csv_text()))


def _deviation(problem: Path, out_dir: Path) -> tuple[int, str, str]:
    return run_cli(["deviation", str(problem), "-o", str(out_dir), "--no-plot", "--json"])


@cache
def problem_baseline(kind: str) -> list[float]:
    folder = Path(tempfile.mkdtemp(prefix="rfsw_fuzz_base_"))
    if kind == "csv":
        (folder / "seam.csv").write_text(_seam_csv_text())
        (folder / "p.toml").write_text(_seam_problem_text())
        path = folder / "p.toml"
    else:
        path = ROOT / "problems" / f"{PROBLEM}.toml"
    code, out, err = _deviation(path, folder / "out")
    assert code == 0, err
    return list(json.loads(out)["lateral_mm"])


def check_problem_case(m: Mutation, folder: Path, seam_csv: bool) -> str:
    if seam_csv:
        (folder / "seam.csv").write_text(m.text, encoding="latin-1" if m.kind == "junk"
                                         else "utf-8", newline="")
        (folder / "p.toml").write_text(_seam_problem_text())
    else:
        (folder / "p.toml").write_text(m.text, encoding="latin-1" if m.kind == "junk"
                                       else "utf-8")
    code, out, err = _deviation(folder / "p.toml", folder / "out")
    check_outcome(m, code, out, err)
    if code != 0:
        return "rejected"
    same = json.loads(out)["lateral_mm"] == pytest.approx(
        problem_baseline("csv" if seam_csv else "toml"), rel=1e-9, abs=1e-9)
    label = f"{m.kind} {m.where} accepted"
    if m.kind in ("rename", "unknown", "harmless") or m.kind.startswith("csv_"):
        assert same, f"{label} and changed the deviation"
    if m.kind == "number":
        value = float(m.where.rsplit("=", 1)[1])
        assert math.isfinite(value) and abs(value) < 1e30, label
    return "accepted, same result" if same else "accepted, legitimate edit"


# -- hypothesis drivers -------------------------------------------------------------------------


def _by_kind(cases: tuple[Mutation, ...]) -> dict[str, list[Mutation]]:
    out: dict[str, list[Mutation]] = {}
    for m in cases:
        out.setdefault(m.kind, []).append(m)
    return out


def _draw(data: st.DataObject, cases: tuple[Mutation, ...]) -> Mutation:
    """A kind first (every family equally likely), then a case of that kind."""
    groups = _by_kind(cases)
    kind = data.draw(st.sampled_from(sorted(groups)))
    return data.draw(st.sampled_from(groups[kind]))


def _fuzz(check: Callable[[Mutation, Path], str], cases: Callable[[], tuple[Mutation, ...]],
          n: int, title: str) -> None:
    """Run ``n`` drawn cases through ``check``; print the outcome counts (``pytest -s``)."""
    folder = Path(tempfile.mkdtemp(prefix="rfsw_fuzz_"))
    counts: Counter[str] = Counter()

    @settings(max_examples=n, derandomize=True, deadline=None, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(st.data())
    def run(data: st.DataObject) -> None:
        m = _draw(data, cases())
        counts[f"{m.kind}: {check(m, folder)}"] += 1

    run()
    print(f"\n{title}: {sum(counts.values())} cases, exit 0/2/3 only, no traceback: "
          + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    # The drawn sample reaches both sides of the reader: files it refuses (one line, exit 2 or
    # 3, checked above) and files it accepts and that were compared with the original's
    # result. A reader that refused everything, or accepted everything, fails here.
    rejected = sum(v for k, v in counts.items() if k.endswith(": rejected"))
    assert 0 < rejected < sum(counts.values()), counts
    # and, as the module says, a renamed or unknown key is never accepted
    assert not [k for k in counts if k.split(":")[0] in ("rename", "unknown")
                and not k.endswith(": rejected")], counts


@pytest.mark.parametrize("name", ROBOTS)
def test_mutated_robot_files_bounded(name: str) -> None:
    _fuzz(lambda m, f: check_robot_case(name, m, f), lambda: robot_cases(name), 25,
          f"robot {name}")


def test_mutated_problem_files_bounded() -> None:
    _fuzz(lambda m, f: check_problem_case(m, f, False), problem_cases, 20, "problem TOML")


def test_mutated_seam_csv_bounded() -> None:
    _fuzz(lambda m, f: check_problem_case(m, f, True), seam_cases, 20, "seam CSV")


def test_every_renamed_or_unknown_key_is_rejected(tmp_path: Path) -> None:
    """All renamed/unknown-key mutations of the bundled robot files (before: 104 of 226 of
    the robot and problem files were accepted)."""
    counts = {"rejected": 0}
    for name in ROBOTS:
        for m in robot_cases(name):
            if m.kind in ("rename", "unknown"):
                outcome = check_robot_case(name, m, tmp_path)
                assert outcome == "rejected", (name, m.kind, m.where)
                counts["rejected"] += 1
    assert counts["rejected"] >= 120


def test_issue_examples_are_one_line_errors(tmp_path: Path) -> None:
    """The typos and impossible values named in issue 9 §4, through the CLI."""
    kuka = (ROOT / "robots" / "kuka_kr600_r2830.toml").read_text()
    fanuc = (ROOT / "robots" / "fanuc_s900ib_400.toml").read_text()
    cases = [
        (kuka, "[tool]", "[tol]", "tol: unknown key; did you mean 'tool'?"),
        (fanuc, "coupling =", "cupling =", "joints.cupling: unknown key; did you mean "
                                           "'coupling'?"),
        (kuka, "[[effects]]", "[[efects]]", "efects: unknown key; did you mean 'effects'?"),
        (fanuc, "[0, 1, 1, 0, 0, 0]", "[0, nan, 1, 0, 0, 0]",
         "joints.coupling: row 3, value 2 is NaN or infinity"),
        (fanuc, "[0, 1, 1, 0, 0, 0]", "[0, inf, 1, 0, 0, 0]",
         "joints.coupling: row 3, value 2 is NaN or infinity"),
        (kuka, "c_t1 = 1.087e-7", "c_t1 = -1e-3", "effects[1].params.c_t1: got -0.001"),
        (kuka, "c_t1 = 1.087e-7", "c_t1 = 0", None),  # a rigid bearing is possible
        (kuka, "c_t1 = 1.087e-7", "c_t1 = 1e308", "effects[1].params.c_t1: got 1e+308"),
        (kuka, "a_mm = [0, 500, 1300", "a_mm = [0, 500, 1e300",
         "kinematics.a_mm: value 3 is 1e+300"),
        (kuka, "upper_deg = [185,", "upper_deg = [1000,", "joints.upper_deg: joint 1 is 1000"),
    ]
    for i, (text, old, new, needle) in enumerate(cases):
        assert text.count(old) >= 1, old
        p = tmp_path / f"r{i}.toml"
        p.write_text(text.replace(old, new, 1))
        name = "fanuc_s900ib_400" if text is fanuc else "kuka_kr600_r2830"
        code, out, err = run_cli(["predict", "--robot", str(p), f"--q-deg={_pose(name)}",
                                  "--wrench", WRENCH])
        if needle is None:
            assert code == 0, err
            continue
        assert code == 2 and out == "" and err.count("\n") == 1, (needle, err)
        assert needle in err and str(p) in err, (needle, err)


@pytest.mark.parametrize(("edit", "needle"), [
    ({"seam.csv": "x_mm,y_mm,z_mm,nx,ny\n0,0,0,0,0\n100,0,0,0,0\n"},
     "header: has nx, ny but not nz"),
    ({"seam.csv": "x_mm,x_mm,z_mm\n0,0,0\n100,0,0\n"}, "header: column 'x_mm' appears twice"),
    ({"seam.csv": "x_mm,y_mm,z_mm\n0,0,0\n1e30,0,0\n"}, "row 3, column x_mm: got 1e30"),
    ({"seam.csv": "x_mm,y_mm,z_mm\n0,0,0\n" + "1" * 140000 + ",0,0\n"},
     "row 3: not readable as CSV"),
    ({"spacing_mm": "1e-320"}, "seam.spacing_mm: got 9.99989e-321"),
    ({"surface_normal": '"up"'}, "seam.surface_normal: got 'up'"),
])
def test_seam_and_problem_issue_examples(tmp_path: Path, edit: dict[str, str],
                                         needle: str) -> None:
    text = _seam_problem_text()
    (tmp_path / "seam.csv").write_text(edit.get("seam.csv", _seam_csv_text()))
    if "spacing_mm" in edit:
        text = re.sub(r"spacing_mm = \S+", f"spacing_mm = {edit['spacing_mm']}", text)
    if "surface_normal" in edit:
        (tmp_path / "seam.csv").write_text(_seam_csv_text().replace(",nx,ny,nz", "").replace(
            ",0,0,1", ""))
        text = text.replace("[seam]\n", f"[seam]\nsurface_normal = {edit['surface_normal']}\n")
    (tmp_path / "p.toml").write_text(text)
    code, out, err = _deviation(tmp_path / "p.toml", tmp_path / "out")
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert needle in err, err


def test_missing_problem_path_says_no_such_file() -> None:
    code, _, err = run_cli(["deviation", "problems/nope.toml", "--no-plot"])
    assert code == 2 and "problems/nope.toml: no such file" in err, err


def test_no_lapack_output_in_a_subprocess(tmp_path: Path) -> None:
    """A fresh process (nothing captured by pytest) prints nothing on stdout for bad input."""
    kuka = (ROOT / "robots" / "kuka_kr600_r2830.toml").read_text()
    p = tmp_path / "huge.toml"
    p.write_text(kuka.replace("d_mm = [1045,", "d_mm = [1e300,"))
    r = subprocess.run([sys.executable, "-m", "rfsw_plan.cli.main", "predict", "--robot", str(p),
                        "--q-deg=0,10,-10,0,20,0", "--wrench", WRENCH],
                       capture_output=True, text=True, cwd=ROOT, timeout=120,
                       env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.returncode == 2 and r.stdout == "" and r.stderr.count("\n") == 1, r


@pytest.mark.slow
@pytest.mark.parametrize("name", ROBOTS)
def test_mutated_robot_files_long(name: str) -> None:
    _fuzz(lambda m, f: check_robot_case(name, m, f), lambda: robot_cases(name), 400,
          f"robot {name}")


@pytest.mark.slow
def test_mutated_problem_files_long() -> None:
    _fuzz(lambda m, f: check_problem_case(m, f, False), problem_cases, 250, "problem TOML")


@pytest.mark.slow
def test_mutated_seam_csv_long() -> None:
    _fuzz(lambda m, f: check_problem_case(m, f, True), seam_cases, 150, "seam CSV")


# -- the fuzz findings of issue 33 (wall 9) ----------------------------------------------------


def test_a_problem_file_the_user_may_not_read_is_one_line(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """A problem file in a folder the user may not search: Python 3.11's ``Path.is_file``
    raises PermissionError. One line naming the file, exit 2 (as root every file is readable,
    so the denial is simulated for that folder; as a user the folder is really locked)."""
    locked = tmp_path / "locked"
    locked.mkdir()
    problem = locked / "p.toml"
    problem.write_text((ROOT / "problems" / "zk500_table6_seam.toml").read_text())
    if os.geteuid() != 0:
        locked.chmod(0)
    else:
        real_stat = os.stat

        def stat(path: object, *a: object, **k: object) -> os.stat_result:
            if not isinstance(path, int) and str(path).startswith(str(locked) + os.sep):
                raise PermissionError(13, "Permission denied", str(path))
            return real_stat(path, *a, **k)  # type: ignore[arg-type]

        monkeypatch.setattr(os, "stat", stat)
    try:
        for argv in (["plan", str(problem), "-o", str(tmp_path / "out")],
                     ["deviation", str(problem), "--no-plot", "-o", str(tmp_path / "dev")]):
            code, out, err = run_cli(argv)
            assert code == 2 and out == "" and err.count("\n") == 1, err
            assert f"{problem}: cannot read file: Permission denied" in err, err
    finally:
        locked.chmod(0o755)


def test_negative_zero_noise_is_zero(tmp_path: Path) -> None:
    """``simulate-campaign --noise-mm -0`` was a ``ValueError: scale < 0`` traceback."""
    out = tmp_path / "c.csv"
    code, _, err = run_cli(["simulate-campaign", "--robot", "zk500", "--poses", "3",
                            "--noise-mm", "-0", "-o", str(out)])
    assert code == 0 and "Traceback" not in err, err
    assert out.is_file()


def test_a_renamed_position_column_is_named_not_ignored(tmp_path: Path) -> None:
    """``y_mm`` renamed ``ym_m`` (a slip of the fingers): the y axis went unmeasured and the
    column became an unused extra. One line naming the column and what it looks like."""
    text = (ROOT / "examples" / "seed001" / "measurements.csv").read_text()
    for old, new in ((",y_mm,", ",ym_m,"), (",y_mm,", ",yy_mm,"), (",x_mm,", ",xm_mm,")):
        p = tmp_path / f"{new.strip(',')}.csv"
        p.write_text(text.replace(old, new, 1))
        code, out, err = run_cli(["validate", "--robot", "zk500", "--data", str(p),
                                  "-o", str(tmp_path / "v")])
        assert code == 2 and out == "" and err.count("\n") == 1, err
        assert f"column '{new.strip(',')}'" in err, err
    # An extra column that is nobody's near miss stays an extra (temperature, a lab's own).
    p = tmp_path / "extra.csv"
    p.write_text(text.replace(",sigma_mm\n", ",sigma_mm,temp_C\n", 1).replace(
        "\n", ",21.5\n").replace(",sigma_mm,temp_C,21.5\n", ",sigma_mm,temp_C\n", 1))
    from rfsw_plan.io.measurements import read_measurements

    assert "temp_C" in read_measurements(p, n_joints=6).extra


def test_a_urdf_with_xacro_elements_is_refused(tmp_path: Path) -> None:
    """A ``.urdf`` that still holds ``<xacro:…>`` elements or ``${…}`` expressions was read as
    if they were not there (only the ``.xacro`` suffix was checked): one line naming the
    element."""
    urdf = (ROOT / "robots" / "tiago_arm.urdf").read_text()
    robot = (ROOT / "robots" / "tiago_arm.toml").read_text()
    ns = '<robot xmlns:xacro="http://www.ros.org/wiki/xacro" '
    cases = [
        (urdf.replace("<robot ", ns, 1).replace(
            "</robot>", '  <xacro:include filename="gripper.urdf.xacro"/>\n</robot>'),
         "<xacro:include>: an unexpanded xacro element"),
        (urdf.replace("<robot ", ns, 1).replace(
            "</robot>", '  <xacro:property name="l" value="0.3"/>\n</robot>'),
         "<xacro:property>: an unexpanded xacro element"),
        (re.sub(r'(<origin xyz=")[^"]*', r"\g<1>${l} 0 0", urdf, count=1),
         "an unexpanded xacro expression"),
    ]
    for i, (text, needle) in enumerate(cases):
        assert text != urdf
        (tmp_path / f"arm{i}.urdf").write_text(text)
        p = tmp_path / f"arm{i}.toml"
        p.write_text(robot.replace('"tiago_arm.urdf"', f'"arm{i}.urdf"'))
        code, out, err = run_cli(["predict", "--robot", str(p), "--q-deg=100,0,0,0,0,0,0,0",
                                  "--wrench", "0,0,-10"])
        assert code == 2 and out == "" and err.count("\n") == 1, err
        assert needle in err and f"arm{i}.urdf" in err, err


# -- unit slips that passed (issue 33, wall 8) -------------------------------------------------


def _problem_with_robot(tmp_path: Path, robot_text: str) -> Path:
    (tmp_path / "robot.toml").write_text(robot_text)
    text = (ROOT / "problems" / "zk500_table6_seam.toml").read_text()
    text = re.sub(r'^robot = "[^"]*"', f'robot = "{tmp_path / "robot.toml"}"', text, flags=re.M)
    (tmp_path / "p.toml").write_text(text)
    return tmp_path / "p.toml"


def test_a_tool_in_metres_is_refused(tmp_path: Path) -> None:
    text = (ROOT / "robots" / "zk500.toml").read_text()
    assert "xyz_mm = [0, 0, 390]" in text
    p = tmp_path / "zk.toml"
    p.write_text(text.replace("xyz_mm = [0, 0, 390]", "xyz_mm = [0, 0, 0.39]"))
    code, out, err = run_cli(["predict", "--robot", str(p), f"--q-deg={_pose('zk500')}",
                              "--wrench", WRENCH])
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert "tool.xyz_mm: the TCP is 0.39 mm from the flange: metres instead of mm?" in err, err


def test_process_forces_in_kilonewtons_are_refused(tmp_path: Path) -> None:
    text = (ROOT / "problems" / "zk500_table6_seam.toml").read_text()
    assert re.search(r"^axial_N = ", text, re.M)
    p = tmp_path / "p.toml"
    p.write_text(re.sub(r"^axial_N = .*$", "axial_N = 4.84258", text, flags=re.M))
    code, out, err = run_cli(["plan", str(p), "-o", str(tmp_path / "out")])
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert "process.forces.axial_N: got 4.84258 N" in err and "kN instead of N?" in err, err


def test_joint_stiffness_in_kilonewton_metres_is_refused(tmp_path: Path) -> None:
    """``k_Nm_per_rad`` written in kN m/rad was planned and reported "unreachable ... by 502 mm";
    now one line naming the key, the joint and the likely unit, before any planning."""
    text = (ROOT / "robots" / "zk500_seed001.toml").read_text()
    m = re.search(r"k_Nm_per_rad = \[([^\]]*)\]", text)
    assert m
    kn = ", ".join(f"{float(x) / 1e3:g}" for x in m[1].split(","))
    p = _problem_with_robot(tmp_path, text.replace(m[0], f"k_Nm_per_rad = [{kn}]"))
    code, out, err = run_cli(["plan", str(p), "-o", str(tmp_path / "out")])
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert "stiffness.k_Nm_per_rad: joint" in err and "kN m/rad instead of N m/rad?" in err, err
    assert not (tmp_path / "out" / "waypoints.csv").exists()


def test_a_weld_track_in_metres_is_refused(tmp_path: Path) -> None:
    """Lateral offsets in metres in ``e_lat_mm`` were "100.0 % inside the window"."""
    from rfsw_plan.io.weld_track import read_weld_track
    from rfsw_plan.process.problem import load_problem
    from rfsw_plan.validation.weld.track import track_on_seam

    pb = load_problem("zk500_table6_seam")
    length_mm = float(pb.frames().s[-1] - pb.frames().s[0]) * 1e3
    s = np.linspace(0.0, length_mm, 200)
    e_mm = 0.3 * np.sin(s / 20.0) - 0.2  # a plausible weld, in mm
    for scale, ok in ((1.0, True), (1e-3, False)):
        p = tmp_path / f"track_{scale:g}.csv"
        p.write_text("s_mm,e_lat_mm\n" + "".join(f"{a:.4f},{b * scale:.9f}\n"
                                                 for a, b in zip(s, e_mm, strict=True)))
        if ok:
            track_on_seam(read_weld_track(p), pb)
            continue
        with pytest.raises(Exception, match=r"column e_lat_mm: every offset is below 0\.005 mm "
                                            r"\(largest 0\.0005 mm\): metres instead of mm\?"):
            track_on_seam(read_weld_track(p), pb)
