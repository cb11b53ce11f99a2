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

__all__ = ["angle", "canonical_quaternion", "cell", "cell_many", "fixed", "fixed_many", "general",
           "shortest"]

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
    faster for long arrays (pages that carry 10^5 numbers): the same text for every finite
    number; NaN becomes ``None`` (the caller writes its "no value"), infinity is refused.

    Raises:
        ValueError: A value is infinite.
    """
    import numpy as np

    flat = np.asarray(values, dtype=float).ravel()
    if np.isinf(flat).any():
        raise ValueError("cannot write an infinite number as text")
    fmt = f"{{:.{digits}f}}".format
    zero = fmt(0.0)
    minus_zero = "-" + zero
    out: list[str] = []
    for v in flat.tolist():
        if v != v:  # NaN
            out.append(None)  # type: ignore[arg-type]
            continue
        t = fmt(v)
        out.append(zero if t == minus_zero else t)
    return out


def cell_many(values: Any, digits: int = 6) -> list[str]:
    """:func:`cell` of every number of ``values`` (any array-like, flattened): the same text,
    many times faster for the columns of a long table (an empty cell for NaN and +-inf)."""
    import numpy as np

    fmt = f"{{:.{digits}f}}".format
    zero = fmt(0.0)
    minus_zero = "-" + zero
    out: list[str] = []
    for v in np.asarray(values, dtype=float).ravel().tolist():
        if v - v != 0.0:  # NaN or +-inf (inf - inf is NaN)
            out.append("")
            continue
        t = fmt(v)
        out.append(zero if t == minus_zero else t)
    return out
