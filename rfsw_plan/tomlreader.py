"""One typed, strict reader for the TOML files of rfsw_plan (robot and problem files).

Every table is read through a :class:`Table` that knows the keys it allows: an unknown key (a
typo, usually) is an :class:`~rfsw_plan.exceptions.InputError` that names the file and the
dotted key and suggests the closest allowed key ("did you mean"). Every number is checked to be
finite and inside the range the caller gives, in file units, before any unit conversion, so an
error message quotes the value as the user wrote it::

    robots/my.toml: tol: unknown key; did you mean 'tool'?
    robots/my.toml: joints.coupling: row 3 contains NaN or infinity (expected finite numbers)
    problems/p.toml: seam.spacing_mm: got 1e-320 (expected a number in [0.01, 1000])

The module sits below every other one (it imports only :mod:`rfsw_plan.exceptions`), so robot
descriptions, problem files and the ``[planning]`` options share it.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Collection, Iterable, Mapping
from difflib import get_close_matches
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError

FloatArray = NDArray[np.float64]

#: Largest magnitude accepted for a number that has no tighter range (file units). Anything
#: larger is a typo or a fuzzed value, and would overflow products of it (1e300^2 = inf).
MAX_ABS = 1e12


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; every failure is one :class:`InputError` naming the file.

    Raises:
        InputError: Unreadable file, not UTF-8, or not valid TOML (with the line and column).
    """
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(path, "", "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, "", f"cannot read file: {_short(exc)}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(path, "", f"not valid TOML: {exc}") from None
    except RecursionError:
        raise InputError(path, "", "not valid TOML: nested too deeply") from None


def suggest(name: str, known: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest known name, or ``""``."""
    close = get_close_matches(name, sorted(known), n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def unknown_name_error(source: str | Path, where: str, name: str, known: Collection[str],
                       what: str = "key") -> InputError:
    """The one-line error for an unknown key or option, with a "did you mean" hint.

    A key is named by its dotted path (``file: seam.tilt_dg: unknown key; did you mean
    'tilt_deg'?``), anything else in the message (``--set: unknown option 'w_stifness'; did
    you mean 'w_stiffness'?``). Without a close match the known names are listed.
    """
    hint = suggest(name, known)
    expected = "" if hint else f"one of {', '.join(sorted(known))}"
    if what == "key":
        return InputError(source, f"{where}.{name}" if where else name,
                          f"unknown key{hint}", expected)
    return InputError(source, where, f"unknown {what} '{name}'{hint}", expected)


def range_text(ge: float | None, gt: float | None, le: float | None, lt: float | None) -> str:
    """Human text of an interval, e.g. ``"a number in (0, 1000]"`` or ``"a number >= 0"``."""
    lo = (f"[{ge:g}" if ge is not None else f"({gt:g}" if gt is not None else None)
    hi = (f"{le:g}]" if le is not None else f"{lt:g})" if lt is not None else None)
    if lo and hi:
        return f"a number in {lo}, {hi}"
    if lo:
        return f"a number {'>=' if ge is not None else '>'} {lo[1:]}"
    if hi:
        return f"a number {'<=' if le is not None else '<'} {hi[:-1]}"
    return "a finite number"


def check_range(values: FloatArray, ge: float | None = None, gt: float | None = None,
                le: float | None = None, lt: float | None = None) -> int | None:
    """Index (flat) of the first value outside the range or not finite, else None."""
    v = np.asarray(values, dtype=float).ravel()
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(v)
        if ge is None and gt is None and le is None and lt is None:
            bad |= np.abs(v) > MAX_ABS
        if ge is not None:
            bad |= v < ge
        if gt is not None:
            bad |= v <= gt
        if le is not None:
            bad |= v > le
        if lt is not None:
            bad |= v >= lt
    idx = np.flatnonzero(bad)
    return int(idx[0]) if idx.size else None


def _short(exc: BaseException) -> str:
    return " ".join(str(exc).split())[:200]


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def _fmt(v: Any) -> str:
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


class Table:
    """Typed access to one TOML table; errors name the file and the dotted key.

    Args:
        source: File (or option) the table came from, for messages.
        data: The parsed table.
        keys: Every key the table may hold; any other key is rejected with a "did you mean".
        prefix: Dotted path of this table (``"joints."``), for messages.
        what: Word for a key in messages (``"key"`` for files, ``"option"`` for ``--set``).

    Raises:
        InputError: ``data`` is not a table, or it holds a key not in ``keys``.
    """

    def __init__(self, source: str | Path, data: Any, keys: Collection[str], prefix: str = "",
                 what: str = "key") -> None:
        self.source = source
        self.prefix = prefix
        self.what = what
        if not isinstance(data, dict):
            raise InputError(source, prefix.rstrip(".") or "<top>", f"got {_fmt(data)}",
                             "a table")
        self.data: dict[str, Any] = data
        self.keys = frozenset(keys)
        for k in data:
            if k not in self.keys:
                raise unknown_name_error(source, prefix.rstrip("."), k, self.keys, what)

    @classmethod
    def load(cls, path: Path, keys: Collection[str]) -> Table:
        """The top-level table of a TOML file (see :func:`read_toml`)."""
        return cls(path, read_toml(path), keys)

    # -- helpers ----------------------------------------------------------------------------
    def key(self, k: str) -> str:
        """Dotted name of key ``k`` for messages."""
        return f"{self.prefix}{k}"

    def has(self, k: str) -> bool:
        """True if the table holds ``k``."""
        return k in self.data

    def error(self, k: str, problem: str, expected: str = "") -> InputError:
        """An :class:`InputError` about key ``k`` of this table."""
        return InputError(self.source, self.key(k), problem, expected)

    def _get(self, k: str, default: Any, expected: str) -> Any:
        assert k in self.keys, f"reader asks for undeclared key {k!r}"
        if k in self.data:
            return self.data[k]
        if default is None:
            raise self.error(k, "missing", expected)
        return default

    # -- scalars ----------------------------------------------------------------------------
    def num(self, k: str, default: float | None = None, *, ge: float | None = None,
            gt: float | None = None, le: float | None = None, lt: float | None = None) -> float:
        """A finite number inside the range (file units); ``default`` if absent."""
        expected = range_text(ge, gt, le, lt)
        v = self._get(k, default, expected)
        if not _is_number(v):
            raise self.error(k, f"got {_fmt(v)}", expected)
        if check_range(np.array([float(v)]), ge, gt, le, lt) is not None:
            raise self.error(k, f"got {float(v):g}", expected)
        return float(v)

    def fraction(self, k: str, default: float | None = None, *, le: float = 1.0,
                 le_percent: float | None = None) -> float:
        """A relative amount as a fraction: the number ``0.2`` or the string ``"20 %"``;
        ``default`` if absent. A number above ``le`` is refused with the fix, as the CLI's
        percent options do: ``force_uncertainty = 10`` is never read as +-1000 %.

        Args:
            le: Largest number (a fraction) accepted.
            le_percent: Largest percentage accepted as a string (default ``100 * le``).
        """
        top = 100.0 * le if le_percent is None else le_percent
        expected = f"a fraction in [0, {le:g}] or a percentage \"0 %\" .. \"{top:g} %\""
        v = self._get(k, default, expected)
        if isinstance(v, str):
            text = v.strip()
            try:
                pct = float(text.removesuffix("%").strip()) if text.endswith("%") else None
            except ValueError:
                pct = None
            if pct is None or not math.isfinite(pct):
                raise self.error(k, f"got {_fmt(v)}", expected)
            if not 0.0 <= pct <= top:
                raise self.error(k, f"got {pct:g} %", expected)
            return pct / 100.0
        if not _is_number(v) or not math.isfinite(float(v)):
            raise self.error(k, f"got {_fmt(v)}", expected)
        f = float(v)
        if f > le and f <= 100.0 * max(top, 100.0):
            raise self.error(k, f"got {f:g}, a fraction above {le:g} (+-{100 * f:g} %); did "
                                f"you mean {f:g} %?", f"the fraction {f / 100:g} or the string "
                                f"\"{f:g} %\"")
        if not 0.0 <= f <= le:
            raise self.error(k, f"got {f:g}", expected)
        return f

    def int_(self, k: str, default: int | None = None, *, ge: int | None = None,
             le: int | None = None) -> int:
        """An integer inside the range; ``default`` if absent (``2.0`` is accepted as 2)."""
        expected = "an integer" + (f" >= {ge}" if ge is not None else "") + (
            f" <= {le}" if le is not None else "")
        v = self._get(k, default, expected)
        if not _is_number(v) or not math.isfinite(v) or float(v) != int(v):
            raise self.error(k, f"got {_fmt(v)}", expected)
        i = int(v)
        if (ge is not None and i < ge) or (le is not None and i > le):
            raise self.error(k, f"got {i}", expected)
        return i

    def str_(self, k: str, default: str | None = None,
             choices: Collection[str] | None = None) -> str:
        """A string, one of ``choices`` if given; ``default`` if absent."""
        expected = ("one of " + ", ".join(f"'{c}'" for c in choices)) if choices else "a string"
        v = self._get(k, default, expected)
        if not isinstance(v, str):
            raise self.error(k, f"got {_fmt(v)}", expected)
        if choices is not None and v not in choices:
            raise self.error(k, f"got '{v}'{suggest(v, choices)}", expected)
        return v

    def bool_(self, k: str, default: bool | None = None) -> bool:
        """``true`` or ``false``; ``default`` if absent."""
        v = self._get(k, default, "true or false")
        if not isinstance(v, bool):
            raise self.error(k, f"got {_fmt(v)}", "true or false")
        return v

    # -- arrays -----------------------------------------------------------------------------
    def vec(self, k: str, n: int | None = None, default: Iterable[float] | None = None, *,
            ge: float | None = None, gt: float | None = None, le: float | None = None,
            lt: float | None = None, min_len: int = 1, item: str = "value") -> FloatArray:
        """A list of ``n`` (any number >= ``min_len`` if None) finite numbers in the range.

        ``item`` names an entry in messages (``"joint"``: "joint 3 is -5").
        """
        count = f"{n}" if n is not None else f"at least {min_len}"
        expected = f"a list of {count} numbers"
        v = self._get(k, None if default is None else list(default), expected)
        if not isinstance(v, list) or not all(_is_number(x) for x in v):
            raise self.error(k, f"got {_fmt(v)}", expected)
        if (n is not None and len(v) != n) or len(v) < min_len:
            raise self.error(k, f"has {len(v)} values", expected)
        arr = np.array([float(x) for x in v], dtype=float)
        self._check(k, arr, ge, gt, le, lt, item)
        return arr

    def matrix(self, k: str, rows: int | None, cols: int, default: Any = None, *,
               ge: float | None = None, gt: float | None = None, le: float | None = None,
               lt: float | None = None, min_rows: int = 1) -> FloatArray:
        """A list of ``rows`` (any number >= ``min_rows`` if None) rows of ``cols`` numbers."""
        shape = f"{rows if rows is not None else f'at least {min_rows}'} rows of {cols} numbers"
        v = self._get(k, default, shape)
        if not isinstance(v, list) or not all(
            isinstance(r, list) and all(_is_number(x) for x in r) for r in v
        ):
            raise self.error(k, f"got {_fmt(v)}", shape)
        if (rows is not None and len(v) != rows) or len(v) < min_rows:
            raise self.error(k, f"has {len(v)} row(s)", shape)
        for i, r in enumerate(v):
            if len(r) != cols:
                raise self.error(k, f"row {i + 1} has {len(r)} values", shape)
        arr = np.array([[float(x) for x in r] for r in v], dtype=float).reshape(len(v), cols)
        self._check(k, arr, ge, gt, le, lt)
        return arr

    def _check(self, k: str, arr: FloatArray, ge: float | None, gt: float | None,
               le: float | None, lt: float | None, item: str = "value") -> None:
        i = check_range(arr, ge, gt, le, lt)
        if i is None:
            return
        flat = arr.ravel()
        pos = (f"{item} {i + 1}" if arr.ndim == 1 else
               f"row {i // arr.shape[1] + 1}, value {i % arr.shape[1] + 1}")
        what = "is NaN or infinity" if not math.isfinite(flat[i]) else f"is {flat[i]:g}"
        raise self.error(k, f"{pos} {what}", range_text(ge, gt, le, lt))

    # -- sub-tables -------------------------------------------------------------------------
    def table(self, k: str, keys: Collection[str], required: bool = False) -> Table | None:
        """The sub-table ``[prefix.k]`` with its allowed keys, or None if absent."""
        assert k in self.keys, f"reader asks for undeclared table {k!r}"
        if k not in self.data:
            if required:
                raise self.error(k, "missing table", f"a [{self.key(k)}] table")
            return None
        return Table(self.source, self.data[k], keys, f"{self.key(k)}.", self.what)

    def tables(self, k: str, keys: Collection[str]) -> list[Table]:
        """The entries of an array of tables ``[[prefix.k]]`` (empty if absent)."""
        assert k in self.keys, f"reader asks for undeclared table {k!r}"
        v = self.data.get(k, [])
        if not isinstance(v, list):
            raise self.error(k, f"got {_fmt(v)}", f"[[{self.key(k)}]] entries")
        return [Table(self.source, e, keys, f"{self.key(k)}[{i + 1}].", self.what)
                for i, e in enumerate(v)]

    def mapping(self, k: str, *, ge: float | None = None, gt: float | None = None,
                le: float | None = None, lt: float | None = None) -> dict[str, float]:
        """An inline table of names to finite numbers (keys checked by the caller)."""
        v = self._get(k, {}, "a table of name = number")
        if not isinstance(v, Mapping):
            raise self.error(k, f"got {_fmt(v)}", "a table of name = number")
        out: dict[str, float] = {}
        for name, x in v.items():
            if not _is_number(x) or check_range(np.array([float(x)]), ge, gt, le, lt) is not None:
                raise InputError(self.source, f"{self.key(k)}.{name}", f"got {_fmt(x)}",
                                 range_text(ge, gt, le, lt))
            out[str(name)] = float(x)
        return out


__all__ = ["MAX_ABS", "Table", "check_range", "range_text", "read_toml", "suggest",
           "unknown_name_error"]
