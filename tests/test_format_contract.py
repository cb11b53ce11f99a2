"""The controller-format contract (issue 26): a format is one class; a toy format defined here,
and nowhere else, gets the CLI choice, the dispatch of ``export`` and the round trip through
the robot model for free, like ``tests/test_effect_contract.py`` does for effects."""

from __future__ import annotations

import ast
import json
from collections.abc import Hashable, Iterator
from pathlib import Path

import numpy as np
import pytest
from _programs import synthetic

from rfsw_plan.exceptions import InputError
from rfsw_plan.export import api
from rfsw_plan.export.format import (
    FORMATS,
    ControllerFormat,
    FormatLimits,
    ReadPoint,
    ReadProgram,
    format_names,
    formats,
    parse_formats,
)
from rfsw_plan.export.program import Program, build_program
from rfsw_plan.robot.kinematics import Robot


@pytest.fixture
def toy() -> Iterator[type[ControllerFormat]]:
    """A JSON 'controller language': the tool, the plate, and per point the pose and the
    sign pattern of the joints as its posture. Removed from the registry afterwards."""

    class ToyFormat(ControllerFormat):
        name = "toy_json"
        description = "a test format: points as JSON"
        suffix = ".toy.json"
        limits = FormatLimits(name_length=16)

        def posture(self, robot: Robot, q: np.ndarray) -> Hashable:
            return tuple(int(x < 0) for x in q)

        def write(self, program: Program, folder: Path) -> list[Path]:
            moved = program.moved_points()
            doc = {"tool": program.tool.tolist(), "work": program.work.tolist(),
                   "points": [{"pose": program.poses[k].tolist(),
                               "posture": list(self.posture(program.robot,
                                                            program.samples.q[k]))}
                              for k in moved]}
            path = folder / self.file_name(program)
            path.write_text(json.dumps(doc))
            return [path]

        def read(self, path: Path) -> ReadProgram:
            doc = json.loads(path.read_text())
            pts = [ReadPoint(f"t{k}", np.array(p["pose"]), tuple(p["posture"]))
                   for k, p in enumerate(doc["points"])]
            return ReadProgram(np.array(doc["tool"]), np.array(doc["work"]), pts, (path,))

    yield ToyFormat
    FORMATS.pop("toy_json", None)


def test_the_builtin_formats_are_registered() -> None:
    assert format_names()[:4] == ("krl", "fanuc_tp", "rapid", "stream")
    for cls in formats().values():
        assert cls.name and cls.description and cls.suffix


def test_an_incomplete_format_is_not_registered() -> None:
    class Half(ControllerFormat):
        name = "half_format"

        def posture(self, robot: Robot, q: np.ndarray) -> Hashable:
            return 0

    assert "half_format" not in FORMATS
    with pytest.raises(TypeError):
        Half()  # type: ignore[abstract]


def test_a_toy_format_round_trips_without_touching_any_other_file(
        toy: type[ControllerFormat], tmp_path: Path) -> None:
    assert parse_formats("krl,toy_json") == ["krl", "toy_json"]
    robot, samples, _ = synthetic()
    res = api.export_programs(robot, samples, {"problem": "golden", "waypoints": {
        "s_mm": [0.0, 5.0, 10.0]}}, ["toy_json", "krl"], tmp_path, plan_sha256="0" * 64,
        spacing=5e-3)
    assert (tmp_path / "rfsw_golden.toy.json").is_file()
    trip = res.round_trips["toy_json"]
    assert trip.ok and len(trip.q) == len(res.round_trips["krl"].q)
    assert float(np.max(trip.joint_error)) < 1e-8  # full precision: the planned joints
    np.testing.assert_allclose(trip.q, res.round_trips["krl"].q, atol=1e-6)  # KRL: 4 decimals


def test_a_toy_format_with_a_wrong_posture_does_not_round_trip(
        toy: type[ControllerFormat], tmp_path: Path) -> None:
    """The round trip takes the posture the file states: flip the wrist sign of one point and
    the IK lands on another branch (or none), never silently on the planned joints."""
    robot, samples, header = synthetic()
    program = build_program(robot, samples, header)
    fmt = toy()
    path = fmt.write(program, tmp_path)[0]
    doc = json.loads(path.read_text())
    doc["points"][5]["posture"][4] = 1 - doc["points"][5]["posture"][4]
    path.write_text(json.dumps(doc))
    from rfsw_plan.export.readback import round_trip

    try:
        trip = round_trip(robot, fmt, fmt.read(path), fmt.expected(program))
    except InputError:
        return
    assert not trip.ok


def test_cli_choices_come_from_the_registry(toy: type[ControllerFormat]) -> None:
    with pytest.raises(InputError) as exc:
        parse_formats("krl,gcode", "--format")
    assert "toy_json" in str(exc.value) and "krl, fanuc_tp, rapid, stream" in str(exc.value)


def test_export_dispatch_has_no_format_names() -> None:
    """export/api.py picks formats through the registry only: no string compared with a
    format name (the if/elif dispatch is gone)."""
    src = Path(api.__file__).read_text()
    names = set(format_names())
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.Compare):
            consts = [c.value for c in ast.walk(node) if isinstance(c, ast.Constant)]
            assert not names & set(consts), ast.unparse(node)


def test_a_new_format_module_is_discovered_without_any_list(tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch
                                                            ) -> None:
    """A format is one module of rfsw_plan/export: formats() finds a module it has never heard
    of (here in a folder added to the package's path) and registers its class, in its order."""
    import sys

    import rfsw_plan.export as package

    (tmp_path / "toy_discovered.py").write_text(
        "from rfsw_plan.export.stream import StreamFormat\n\n\n"
        "class Discovered(StreamFormat):\n"
        "    name = 'toy_discovered'\n"
        "    order = 15\n")
    monkeypatch.setattr(package, "__path__", [*package.__path__, str(tmp_path)])
    try:
        names = format_names()
        assert "toy_discovered" in names
        assert names.index("krl") < names.index("toy_discovered") < names.index("fanuc_tp")
    finally:
        monkeypatch.undo()
        FORMATS.pop("toy_discovered", None)
        sys.modules.pop("rfsw_plan.export.toy_discovered", None)
    assert "toy_discovered" not in format_names()


def test_the_stream_rows_are_the_csv_writers_cells() -> None:
    """Issue 41: the stream file's rows are formatted one row at a time
    (``stream._rows_text``); the text is what the CSV writer made of the cells
    (``stream._column_text``: ``fixed(x, 6)``, never ``-0.000000``), the rounding edges
    included, and a text cell the writer would quote goes back to the writer."""
    import csv
    import io

    from rfsw_plan.export.stream import _column_text, _rows_text

    rng = np.random.default_rng(3)
    edges = np.array([0.0, -0.0, -4e-7, -5e-7, -5.000001e-7, -6e-7, 5e-7, -1e-6, 1e-6,
                      -0.0000004999999, 123456.0000005, -2.5e-7, -1e-300])
    nums = np.concatenate([edges, rng.normal(scale=100.0, size=200 - len(edges))])
    cols = [nums, np.array(["weld", "plunge"] * 100), np.arange(200), nums[::-1] * 1e-6,
            np.where(nums > 0, "1", "0")]
    want = io.StringIO()
    csv.writer(want).writerows(zip(*[_column_text(c) for c in cols], strict=True))
    assert _rows_text(cols) == want.getvalue()
    assert _rows_text([nums, np.array(["a,b"] * 200)]) is None
    with pytest.raises(ValueError, match="non-finite"):
        _rows_text([np.array([1.0, np.nan])])
