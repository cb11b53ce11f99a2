"""Column tables from CSV files: dialect detection, strict cells, and named quantities.

One helper for every CSV reader of measured data (:mod:`rfsw_plan.io.measurements`,
:mod:`rfsw_plan.io.force_series`):

* :func:`read_table` reads the file once, detects the delimiter (``,`` ``;`` or tab) and the
  decimal separator (point, or comma as a German spreadsheet writes it), rejects duplicated
  column names and over-long cells, and says what it detected (:attr:`Table.dialect`);
* :class:`Quantity` names a physical quantity with the units a file may give it in (``fz`` in
  ``N`` or ``kN``); :meth:`Table.find` finds its column by the ``<quantity>_<unit>`` naming rule
  or through a lab's own mapping (:class:`ColumnMap`, a ``--columns FILE.toml``), and
  :meth:`Table.numbers` returns it in SI units;
* a missing column gets a rename hint only from a column that holds the same quantity (``fz``
  or ``fz_kN`` for ``fz_N``), never from a merely similar spelling (``fy_N``).
"""

from __future__ import annotations

import csv
import io
import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.exceptions import InputError

FloatArray = NDArray[np.float64]

#: Largest magnitude accepted in any numeric cell. Nothing a robot cell measures comes near it
#: in any unit; a 1e300 would overflow the least-squares algebra downstream.
MAX_MAGNITUDE = 1e12
#: Longest cell accepted [characters] (the csv module's own limit is 131,072).
MAX_CELL = 10_000
DELIMITERS = (",", ";", "\t")
_DECIMAL_COMMA = re.compile(r"^[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?$")
_NAMES = {",": "comma", ";": "semicolon", "\t": "tab"}


@dataclass(frozen=True)
class Quantity:
    """A physical quantity a column may hold.

    Attributes:
        key: Quantity name, the column name before the unit (``fz``, ``q3``, ``x``).
        units: Accepted units and their factor to SI, e.g. ``{"N": 1.0, "kN": 1e3}``; an empty
            string means a unit-less column (``pose_id``, ``quat_w``).
        text: True if the column holds text (labels), not numbers.
    """

    key: str
    units: Mapping[str, float]
    text: bool = False

    def names(self) -> list[str]:
        """Column names that hold this quantity under the naming rule."""
        return [self.key if u == "" else f"{self.key}_{u}" for u in self.units]

    def default(self) -> str:
        """The canonical column name (first unit)."""
        return self.names()[0]


@dataclass(frozen=True)
class ColumnMap:
    """A lab's own column names and units (``--columns FILE.toml``).

    File format::

        frame = "device"                        # optional: positions in the device frame
        [columns]
        q1 = { name = "torso_lift_joint", unit = "m" }
        x = { name = "x1", unit = "m" }

    Attributes:
        columns: Quantity key -> (column name in the file, unit).
        options: Other top-level keys (``frame``, ``wrench_frame``, ...), validated by the
            reader that uses them.
        source: The mapping file.
    """

    columns: Mapping[str, tuple[str, str]]
    options: Mapping[str, Any] = field(default_factory=dict)
    source: str = "<memory>"


def read_column_map(path: str | Path, allowed_options: Mapping[str, str]) -> ColumnMap:
    """Read a column mapping TOML (format in :class:`ColumnMap`).

    Args:
        path: The TOML file.
        allowed_options: Top-level keys besides ``[columns]`` and what each expects.

    Raises:
        InputError: Unreadable file, unknown key, entry without name or unit.
    """
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(p, "", f"cannot read file: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(p, "", f"not valid TOML: {exc}") from None
    cols = data.get("columns")
    if not isinstance(cols, dict) or not cols:
        raise InputError(p, "[columns]", "missing or empty table",
                         "quantity = { name = 'column in the file', unit = '...' }")
    out = {key: _column_entry(p, key, entry) for key, entry in cols.items()}
    used = [v[0] for v in out.values()]
    dup = sorted({n for n in used if used.count(n) > 1})
    if dup:
        raise InputError(p, "[columns]", f"column '{dup[0]}' is mapped twice",
                         "each file column mapped to one quantity")
    options: dict[str, Any] = {}
    for key, value in data.items():
        if key == "columns":
            continue
        if key not in allowed_options:
            known = ", ".join(["columns", *allowed_options])
            raise InputError(p, key, "unknown key", known)
        options[key] = value
    return ColumnMap(out, options, str(p))


def _column_entry(p: Path, key: str, entry: Any) -> tuple[str, str]:
    """(column name, unit) of one ``[columns]`` entry of a column map (:class:`ColumnMap`),
    checked; ``column = N`` names column N of a MATLAB array (:func:`array_column`)."""
    if (not isinstance(entry, dict) or set(entry) - {"name", "unit", "column"}
            or "name" not in entry):
        raise InputError(p, f"columns.{key}", f"got {entry!r}",
                         "{ name = 'column in the file', unit = '...' } (and column = N "
                         "for column N of a MATLAB array)")
    name, unit = entry["name"], entry.get("unit", "")
    if not isinstance(name, str) or not isinstance(unit, str) or not name.strip():
        raise InputError(p, f"columns.{key}", f"got {entry!r}", "name and unit as strings")
    name = name.strip()
    if "column" in entry:
        col = entry["column"]
        if isinstance(col, bool) or not isinstance(col, int) or col < 1:
            raise InputError(p, f"columns.{key}.column", f"got {col!r}",
                             "a column number of the array, 1 or more")
        name = array_column(name, col)
    return name, unit.strip()


@dataclass(frozen=True)
class Table:
    """A CSV file read into cells.

    Attributes:
        path: The file.
        header: Column names (stripped), unique.
        rows: Data rows (cells stripped), blank rows removed; ``row_numbers`` gives each one's
            1-based line in the file.
        row_numbers: File row of every data row (header = row 1 when it is the first line).
        delimiter: Detected delimiter.
        decimal: Detected decimal separator, ``.`` or ``,``.
        mapping: The lab's column mapping, if one was given.
    """

    path: Path
    header: list[str]
    rows: list[list[str]]
    row_numbers: list[int]
    delimiter: str
    decimal: str
    mapping: ColumnMap | None = None

    @property
    def dialect(self) -> str:
        """What was detected, e.g. ``"semicolon-separated, decimal comma"``."""
        if self.path.suffix.lower() == ".mat":
            return "MATLAB file"
        return (f"{_NAMES[self.delimiter]}-separated, "
                f"decimal {'comma' if self.decimal == ',' else 'point'}")

    def __len__(self) -> int:
        return len(self.rows)

    # -- columns ------------------------------------------------------------------------------
    def find(self, q: Quantity) -> tuple[str, float] | None:
        """Column holding quantity ``q`` and its factor to SI, or None if absent.

        Raises:
            InputError: Two columns give the same quantity (``q1_deg`` and ``q1_rad``), or the
                mapping names a column the file lacks or a unit the quantity cannot have.
        """
        if self.mapping is not None and q.key in self.mapping.columns:
            name, unit = self.mapping.columns[q.key]
            if unit not in q.units:
                raise InputError(self.mapping.source, f"columns.{q.key}", f"unit '{unit}'",
                                 " | ".join(repr(u) for u in q.units))
            if name not in self.header:
                raise InputError(self.path, f"column '{name}'",
                                 f"missing (mapped to {q.key} by {self.mapping.source})",
                                 _close_hint(name, self.header))
            return name, q.units[unit]
        hits = [n for n in q.names() if n in self.header]
        if len(hits) > 1:
            raise InputError(self.path, "header", f"columns {' and '.join(hits)} both give "
                             f"{q.key}", "one column per quantity")
        if not hits:
            return None
        unit = hits[0][len(q.key) + 1:] if hits[0] != q.key else ""
        return hits[0], q.units[unit]

    def missing(self, q: Quantity) -> InputError:
        """Error for a missing quantity, with a hint at a column of the *same* quantity.

        A header that is the quantity without its unit (``fz``), with another unit
        (``fz_kN``) or in other letter case (``FZ_N``) is offered; a merely similar
        spelling of another quantity (``fy_N`` for ``fz_N``) never is.
        """
        want = q.default()
        same = [h for h in self.header if _quantity_of(h) == q.key.lower()]
        hint = ""
        if same:
            units = ", ".join(u if u else "(none)" for u in q.units)
            hint = (f"; found '{same[0]}': rename it to '{want}' if it holds {q.key} "
                    f"(units in the column name: {units}), or map it with `columns`")
        return InputError(self.path, f"column '{want}'", f"missing{hint}",
                          f"a column named {' or '.join(repr(n) for n in q.names())}")

    def numbers(self, name: str, factor: float = 1.0, allow_blank: bool = False) -> FloatArray:
        """Numeric column ``name`` times ``factor`` (to SI), shape (rows,).

        Raises:
            InputError: A cell that is not a finite number of at most :data:`MAX_MAGNITUDE`
                (row and column named); a blank cell unless ``allow_blank`` (then NaN).
        """
        i = self.header.index(name)
        out = np.empty(len(self.rows))
        for r, row in enumerate(self.rows):
            cell = row[i] if i < len(row) else ""
            where = f"row {self.row_numbers[r]}, column '{name}'"
            if cell == "":
                if allow_blank:
                    out[r] = math.nan
                    continue
                raise InputError(self.path, where, "blank cell", "a number")
            text = cell.replace(",", ".") if self.decimal == "," else cell
            try:
                v = float(text)
            except ValueError:
                raise InputError(self.path, where, f"'{_short(cell)}' is not a number") from None
            if not math.isfinite(v):
                raise InputError(self.path, where, f"value is {_short(cell)}",
                                 "a finite number (leave position cells blank if not measured)")
            if abs(v) > MAX_MAGNITUDE:
                raise InputError(self.path, where, f"value {v:.3g} is out of range",
                                 f"|value| <= {MAX_MAGNITUDE:g} in any unit")
            out[r] = v * factor
        return out

    def texts(self, name: str) -> NDArray[np.str_]:
        """Text column ``name``, shape (rows,)."""
        i = self.header.index(name)
        return np.array([row[i] if i < len(row) else "" for row in self.rows])


def refuse_near_misses(tab: Table, known: list[Quantity], allowed: set[str]) -> None:
    """Refuse a column that names a known quantity in a spelling the naming rule does not
    accept (``x__mm``, ``Z_MM``, ``fz_N ``, ``fz_kg``), instead of silently ignoring it.

    Args:
        tab: The table.
        known: The quantities the reader understands.
        allowed: Column names the reader takes (matched ones, text columns...).

    Raises:
        InputError: Names the column, the quantity it looks like and its accepted names.
    """
    for h in tab.header:
        if h in allowed:
            continue
        norm = re.sub(r"_+", "_", re.sub(r"[\s\[\]()]+", "_", h.lower())).strip("_")
        q = next((q for q in known if norm == q.key.lower()
                  or norm in (n.lower() for n in q.names())
                  or re.fullmatch(rf"{re.escape(q.key.lower())}_[a-z]{{1,4}}", norm)), None)
        if q is None:
            continue
        raise InputError(tab.path, f"column '{h}'", f"looks like {q.key} but is not one of its "
                         "names, so it would be ignored",
                         f"{' or '.join(repr(n) for n in q.names())} (units in the name), or "
                         "map it with `columns`")


def refuse_group_near_misses(tab: Table, groups: list[tuple[Quantity, ...]],
                             allowed: set[str]) -> None:
    """Refuse a column that stands for the missing member of a group whose other members are
    there: ``ym_m`` beside ``x_mm`` and ``z_mm`` (a renamed position axis), which would
    otherwise be kept as an extra column while that axis silently goes unmeasured.

    A column is taken for the missing member when its unit is one the member accepts and its
    name before the unit is one edit (a letter added, dropped or changed) from the member's.

    Raises:
        InputError: Names the column, the member it looks like and the members present.
    """
    for group in groups:
        present = [q for q in group if tab.find(q) is not None]
        if not present or len(present) == len(group):
            continue
        for q in group:
            if q in present:
                continue
            for h in tab.header:
                if h in allowed:
                    continue
                stem, _, unit = h.strip().rpartition("_")
                if unit not in q.units or not stem or not _one_edit(stem.lower(), q.key):
                    continue
                raise InputError(tab.path, f"column '{h}'", f"looks like {q.key}, which is "
                                 f"missing while {', '.join(p.key for p in present)} "
                                 "are given; it would be ignored",
                                 f"{' or '.join(repr(n) for n in q.names())}, or map it with "
                                 "`columns`")


def _one_edit(a: str, b: str) -> bool:
    """``a`` and ``b`` differ by one inserted, deleted or changed character."""
    if a == b or abs(len(a) - len(b)) > 1:
        return False
    if len(a) == len(b):
        return sum(x != y for x, y in zip(a, b, strict=True)) == 1
    short, long_ = (a, b) if len(a) < len(b) else (b, a)
    return any(long_[:i] + long_[i + 1:] == short for i in range(len(long_)))


def _quantity_of(header: str) -> str:
    """The quantity part of a column name: lower case, before the unit or a bracket."""
    h = header.strip().lower()
    h = re.split(r"[\s\[\(]", h, maxsplit=1)[0]
    return h.split("_", 1)[0] if re.match(r"^[a-z]+\d*_", h) else h


def _close_hint(name: str, header: list[str]) -> str:
    same = [h for h in header if h.lower() == name.lower()]
    return f"a column named '{name}'" + (f" (found '{same[0]}')" if same else "")


def _short(cell: str) -> str:
    return cell if len(cell) <= 40 else cell[:37] + "..."


def _detect_delimiter(line: str) -> str:
    counts = {d: line.count(d) for d in DELIMITERS}
    best = max(DELIMITERS, key=lambda d: counts[d])
    return best if counts[best] > 0 else ","


def array_column(array: str, column: int) -> str:
    """The table column name of column ``column`` (1-based) of a MATLAB array: ``q[3]``."""
    return f"{array}[{column}]"


def read_table(path: str | Path, mapping: ColumnMap | None = None) -> Table:
    """Read a CSV file with a header row (see module docstring), or a MATLAB ``.mat`` file
    (:func:`read_mat_table`).

    Raises:
        InputError: Unreadable or empty file, no data rows, a duplicated or empty column name,
            a cell longer than :data:`MAX_CELL` characters, a row with more or fewer cells than
            the header, a malformed CSV row.
    """
    p = Path(path)
    if p.suffix.lower() == ".mat":
        return read_mat_table(p, mapping)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(p, "", f"cannot read file: {exc}") from None
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    if not first:
        raise InputError(p, "", "file is empty", "a header row and samples")
    delimiter = _detect_delimiter(first)
    rows, numbers = _rows(p, text, delimiter)
    header = rows[0]
    _check_header(p, header)
    body, body_rows = rows[1:], numbers[1:]
    if not body:
        raise InputError(p, "", "no samples after the header row")
    for row, line in zip(body, body_rows, strict=True):
        if len(row) != len(header):
            # A cell too few or too many shifts every value after it into the wrong column.
            raise InputError(p, f"row {line}", f"{len(row)} cells, the header has "
                             f"{len(header)} ({_NAMES[delimiter]}-separated)",
                             f"{len(header)} cells per row (an empty cell for no value)")
    decimal = "."
    if delimiter != "," and any(_DECIMAL_COMMA.match(c) for row in body for c in row):
        decimal = ","
    return Table(p, header, body, body_rows, delimiter, decimal, mapping)


def _rows(p: Path, text: str, delimiter: str) -> tuple[list[list[str]], list[int]]:
    """The non-blank rows (cells stripped) and their line numbers."""
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter)
    rows: list[list[str]] = []
    numbers: list[int] = []
    try:
        for row in reader:
            if any(len(c) > MAX_CELL for c in row):
                raise csv.Error("field larger than field limit")
            if any(c.strip() for c in row):
                rows.append([c.strip() for c in row])
                numbers.append(reader.line_num)
    except csv.Error as exc:
        if "field larger than field limit" in str(exc):
            raise InputError(p, f"row {reader.line_num}", "a cell is longer than "
                             f"{MAX_CELL} characters", "short numeric cells") from None
        raise InputError(p, f"row {reader.line_num}", f"malformed CSV: {exc}") from None
    return rows, numbers


def _check_header(p: Path, header: list[str]) -> None:
    seen: set[str] = set()
    for k, h in enumerate(header):
        if h == "":
            raise InputError(p, f"header, column {k + 1}", "empty column name", "a name")
        if h in seen:
            raise InputError(p, "header", f"column '{h}' appears twice",
                             "each column name once")
        seen.add(h)


def read_mat_table(path: str | Path, mapping: ColumnMap | None) -> Table:
    """Read the arrays of a MATLAB (v4 to v7.2) file that ``mapping`` names, as a table.

    A MATLAB file has no column names, so nothing is guessed: every quantity is declared in
    the column map as ``{ name = "ARRAY", column = N, unit = "..." }`` (column N, 1-based, of
    the 2-D numeric array ARRAY, one sample per array row), or ``{ name = "ARRAY" }`` for a
    one-column array. The table's columns are named ``ARRAY[N]`` (:func:`array_column`) and
    its rows are the array rows (``row 1`` is the first sample). Arrays the map does not name
    are not read.

    Raises:
        InputError: No column map, an unreadable file, a named array that is missing, not
            numeric or not 2-D, a column beyond the array's, mapped arrays of different row
            counts.
    """
    import scipy.io

    p = Path(path)
    if mapping is None:
        raise InputError(p, "", "a MATLAB file has no column names",
                         "a column map (`columns` FILE.toml) naming each quantity's array "
                         "and column")
    try:
        arrays = scipy.io.loadmat(str(p))
    except (OSError, ValueError, NotImplementedError, TypeError) as exc:
        raise InputError(p, "", f"cannot read MATLAB file: {exc}",
                         "a MATLAB v4-v7.2 .mat file (v7.3/HDF5 is not read)") from None
    wanted: dict[str, list[int]] = {}
    for key, (name, _unit) in mapping.columns.items():
        array, col = _mapped_array_column(p, arrays, mapping, key, name)
        wanted.setdefault(array, []).append(col)
    n_rows = {a: int(arrays[a].shape[0]) for a in wanted}
    if len(set(n_rows.values())) > 1:
        a, b = sorted(n_rows, key=lambda k: n_rows[k])[0], max(n_rows, key=lambda k: n_rows[k])
        raise InputError(p, f"array '{a}'", f"{n_rows[a]} rows but array '{b}' has {n_rows[b]}",
                         "one sample per row in every mapped array")
    m_rows = next(iter(n_rows.values()))
    if m_rows == 0:
        raise InputError(p, "", "no samples in the mapped arrays")
    header: list[str] = []
    columns: list[FloatArray] = []
    for array, cols in wanted.items():
        for col in sorted(set(cols)):
            header.append(array if col == 0 else array_column(array, col))
            columns.append(np.asarray(arrays[array][:, max(col, 1) - 1], dtype=float))
    # repr() round-trips every float exactly, so the strict cell checks apply unchanged.
    rows = [[repr(float(c[i])) for c in columns] for i in range(m_rows)]
    return Table(p, header, rows, list(range(1, m_rows + 1)), ",", ".", mapping)


def _mapped_array_column(p: Path, arrays: Mapping[str, Any], mapping: ColumnMap, key: str,
                         name: str) -> tuple[str, int]:
    """The array and 1-based column (0: a one-column array) a column-map entry names in a
    MATLAB file's arrays, checked (see :func:`read_mat_table`)."""
    m = re.fullmatch(r"(.+)\[(\d+)\]", name)
    array, col = (m.group(1), int(m.group(2))) if m else (name, 0)
    value = arrays.get(array)
    where = f"array '{array}' (columns.{key} of {mapping.source})"
    if value is None:
        known = sorted(k for k in arrays if not k.startswith("__"))
        raise InputError(p, where, "missing", f"one of {', '.join(known) or 'no arrays'}")
    if not isinstance(value, np.ndarray) or value.ndim != 2 or value.dtype.kind not in "iuf":
        raise InputError(p, where, f"not a 2-D numeric array ({getattr(value, 'shape', '')})",
                         "a numeric matrix with one sample per row")
    if col == 0 and value.shape[1] != 1:
        raise InputError(mapping.source, f"columns.{key}", f"array '{array}' has "
                         f"{value.shape[1]} columns", "column = N to say which one")
    if col > value.shape[1]:
        raise InputError(mapping.source, f"columns.{key}.column", f"{col} but array "
                         f"'{array}' has {value.shape[1]} columns", f"1 .. {value.shape[1]}")
    return array, col
