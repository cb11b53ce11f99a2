"""The same bytes on every machine: no negative zero in any written file (issues 24 and 25).

A value that is zero in exact arithmetic is +1e-17 on one machine and -1e-17 on another; both
must be written as the same text. Each writer is run twice on the same data, once as computed
and once with every zero forced to -0.0 and every float-noise value (|v| < 1e-12) negated: the
bytes must be identical, and no file may hold a negative zero (``-0.000``, ``-0,``, ``-0]``).
"""

from __future__ import annotations

import dataclasses
import json
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rfsw_plan import numfmt
from rfsw_plan.files import strict_json

sys.path.insert(0, str(Path(__file__).parent))

#: A negative zero in text: a minus sign, then only zeros (and a point) up to a non-digit.
NEGATIVE_ZERO = re.compile(r"(?<![\w.])-0(\.0*)?(?![\d.])")


def negzero(obj: Any) -> Any:
    """``obj`` with every 0.0 turned into -0.0 and every |v| < 1e-12 negated (float arrays,
    floats, and the fields of dataclasses, tuples and lists, recursively)."""
    if isinstance(obj, np.ndarray) and obj.dtype.kind == "f":
        out = obj.copy()
        tiny = np.abs(out) < 1e-12
        out[tiny] = -out[tiny]
        out[out == 0] = -0.0
        return out
    if isinstance(obj, float):
        return -obj if abs(obj) < 1e-12 else obj
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        changes = {f.name: negzero(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                   if (f.init and isinstance(getattr(obj, f.name),
                                            (np.ndarray, float, tuple, list)))
                   or dataclasses.is_dataclass(getattr(obj, f.name))}
        changes = {k: v for k, v in changes.items() if not _is_robot(v)}
        return dataclasses.replace(obj, **changes)
    if isinstance(obj, tuple):
        return tuple(negzero(v) for v in obj)
    if isinstance(obj, list):
        return [negzero(v) for v in obj]
    return obj


def _is_robot(v: Any) -> bool:
    return type(v).__name__ in ("Robot", "RobotDescription")


def assert_no_negative_zero(text: str, what: str) -> None:
    hit = NEGATIVE_ZERO.search(text)
    assert hit is None, f"{what}: negative zero {text[max(hit.start() - 30, 0):hit.end() + 10]!r}"


# -- the helper -------------------------------------------------------------------------------


@pytest.mark.parametrize(("x", "digits", "text"), [
    (-0.0, 4, "0.0000"), (-1e-17, 4, "0.0000"), (1e-17, 4, "0.0000"), (-0.00004, 4, "0.0000"),
    (-0.00005001, 4, "-0.0001"), (-1.5, 1, "-1.5"), (-0.4, 0, "0"), (2.5, 0, "2"),
    (390.0, 4, "390.0000"), (-123456.789, 2, "-123456.79")])
def test_fixed(x: float, digits: int, text: str) -> None:
    assert numfmt.fixed(x, digits) == text
    assert numfmt.fixed(np.float64(x), digits) == text


def test_general_cell_and_non_finite() -> None:
    assert numfmt.general(-0.0) == "0"
    assert numfmt.general(-1e-300, 6) == "-1e-300"  # not zero: keeps its sign
    assert numfmt.general(-2.5e-7, 3) == "-2.5e-07"
    assert numfmt.cell(float("nan")) == "" and numfmt.cell(None) == ""
    assert numfmt.cell(-0.0, 3) == "0.000"
    for bad in (float("nan"), float("inf"), -float("inf")):
        with pytest.raises(ValueError):
            numfmt.fixed(bad, 3)
        with pytest.raises(ValueError):
            numfmt.general(bad)


def test_strict_json_has_no_negative_zero() -> None:
    text = strict_json({"a": -0.0, "b": [np.float64(-0.0), np.array([-0.0, 1.0])]})
    assert json.loads(text) == {"a": 0.0, "b": [0.0, [0.0, 1.0]]}
    assert_no_negative_zero(text, "strict_json")


# -- every writer, with and without -0.0 forced in ----------------------------------------------


def _program() -> tuple[Any, Any]:
    from _programs import synthetic

    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.export.program import build_program

    robot, samples, header = synthetic()
    return robot, build_program(robot, samples, header,
                                payload=ElastostaticModel(robot).tool_payload())


def _write_programs(program: Any, robot: Any, folder: Path) -> dict[str, bytes]:
    """Every registered controller format (the stream included) through its own writer."""
    from rfsw_plan.export.format import formats

    folder.mkdir()
    for cls in formats().values():
        cls().write(program, folder)
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_controller_programs_are_the_same_with_negative_zeros(tmp_path: Path) -> None:
    robot, program = _program()
    plain = _write_programs(program, robot, tmp_path / "plain")
    forced = _write_programs(negzero(program), robot, tmp_path / "forced")
    assert {"rfsw_golden.src", "rfsw_golden.dat", "RFSW_GOLDEN.ls",
            "rfsw_golden.mod"} < set(plain)
    for name, data in plain.items():
        assert forced[name] == data, name
        assert_no_negative_zero(data.decode(), name)


def _measurements() -> Any:
    from rfsw_plan.elastostatics.measurement_set import MeasurementSet

    rng = np.random.default_rng(3)
    m = 6
    q = rng.normal(size=(m, 6))
    q[0] = 0.0
    wrench = np.zeros((m, 6))
    wrench[2:, 2] = -1000.0
    pos = rng.normal(size=(m, 3))
    pos[1] = 0.0
    pos[3, 1] = np.nan
    return MeasurementSet(q, wrench, pos, np.arange(m) * 1.0, None, None,
                          {"temperature_C": np.zeros(m)}, "mem")


def test_data_writers_are_the_same_with_negative_zeros(tmp_path: Path) -> None:
    from rfsw_plan.io.force_series import write_force_series
    from rfsw_plan.io.measurements import write_measurements
    from rfsw_plan.io.weld_track import WeldTrack, write_weld_track
    from rfsw_plan.process.force_series import ForceSeries

    fs = ForceSeries(t=np.arange(5) * 0.1, force=np.zeros((5, 3)), moment=np.zeros((5, 3)),
                     frame="seam", source="mem")
    track = WeldTrack("seam", np.arange(4) * 1e-3, np.array([0.0, 1e-18, -2e-4, 0.0]),
                      np.zeros(4), None)
    base = WeldTrack("base", None, None, None, np.zeros((3, 3)))
    writers = {
        "m.csv": lambda p, neg: write_measurements(p, negzero(_measurements()) if neg
                                                   else _measurements()),
        "f.csv": lambda p, neg: write_force_series(p, negzero(fs) if neg else fs),
        "t.csv": lambda p, neg: write_weld_track(p, negzero(track) if neg else track),
        "b.csv": lambda p, neg: write_weld_track(p, negzero(base) if neg else base),
    }
    for name, write in writers.items():
        write(tmp_path / f"plain_{name}", False)
        write(tmp_path / f"neg_{name}", True)
        data = (tmp_path / f"plain_{name}").read_bytes()
        assert (tmp_path / f"neg_{name}").read_bytes() == data, name
        assert_no_negative_zero(data.decode(), name)


@pytest.fixture(scope="module")
def zk500_plan() -> Any:
    from rfsw_plan.planning.api import plan

    return plan("zk500_table6_seam", spacing=0.02)


def test_plan_folder_is_the_same_with_negative_zeros(tmp_path: Path, zk500_plan: Any,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """The plan written twice, the second time with -0.0 forced into every float of the
    waypoint table and of the exported programs: waypoints.csv and the programs are
    byte-identical."""
    from rfsw_plan.export import api as export_api
    from rfsw_plan.export.api import export_programs
    from rfsw_plan.files import sha256_file
    from rfsw_plan.planfiles import waypoints as wp
    from rfsw_plan.planfiles.folder import read_plan_samples

    def write(folder: Path) -> dict[str, bytes]:
        folder.mkdir()
        wp.write_waypoints_csv(folder / "waypoints.csv", zk500_plan)
        robot = zk500_plan.model.robot
        samples = read_plan_samples(folder / "waypoints.csv",
                                    robot.description.convention.column_names())
        export_programs(robot, samples, zk500_plan.summary(), ["krl", "fanuc_tp", "rapid"],
                        folder, plan_sha256=sha256_file(folder / "waypoints.csv"))
        return {p.name: p.read_bytes() for p in sorted(folder.iterdir())
                if p.suffix in (".csv", ".src", ".dat", ".ls", ".mod")}

    plain = write(tmp_path / "plain")
    table, build = wp.waypoint_table, export_api.build_program

    def forced_table(result: Any) -> Any:
        header, rows = table(result)
        rows = rows.copy()
        for idx, v in np.ndenumerate(rows):
            if isinstance(v, float | np.floating) and abs(v) < 1e-12:
                rows[idx] = -0.0 if v == 0 else -float(v)
        return header, rows

    monkeypatch.setattr(wp, "waypoint_table", forced_table)
    monkeypatch.setattr(export_api, "build_program", lambda *a, **k: negzero(build(*a, **k)))
    forced = write(tmp_path / "forced")
    assert {"waypoints.csv"} < set(plain) and len(plain) >= 5
    for name, data in plain.items():
        # The plan id and stamps are the same: they come from the same waypoints.csv bytes.
        assert_no_negative_zero(data.decode(), name)
        if name.endswith(".ls"):  # the TP header carries the write time (minutes)
            data = re.sub(rb"(CREATE|MODIFIED)\s*= DATE [^;]*;", b"", data)
            forced[name] = re.sub(rb"(CREATE|MODIFIED)\s*= DATE [^;]*;", b"", forced[name])
        assert forced[name] == data, name


def test_fixed_many_is_fixed_for_every_number() -> None:
    """The array formatter of the 3-D pages gives :func:`fixed`'s text for every number
    (negative zeros, values that round to zero from below, halves, large and tiny values)."""
    from rfsw_plan.numfmt import fixed, fixed_many

    rng = np.random.default_rng(3)
    values = np.concatenate([
        [0.0, -0.0, -1e-17, 1e-17, -0.00049, -0.0005, 0.0005, 0.125, -0.125, 2.5, -2.5, 1e12],
        rng.normal(size=500) * 10.0 ** rng.integers(-8, 5, 500)])
    for digits in (0, 1, 3, 4, 5):
        assert fixed_many(values, digits) == [fixed(v, digits) for v in values], digits
    assert fixed_many(np.array([[1.0, np.nan]]), 2) == ["1.00", None]
    with pytest.raises(ValueError):
        fixed_many([1.0, np.inf], 2)


def test_cell_many_is_cell_for_every_number() -> None:
    """The column formatter of ``waypoints.csv`` gives :func:`cell`'s text for every number,
    including the empty "no value" cell of NaN and +-inf."""
    from rfsw_plan.numfmt import cell, cell_many

    rng = np.random.default_rng(4)
    values = np.concatenate([
        [0.0, -0.0, -1e-17, 1e-17, -4.9e-7, -5e-7, 5e-7, np.nan, np.inf, -np.inf, 1e12],
        rng.normal(size=500) * 10.0 ** rng.integers(-9, 5, 500)])
    for digits in (0, 3, 6):
        assert cell_many(values, digits) == [cell(v, digits) for v in values], digits


def _near_halves(digits: int, rng: np.random.Generator) -> np.ndarray:
    """Values whose scaled fraction is at or next to one half (the integer conversion's only
    doubtful case), the doubles on both sides of each, large and tiny ones, both signs."""
    base = (rng.integers(-10**8, 10**8, 3000) + 0.5) / 10.0 ** digits
    return np.concatenate([base, np.nextafter(base, np.inf), np.nextafter(base, -np.inf),
                           [2.0 ** 52 / 10 ** digits, -(2.0 ** 52) / 10 ** digits, 1e20, -1e20,
                            5e-324, -5e-324, 9.9999999999, -9.99999999, 99999.9999999]])


def test_fixed_codes_are_pythons_conversion_digit_for_digit() -> None:
    """The array conversion (integers for the digits, Python for the doubtful values) gives
    Python's correctly rounded text, never ``-0``, at the halves and next to them, for huge
    and subnormal values and every magnitude in between."""
    from rfsw_plan.numfmt import cell, fixed_texts

    rng = np.random.default_rng(5)
    for digits in (0, 1, 3, 6, 9, 12):
        values = np.concatenate([_near_halves(digits, rng), [0.0, -0.0, np.nan, np.inf],
                                 rng.normal(size=3000) * 10.0 ** rng.integers(-12, 12, 3000)])
        assert fixed_texts(values, digits).tolist() == [cell(v, digits) for v in values], digits


def test_table_bytes_is_the_csv_modules_table(tmp_path: Path) -> None:
    """``waypoints.csv``'s body, built as arrays, is byte for byte what ``csv.writer`` writes
    from :func:`cell` texts; a text cell that needs quoting is refused (the writer then uses
    the csv module)."""
    import csv
    import io

    from rfsw_plan.numfmt import cell, table_bytes

    rng = np.random.default_rng(6)
    n = 400
    columns: list[Any] = [rng.normal(size=n) * 10.0 ** rng.integers(-9, 6, n),
                          [("weld", "", "plunge", "x y")[k % 4] for k in range(n)],
                          np.where(rng.random(n) < 0.2, np.nan, rng.normal(size=n)),
                          _near_halves(6, rng)[:n]]
    ref = io.StringIO(newline="")
    csv.writer(ref).writerows(
        [[c[k] if isinstance(c, list) else cell(c[k], 6) for c in columns] for k in range(n)])
    assert table_bytes(columns, 6) == ref.getvalue().encode("ascii")
    with pytest.raises(ValueError, match="quoting"):
        table_bytes([np.zeros(2), ["a,b", "c"]], 6)
