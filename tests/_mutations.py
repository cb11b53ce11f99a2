"""Mutations of input files for the reader fuzz tests (problem TOML, robot TOML, seam CSV).

Each mutation is a small, named change a user could make by accident: a renamed or deleted
key, a value of the wrong type, NaN / infinity / a huge, tiny, negative or zero number, a
duplicated or dropped CSV column, a truncated file, junk bytes, another delimiter. Mutations are
applied to the parsed TOML (written back with ``tomli_w``) or to the text, so that every one is
reproducible from its description.

``harmless`` mutations (comments, blank lines, reordered tables) must never change what a
reader produces; every other one must either be rejected (exit 2) or leave the model unchanged.
"""

from __future__ import annotations

import copy
import math
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import tomli_w

Path_ = tuple[str | int, ...]

#: Replacement numbers that test the range and finite checks.
BAD_NUMBERS: tuple[float, ...] = (
    math.nan, math.inf, -math.inf, 1e308, -1e308, 1e300, 1e30, -1.0, 0.0, 1e-320, 1000.0, -1000.0,
)


@dataclass(frozen=True)
class Mutation:
    """One mutation of a file.

    Attributes:
        kind: Family (``rename``, ``unknown``, ``delete``, ``retype``, ``number``, ``text``,
            ``harmless``...).
        where: Dotted key or text position it touches.
        text: The mutated file content.
    """

    kind: str
    where: str
    text: str

    @property
    def harmless(self) -> bool:
        """True for changes that cannot change what the file means."""
        return self.kind == "harmless"


def dotted(path: Path_) -> str:
    return ".".join(str(p) for p in path)


def key_paths(data: Any, prefix: Path_ = ()) -> Iterator[Path_]:
    """Every key path (tables, arrays of tables, keys) in parsed TOML, depth first."""
    if isinstance(data, dict):
        for k, v in data.items():
            yield (*prefix, k)
            yield from key_paths(v, (*prefix, k))
    elif isinstance(data, list) and data and all(isinstance(x, dict) for x in data):
        for i, x in enumerate(data):
            yield from key_paths(x, (*prefix, i))


def number_paths(data: Any, prefix: Path_ = ()) -> Iterator[Path_]:
    """Every numeric leaf (including list elements) in parsed TOML."""
    if isinstance(data, dict):
        for k, v in data.items():
            yield from number_paths(v, (*prefix, k))
    elif isinstance(data, list):
        for i, x in enumerate(data):
            yield from number_paths(x, (*prefix, i))
    elif isinstance(data, int | float) and not isinstance(data, bool):
        yield prefix


def table_paths(data: Any, prefix: Path_ = ()) -> Iterator[Path_]:
    """Every table (dict) path, the root included."""
    if isinstance(data, dict):
        yield prefix
        for k, v in data.items():
            yield from table_paths(v, (*prefix, k))
    elif isinstance(data, list):
        for i, x in enumerate(data):
            if isinstance(x, dict):
                yield from table_paths(x, (*prefix, i))


def _get(data: Any, path: Path_) -> Any:
    for p in path:
        data = data[p]
    return data


def typos(key: str) -> list[str]:
    """Typing slips of a key: a dropped, doubled or swapped letter (never the key itself)."""
    out: list[str] = []
    for i in range(len(key)):
        out.append(key[:i] + key[i + 1:])
        out.append(key[:i] + key[i] + key[i:])
        if i + 1 < len(key):
            out.append(key[:i] + key[i + 1] + key[i] + key[i + 2:])
    return [t for t in dict.fromkeys(out) if t and t != key]


def _dump(data: dict[str, Any]) -> str:
    return tomli_w.dumps(data)


def rename(data: dict[str, Any], path: Path_, new: str) -> str:
    d = copy.deepcopy(data)
    parent = _get(d, path[:-1])
    items = list(parent.items())
    parent.clear()
    for k, v in items:
        parent[new if k == path[-1] else k] = v
    return _dump(d)


def delete(data: dict[str, Any], path: Path_) -> str:
    d = copy.deepcopy(data)
    parent = _get(d, path[:-1])
    del parent[path[-1]]
    return _dump(d)


def set_value(data: dict[str, Any], path: Path_, value: Any) -> str:
    d = copy.deepcopy(data)
    parent = _get(d, path[:-1])
    parent[path[-1]] = value
    return _dump(d)


def add_key(data: dict[str, Any], table: Path_, key: str, value: Any = 1.0) -> str:
    d = copy.deepcopy(data)
    _get(d, table)[key] = value
    return _dump(d)


def key_mutations(text: str) -> list[Mutation]:
    """Renamed (first typo of every key) and unknown-key (one per table) mutations."""
    data = tomllib.loads(text)
    out: list[Mutation] = []
    for path in key_paths(data):
        if isinstance(path[-1], int):
            continue
        key = str(path[-1])
        out.append(Mutation("rename", dotted(path), rename(data, path, typos(key)[0])))
    for table in table_paths(data):
        out.append(Mutation("unknown", dotted(table) or "<top>",
                            add_key(data, table, "unexpected_key")))
    return out


def value_mutations(text: str) -> list[Mutation]:
    """Deleted keys, wrong types and bad numbers at every key / numeric leaf."""
    data = tomllib.loads(text)
    out: list[Mutation] = []
    for path in key_paths(data):
        if isinstance(path[-1], int):
            continue
        out.append(Mutation("delete", dotted(path), delete(data, path)))
        for v in ("up", True, [], {"a": 1}):
            out.append(Mutation("retype", f"{dotted(path)}={v!r}", set_value(data, path, v)))
    for path in number_paths(data):
        for v in BAD_NUMBERS:
            out.append(Mutation("number", f"{dotted(path)}={v!r}", set_value(data, path, v)))
    return out


def harmless_mutations(text: str) -> list[Mutation]:
    """Comments, blank lines and a re-serialised (reordered, reformatted) copy."""
    lines = text.splitlines()
    out = [Mutation("harmless", "re-dump", _dump(tomllib.loads(text)))]
    for i in range(0, len(lines) + 1, max(1, len(lines) // 6)):
        out.append(Mutation("harmless", f"comment@{i}",
                            "\n".join([*lines[:i], "# a comment [tool] = 1", *lines[i:]])))
        out.append(Mutation("harmless", f"blank@{i}", "\n".join([*lines[:i], "   ", *lines[i:]])))
    return out


def text_mutations(text: str, positions: list[int],
                   junk: bytes = b"\x00\xff=[\"") -> list[Mutation]:
    """Truncations and junk inserted at the given character positions."""
    out: list[Mutation] = []
    for p in positions:
        p = max(0, min(len(text), p))
        out.append(Mutation("truncate", f"@{p}", text[:p]))
        out.append(Mutation("junk", f"@{p}", text[:p] + junk.decode("latin-1") + text[p:]))
    return out
