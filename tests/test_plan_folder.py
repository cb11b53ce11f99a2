"""The one strict plan-folder reader (issue 25): damaged folders give one line and exit 2 (3 for
an infeasible plan), never a traceback, through ``read_plan_folder`` and through the commands
that use it (``export``, ``check``)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from _programs import synthetic

from rfsw_plan.cli.main import main
from rfsw_plan.exceptions import InfeasibleError, InputError
from rfsw_plan.files import sha256_file
from rfsw_plan.planfiles.folder import read_plan_folder

COLS = ["t_s", "s_mm", "phase", "seam_x_mm", "seam_y_mm", "seam_z_mm", "J1_deg", "J2_deg",
        "J3_deg", "J4_deg", "J5_deg", "J6_deg", "fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm",
        "mz_Nm"]


def _folder(tmp: Path) -> Path:
    """A small verified-looking plan folder of the synthetic ZK-500 path."""
    _, s, _ = synthetic()
    tmp.mkdir(parents=True, exist_ok=True)
    with (tmp / "waypoints.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(COLS)
        for k in range(len(s)):
            w.writerow([f"{s.t[k]:.6f}", f"{s.s[k] * 1e3:.6f}", s.phase[k],
                        *(f"{x * 1e3:.6f}" for x in s.seam[k]),
                        *(f"{x:.6f}" for x in np.degrees(s.q[k])), *(["0.000000"] * 6)])
    rec = {"status": "optimal", "problem": "golden", "robot": "zk500",
           "waypoints": {"s_mm": [0.0, 5.0, 10.0]},
           "sha256": {"waypoints.csv": sha256_file(tmp / "waypoints.csv")}}
    (tmp / "plan.json").write_text(json.dumps(rec))
    return tmp


def _one_line_exit(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(args)
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    return code, err


def test_a_good_folder_reads(tmp_path: Path) -> None:
    pf = read_plan_folder(_folder(tmp_path / "p"))
    assert pf.status == "optimal" and len(pf.samples) > 40
    assert pf.samples.q.shape[1] == 6 and np.all(np.isfinite(pf.samples.q))


def _utf16(p: Path) -> None:
    p.write_bytes(p.read_text().encode("utf-16"))


def _random(p: Path) -> None:
    p.write_bytes(np.random.default_rng(1).integers(0, 256, 500, dtype=np.uint8).tobytes())


def _empty(p: Path) -> None:
    p.write_bytes(b"")


def _nan(p: Path) -> None:
    p.write_text(p.read_text().replace('"status": "optimal"', '"status": "optimal", "x": NaN'))


def _failed(p: Path) -> None:
    p.write_text(p.read_text().replace('"status": "optimal"',
                                       '"status": "failed", "message": "IPOPT crashed"'))


def _infeasible(p: Path) -> None:
    p.write_text(p.read_text().replace('"status": "optimal"',
                                       '"status": "infeasible", "message": "window at wp 3"'))


def _duplicate(p: Path) -> None:
    p.write_text(p.read_text().replace('"status": "optimal"',
                                       '"status": "optimal", "status": "optimal"'))


def _array(p: Path) -> None:
    p.write_text("[1, 2]")


def _no_robot(p: Path) -> None:
    p.write_text(p.read_text().replace('"robot": "zk500", ', ""))


def _infeasible_no_robot(p: Path) -> None:
    _no_robot(p)
    _infeasible(p)


DAMAGE = [("utf16", _utf16, 2, "not UTF-8"), ("random", _random, 2, "plan.json"),
          ("empty", _empty, 2, "empty"), ("nan", _nan, 2, "NaN"),
          ("failed", _failed, 2, "'failed': IPOPT crashed"),
          ("infeasible", _infeasible, 3, "'infeasible': window at wp 3"),
          ("duplicate", _duplicate, 2, "duplicate key"), ("array", _array, 2, "not an object"),
          # the status is named before the robot is looked for (was: "unknown robot ''")
          ("infeasible, no robot", _infeasible_no_robot, 3, "'infeasible': window at wp 3")]


@pytest.mark.parametrize(("damage", "code", "words"), [d[1:] for d in DAMAGE],
                         ids=[d[0] for d in DAMAGE])
def test_a_damaged_record_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                      damage, code: int, words: str) -> None:
    folder = _folder(tmp_path / "p")
    damage(folder / "plan.json")
    with pytest.raises((InputError, InfeasibleError)) as exc:
        read_plan_folder(folder)
    assert words in str(exc.value)
    for cmd in (["export", str(folder), "-o", str(tmp_path / "o")],
                ["check", str(tmp_path / "x.src"), "--plan", str(folder)]):
        if cmd[0] == "check":
            (tmp_path / "x.src").write_text("DEF x( )\nEND\n")
            (tmp_path / "x.dat").write_text("DEFDAT x\nENDDAT\n")
        got, err = _one_line_exit(cmd, capsys)
        assert got == code
        assert len(err.splitlines()) == 1, err
    # the refused export wrote nothing: no program and no half-written .export-* staging
    # folder (its output folder, checked before the record is read, is left empty)
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == []


def test_a_plan_naming_no_robot_is_one_line(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    """export and check need the plan's robot: a record without one is named (was "unknown
    robot ''")."""
    folder = _folder(tmp_path / "p")
    _no_robot(folder / "plan.json")
    (tmp_path / "x.src").write_text("DEF x( )\nEND\n")
    (tmp_path / "x.dat").write_text("DEFDAT x\nENDDAT\n")
    for cmd in (["export", str(folder), "-o", str(tmp_path / "o")],
                ["check", str(tmp_path / "x.src"), "--plan", str(folder)]):
        got, err = _one_line_exit(cmd, capsys)
        assert got == 2 and len(err.splitlines()) == 1, err
        assert "robot_file: missing: the plan names no robot" in err


def test_nan_in_a_joint_cell_with_the_hash_updated(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 25 item 5: once a traceback from an interpolation, now one line naming the cell."""
    folder = _folder(tmp_path / "p")
    text = (folder / "waypoints.csv").read_text().splitlines()
    cells = text[5].split(",")
    cells[COLS.index("J3_deg")] = "nan"
    text[5] = ",".join(cells)
    (folder / "waypoints.csv").write_text("\n".join(text) + "\n")
    rec = json.loads((folder / "plan.json").read_text())
    rec["sha256"]["waypoints.csv"] = sha256_file(folder / "waypoints.csv")
    (folder / "plan.json").write_text(json.dumps(rec))
    code, err = _one_line_exit(["export", str(folder), "-o", str(tmp_path / "o")], capsys)
    assert code == 2 and len(err.splitlines()) == 1
    assert "row 6, column J3_deg" in err and "not a finite number" in err


def test_a_changed_or_missing_file_is_named(tmp_path: Path) -> None:
    folder = _folder(tmp_path / "p")
    with (folder / "waypoints.csv").open("a") as fh:
        fh.write("\n")
    with pytest.raises(InputError, match=r"changed since plan\.json"):
        read_plan_folder(folder)
    (folder / "waypoints.csv").unlink()
    with pytest.raises(InputError, match=r"missing beside plan\.json"):
        read_plan_folder(folder)


def test_joint_values_outside_the_limits_are_refused(tmp_path: Path) -> None:
    folder = _folder(tmp_path / "p")
    lo, hi = np.radians([-10.0] * 6), np.radians([10.0] * 6)
    with pytest.raises(InputError, match="outside the joint limits"):
        read_plan_folder(folder, limits=(lo, hi))


# ---- the one owner of the folder: PlanRecord and PlanFolder.rebuild (issue 33) ---------------


@pytest.fixture(scope="module")
def written(planned_result, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The bundled zk500 plan written by the library (as ``rfsw-plan plan -o`` writes it)."""
    from rfsw_plan.planfiles import write_plan

    res = planned_result("zk500_table6_seam")
    folder = tmp_path_factory.mktemp("zk500_plan")
    write_plan(folder, res, robot_file=res.model.robot.description.path)
    return folder


def test_plan_record_round_trips_the_bytes_of_a_written_record(tmp_path: Path,
                                                               written: Path) -> None:
    """A record read and written again has the bytes the planner wrote (key order included)."""
    from rfsw_plan.planfiles.record import PlanRecord

    folder = written
    rec = PlanRecord.read(folder / "plan.json")
    assert PlanRecord.from_json(rec.to_json()) == rec
    rec.write(tmp_path / "plan.json")
    assert (tmp_path / "plan.json").read_bytes() == (folder / "plan.json").read_bytes()
    assert rec.verified and rec.problem == "zk500_table6_seam"
    assert set(rec.sha256) >= {"waypoints.csv", "lateral_error.png"}


@pytest.mark.parametrize(("key", "value", "want"), [
    ("status", 5, "status: a JSON integer (expected string)"),
    ("sha256", ["waypoints.csv"], "sha256: a JSON array (expected object)"),
    ("n_start_waypoints", True, "n_start_waypoints: a JSON boolean (expected integer)"),
])
def test_a_typed_record_key_of_the_wrong_type_is_one_line(tmp_path: Path, key: str, value: object,
                                                        want: str) -> None:
    folder = _folder(tmp_path / "p")
    rec = json.loads((folder / "plan.json").read_text())
    rec[key] = value
    (folder / "plan.json").write_text(json.dumps(rec))
    with pytest.raises(InputError) as err:
        read_plan_folder(folder)
    assert want in str(err.value) and "\n" not in str(err.value)


def test_rebuild_gives_the_task_and_waypoints_the_plan_was_made_on(written: Path,
                                                                   planned_result) -> None:
    """PlanFolder.rebuild() (what check and validate-weld use) reproduces the planner's task:
    the same waypoints (arc length, phase, loads) and the same joints, from the files alone."""
    from rfsw_plan.planfiles.folder import PlanFolder

    res = planned_result("zk500_table6_seam")
    rebuilt = PlanFolder.open(written).rebuild()
    task = rebuilt.task()
    assert len(task) == len(res.task) and task.n_start == res.task.n_start
    assert np.array_equal(task.phase, res.task.phase)
    np.testing.assert_allclose(task.s, res.task.s, atol=1e-9)
    np.testing.assert_allclose(task.force_seam, res.task.force_seam, atol=1e-6)
    np.testing.assert_allclose(rebuilt.waypoints.q, res.q, atol=1e-9)
    assert rebuilt.problem.name == "zk500_table6_seam"


@pytest.mark.parametrize("status", ["optimal", "optimal_nominal", "verified", "verified_nominal"])
def test_every_status_the_planner_writes_for_a_verified_plan_reads(tmp_path: Path,
                                                                   status: str) -> None:
    """plan() writes ``verified_nominal`` for a fallback plan that does not hold the requested
    uncertainty (planning/api.py); the strict reader refused it before (test_plan_property)."""
    folder = _folder(tmp_path / "p")
    rec = json.loads((folder / "plan.json").read_text())
    (folder / "plan.json").write_text(json.dumps({**rec, "status": status}))
    assert read_plan_folder(folder).status == status


def test_csv_rows_are_the_csv_modules_rows() -> None:
    """The plan readers split a quote-free CRLF ``waypoints.csv`` at its commas and line
    ends: the rows the csv module reads, blank lines, empty cells and a missing last line end
    included; any other text (quotes, LF or CR line ends) goes to the csv module."""
    import io
    import random

    from rfsw_plan.planfiles.folder import csv_rows

    rnd = random.Random(7)
    pieces = ["1.5", "", "-0.000001", "weld", ",", "\r\n", "\n", "\r", '"a,b"', "x y", "\t"]
    for _ in range(3000):
        text = "".join(rnd.choice(pieces) for _ in range(rnd.randint(0, 12)))
        assert csv_rows(text) == list(csv.reader(io.StringIO(text, newline=""))), repr(text)
