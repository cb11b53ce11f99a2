"""The one TOML writer (rfsw_plan/tomlwriter.py): every bundled problem and robot file reads
back as the same data, and numbers go through numfmt (no negative zero, exact floats)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from rfsw_plan.tomlwriter import dumps_toml

ROOT = Path(__file__).resolve().parents[1]
FILES = sorted((ROOT / "problems").glob("*.toml")) + sorted((ROOT / "robots").glob("*.toml"))


@pytest.mark.parametrize("path", FILES, ids=[p.name for p in FILES])
def test_a_bundled_file_reads_back_as_the_same_data(path: Path) -> None:
    data = tomllib.loads(path.read_text())
    assert tomllib.loads(dumps_toml(data)) == data


def test_numbers_are_exact_and_never_negative_zero() -> None:
    text = dumps_toml({"a": -0.0, "b": 0.1 + 0.2, "t": {"m": [[1e-07, -0.0]]}})
    assert "-0.0" not in text
    back = tomllib.loads(text)
    assert back["b"] == 0.1 + 0.2 and back["t"]["m"] == [[1e-07, 0.0]]
    with pytest.raises(ValueError):
        dumps_toml({"x": float("nan")})
