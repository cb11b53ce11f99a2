"""Numbers as text, the same bytes on every machine: the one formatter of every file writer.

A value that is zero in exact arithmetic comes out of a floating-point computation as ``+1e-17``
on one machine and ``-1e-17`` on another (another BLAS, another summation order, another CPU's
fused multiply-add). Printed with a fixed number of decimals both are zero, but Python prints
the second as ``-0.0000``: a written plan, a controller program or a golden file would then
differ between machines although the numbers are the same. Every writer therefore formats
through :func:`fixed` (or :func:`cell` for table cells, :func:`general` for ``%g``-style text,
:func:`shortest` for a number kept exactly):

* the text is Python's own correctly rounded conversion (the same on every platform, unlike
  C ``printf`` or NumPy's ``str``), and
* a text that rounds to zero never carries a sign (``-0.0000`` -> ``0.0000``, ``-0`` -> ``0``).

Non-finite numbers are never written as ``nan`` or ``inf``: :func:`fixed` and :func:`general`
refuse them (``ValueError``, a bug in the writer), :func:`cell` writes an empty cell, the
documented "no value" of every CSV this package reads.
"""

from __future__ import annotations

import math
import re
from typing import Any, SupportsFloat

__all__ = ["angle", "canonical_quaternion", "cell", "cell_many", "fixed", "fixed_codes",
           "fixed_many", "fixed_texts", "general", "shortest", "table_bytes"]

_NONZERO = frozenset("123456789")
_MINUS_180 = re.compile(r"-180(\.0*)?")


def _unsigned_zero(text: str) -> str:
    """``text`` without its minus sign if every digit is 0 (``-0.000``, ``-0``, ``-0e+00``)."""
    if text.startswith("-"):
        mantissa = text[1:].split("e", 1)[0].split("E", 1)[0]
        if not _NONZERO.intersection(mantissa):
            return text[1:]
    return text


def _finite(x: SupportsFloat) -> float:
    v = float(x)
    if not math.isfinite(v):
        raise ValueError(f"cannot write the non-finite number {v!r} as text")
    return v


def fixed(x: SupportsFloat, digits: int) -> str:
    """``x`` with ``digits`` decimals (``f"{x:.{digits}f}"``), never ``-0.000``.

    Args:
        x: A finite number (Python or NumPy float or int).
        digits: Decimals after the point, >= 0.

    Raises:
        ValueError: ``x`` is NaN or infinite.
    """
    return _unsigned_zero(f"{_finite(x):.{digits}f}")


def shortest(x: SupportsFloat) -> str:
    """``x`` as the shortest text that reads back as the same float (``repr``: ``0.1``,
    ``2e-07``, ``1.0``), never ``-0.0``: for files that keep a number exactly (robot and
    problem TOML)."""
    return _unsigned_zero(repr(_finite(x)))


def general(x: SupportsFloat, significant: int = 6) -> str:
    """``x`` with ``significant`` significant digits (``f"{x:.{significant}g}"``), never ``-0``.

    Raises:
        ValueError: ``x`` is NaN or infinite.
    """
    return _unsigned_zero(f"{_finite(x):.{significant}g}")


def cell(x: SupportsFloat | None, digits: int = 6) -> str:
    """A CSV cell: :func:`fixed`, or an empty cell for None, NaN or +-inf ("no value")."""
    if x is None:
        return ""
    v = float(x)
    return fixed(v, digits) if math.isfinite(v) else ""


def angle(x: SupportsFloat, digits: int) -> str:
    """An Euler angle [deg] in (-180, 180] with ``digits`` decimals: :func:`fixed`, with the two
    texts of the branch cut made one (``-180.000`` -> ``180.000``; ``atan2(-0.0, -1)`` is
    -180 deg and ``atan2(+0.0, -1)`` +180 deg, the same orientation).

    Raises:
        ValueError: ``x`` is NaN or infinite.
    """
    text = fixed(x, digits)
    return text[1:] if _MINUS_180.fullmatch(text) else text


def canonical_quaternion(q: Any) -> Any:
    """A unit quaternion (w, x, y, z) with the sign a machine's rounding cannot flip: the first
    component that is not float noise (|c| > 1e-12) is positive (q and -q are one rotation).

    Args:
        q: Quaternion, shape (4,) or (m, 4); returned as a NumPy array of the same shape.
    """
    import numpy as np

    a = np.array(q, dtype=float)
    flat = np.atleast_2d(a)
    first = np.argmax(np.abs(flat) > 1e-12, axis=1)
    sign = np.where(flat[np.arange(len(flat)), first] < 0, -1.0, 1.0)
    return (flat * sign[:, None]).reshape(a.shape)


def fixed_many(values: Any, digits: int) -> list[str]:
    """:func:`fixed` of every number of ``values`` (any array-like, flattened), many times
    faster for long arrays (pages that carry 10^5 numbers, :func:`fixed_texts`): the same
    text for every finite number; NaN becomes ``None`` (the caller writes its "no value"),
    infinity is refused.

    Raises:
        ValueError: A value is infinite.
    """
    import numpy as np

    flat = np.asarray(values, dtype=float).ravel()
    if np.isinf(flat).any():
        raise ValueError("cannot write an infinite number as text")
    text = fixed_texts(flat, digits).tolist()
    if np.isnan(flat).any():
        for k in np.flatnonzero(np.isnan(flat)).tolist():
            text[k] = None
    return text


def cell_many(values: Any, digits: int = 6) -> list[str]:
    """:func:`cell` of every number of ``values`` (any array-like, flattened): the same text,
    many times faster for the columns of a long table (an empty cell for NaN and +-inf)."""
    return fixed_texts(values, digits).tolist()


#: :func:`fixed_codes` converts with integers where ``|x| 10^digits`` stays below this (exact
#: in a double, and far from the 64-bit integers' end).
_FAST_LIMIT = 2.0 ** 52


def fixed_texts(values: Any, digits: int) -> Any:
    """:func:`fixed` of every number of ``values`` (flattened) as a NumPy string array
    (:func:`fixed_codes`, left-aligned); an empty string for NaN and +-inf."""
    import numpy as np

    codes, start = fixed_codes(values, digits)
    width = codes.shape[1]
    cols = np.minimum(np.arange(width)[None, :] + start[:, None], width)
    padded = np.pad(codes, ((0, 0), (0, 1)))  # column ``width``: NUL
    left = np.take_along_axis(padded, cols, axis=1).astype(np.uint32)
    return np.ascontiguousarray(left).view(f"<U{width}").ravel()


def table_bytes(columns: Any, digits: int, sep: str = ",", end: str = "\r\n") -> bytes:
    """The rows of a table as ASCII text, many times faster than a ``csv.writer`` for long
    tables and byte for byte what it writes (minimal quoting, ``end`` after every row): a
    numeric column's cells as :func:`cell` with ``digits`` decimals (empty for NaN and
    +-inf, :func:`fixed_codes`), a text column's as they are.

    Args:
        columns: The columns, each a float array (numbers) or a sequence of ``str`` (text),
            all of one length.
        digits: Decimals of the numbers.
        sep: The cell separator.
        end: The row terminator.

    Raises:
        ValueError: A text cell is not ASCII or would need quoting (it holds ``sep``, a
            quote or a line break): write that table with the ``csv`` module.
    """
    import numpy as np

    blocks = []
    rows = -1
    for j, col in enumerate(columns):
        if isinstance(col, np.ndarray) and col.dtype.kind in "fiu":
            codes = fixed_codes(col, digits)[0]
        else:
            texts = [str(c) for c in col]
            if any(sep in t or '"' in t or "\r" in t or "\n" in t for t in set(texts)):
                raise ValueError(f"column {j}: a cell needs quoting")
            raw = np.array([t.encode("ascii") for t in texts], dtype=bytes)
            codes = raw.view(np.uint8).reshape(len(texts), raw.dtype.itemsize) if len(texts) \
                else np.zeros((0, 1), dtype=np.uint8)
        if rows >= 0 and len(codes) != rows:
            raise ValueError(f"column {j} has {len(codes)} cells, not {rows}")
        rows = len(codes)
        if j:
            blocks.append(np.full((rows, len(sep)), sep.encode("ascii"), dtype=f"S{len(sep)}")
                          .view(np.uint8).reshape(rows, len(sep)))
        blocks.append(codes)
    if rows <= 0:
        return b""
    blocks.append(np.frombuffer(end.encode("ascii"), dtype=np.uint8)[None, :].repeat(rows, 0))
    flat = np.concatenate(blocks, axis=1).ravel()
    return flat[flat != 0].tobytes()


def fixed_codes(values: Any, digits: int) -> tuple[Any, Any]:
    """:func:`fixed` of every number of ``values`` (flattened) as ASCII codes built with array
    operations, the same text as Python's correctly rounded conversion, digit for digit.

    Returns:
        (codes, start): codes (n, width) uint8, each text right-aligned with NUL (0) before
        it (all NUL for NaN and +-inf: an empty text); start (n,) the column where each text
        begins.

    The value scaled by 10^digits, x = fl(v 10^d), is within |x| 2^-53 of the exact v 10^d,
    so ``rint(x)`` is the correctly rounded integer (half to even on the exact value, as
    Python rounds) unless x's fraction lies that close to one half: those values, and any with
    |x| >= 2^52, are converted by Python itself. A text that rounds to zero has no sign.

    Args:
        values: Numbers (any array-like).
        digits: Decimals after the point, 0..15.
    """
    import numpy as np

    if not 0 <= digits <= 15:
        raise ValueError(f"digits must be in 0..15, got {digits}")
    v = np.asarray(values, dtype=float).ravel()
    m = len(v)
    finite = np.isfinite(v)
    x = v * float(10 ** digits)
    with np.errstate(invalid="ignore"):
        half = np.abs(np.abs(x - np.floor(x)) - 0.5)
        fast = finite & (np.abs(x) < _FAST_LIMIT) & (half > np.abs(x) * 2.0 ** -50 + 1e-12)
    n = np.rint(np.where(fast, x, 0.0)).astype(np.int64)
    mag = np.abs(n)
    scale = np.int64(10 ** digits)
    whole = mag // scale
    frac = mag - whole * scale
    top = int(whole.max(initial=0))
    places = len(str(top))
    width = 1 + places + (1 + digits if digits else 0)
    codes = np.zeros((m, width), dtype=np.uint8)
    rest = frac
    for col in range(width - 1, places + 1, -1):  # the decimals, right to left
        rest, d = np.divmod(rest, 10)
        codes[:, col] = d + 48
    if digits:
        codes[:, places + 1] = ord(".")
    rest = whole
    ndig = np.ones(m, dtype=np.int64)
    for k, col in enumerate(range(places, 0, -1)):  # the whole part, right to left
        rest, d = np.divmod(rest, 10)
        written = (rest > 0) | (d > 0) if k else np.ones(m, dtype=bool)
        codes[:, col] = np.where(written, d + 48, 0)
        ndig += (rest > 0) & (k < places - 1)
    start = places + 1 - ndig
    neg = n < 0
    start[neg] -= 1
    codes[neg, start[neg]] = ord("-")
    codes[~finite] = 0
    start[~finite] = width
    slow = np.flatnonzero(finite & ~fast)
    if len(slow):
        texts = {k: fixed(float(v[k]), digits) for k in slow.tolist()}
        extra = max(0, *(len(t) - width for t in texts.values()))
        codes = np.pad(codes, ((0, 0), (extra, 0)))
        start += extra
        width += extra
        for k, t in texts.items():
            codes[k] = 0
            codes[k, width - len(t):] = np.frombuffer(t.encode("ascii"), dtype=np.uint8)
            start[k] = width - len(t)
    return codes, start
