"""The one TOML writer (robot files, placed problem files): :func:`dumps_toml`.

The reader is :mod:`rfsw_plan.tomlreader`; every number goes through :mod:`rfsw_plan.numfmt`, so
the same data gives the same bytes on every machine.
"""

from __future__ import annotations

import re
from typing import Any

from rfsw_plan.numfmt import shortest

__all__ = ["dumps_toml"]

_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(k: str) -> str:
    return k if _BARE_KEY.match(k) else _toml_str(k)


def _toml_str(v: str) -> str:
    out = []
    for ch in v:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_scalar(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return shortest(v)  # ValueError for a non-finite number (a bug in the writer)
    if isinstance(v, str):
        return _toml_str(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_scalar(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_scalar(x)}" for k, x in v.items()) \
            + " }" if v else "{}"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _toml_lines(table: dict[str, Any]) -> list[str]:
    lines = []
    for k, v in table.items():
        if isinstance(v, list) and v and all(isinstance(r, list) for r in v):
            lines.append(f"{_toml_key(k)} = [")
            lines += [f"    {_toml_scalar(r)}," for r in v]
            lines.append("]")
        else:
            lines.append(f"{_toml_key(k)} = {_toml_scalar(v)}")
    return lines


def dumps_toml(d: dict[str, Any]) -> str:
    """TOML text of a dict: scalars first, then ``[table]`` s and ``[[array]]`` s.

    Nested dicts inside a table (effect ``params``, ``std``, a problem's ``[process.forces]``)
    become inline tables; a list of lists (a coupling matrix, seam points) is one row per line;
    floats are the shortest text that reads back exactly (:func:`rfsw_plan.numfmt.shortest`).
    """
    top = {k: v for k, v in d.items() if not isinstance(v, dict)
           and not (isinstance(v, list) and v and all(isinstance(x, dict) for x in v))}
    lines = _toml_lines(top)
    for k, v in d.items():
        if isinstance(v, dict):
            lines += ["", f"[{_toml_key(k)}]", *_toml_lines(v)]
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for item in v:
                lines += ["", f"[[{_toml_key(k)}]]", *_toml_lines(item)]
    return "\n".join(lines) + "\n"
