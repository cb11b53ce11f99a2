"""Atomic writes, strict JSON, checked and locked output folders (rfsw_plan.files)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rfsw_plan.exceptions import OutputPathError
from rfsw_plan.files import (
    OutputLock,
    atomic_path,
    prepare_output_dir,
    strict_json,
    write_json,
    write_text,
)


def _reject(c: str) -> float:
    raise ValueError(f"non-strict JSON constant {c}")


def test_strict_json_turns_nan_and_inf_into_null() -> None:
    obj = {"a": math.nan, "b": [np.inf, -np.inf, np.float64(1.5)], "c": np.arange(2),
           "d": np.bool_(True), "e": (1, 2.0)}
    text = strict_json(obj)
    back = json.loads(text, parse_constant=_reject)
    assert back == {"a": None, "b": [None, None, 1.5], "c": [0, 1], "d": True, "e": [1, 2.0]}


def test_atomic_write_leaves_old_file_on_failure(tmp_path) -> None:
    target = tmp_path / "x.txt"
    write_text(target, "old\n")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("killed")
    assert target.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["x.txt"]  # no temporary left behind
    write_json(target, {"v": 1})
    assert json.loads(target.read_text()) == {"v": 1}


def test_output_dir_checks(tmp_path) -> None:
    f = tmp_path / "file"
    f.write_text("")
    with pytest.raises(OutputPathError, match="existing file"):
        prepare_output_dir(f)
    with pytest.raises(OutputPathError, match="under the file"):
        prepare_output_dir(f / "sub")
    with pytest.raises(OutputPathError, match="pseudo file system"):
        prepare_output_dir("/proc/self")
    assert prepare_output_dir(tmp_path / "new" / "dir").is_dir()


def test_second_writer_is_refused(tmp_path) -> None:
    with OutputLock(tmp_path), pytest.raises(OutputPathError, match="another rfsw-plan"):
        OutputLock(tmp_path).__enter__()
    with OutputLock(tmp_path):  # released after the first one ends
        pass


def test_no_file_is_named_after_a_stop_request(tmp_path) -> None:
    """SIGTERM raises KeyboardInterrupt, which a library may swallow (CasADi's wrappers have
    bare ``except:``): after the stop request no file gets its name and no lock is taken."""
    from rfsw_plan import files

    files.note_interrupt()
    try:
        with pytest.raises(KeyboardInterrupt):
            write_text(tmp_path / "x.txt", "a")
        with pytest.raises(KeyboardInterrupt):
            OutputLock(tmp_path).__enter__()
    finally:
        files.clear_interrupt()
    assert list(tmp_path.iterdir()) == []
    write_text(tmp_path / "x.txt", "a")


def test_a_figure_is_written_like_every_other_file(tmp_path, monkeypatch) -> None:
    """Plots are rendered in memory and get the unnamed temporary of every other file (a kill
    while plotting once left ``.lateral_error_time.png.*.tmp.png`` beside a plan), in the
    format their suffix names."""
    import tempfile

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rfsw_plan.files import write_figure

    def no_named_temporary(*args, **kwargs):
        raise AssertionError("a named temporary was made")

    monkeypatch.setattr(tempfile, "mkstemp", no_named_temporary)
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    png = write_figure(tmp_path / "a.png", fig, dpi=50)
    svg = write_figure(tmp_path / "a.svg", fig)
    plt.close(fig)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in svg.read_bytes()[:400]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "a.svg"]
