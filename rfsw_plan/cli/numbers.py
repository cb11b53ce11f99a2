"""Numbers on the command line: parsed and range-checked by argparse, before any heavy import.

Every numeric option of ``rfsw-plan`` is declared with one of these ``type=`` callables. A value
that is not a finite number, or lies outside the option's range, is refused by the parser with
one line (``rfsw-plan deviation: error: argument --dt: 1e-09 s is below 1e-06 s ...``, exit 2)
before the command module runs, so before NumPy, SciPy, CasADi or Pinocchio are imported and
before anything is allocated. The ranges come from the physics where it gives one (a controller
cycle of 0.1-1000 ms, a force a robot cell can apply, a noise below the size of a cell); a check
that needs the problem (a time step at most the weld's duration) is done by the command after
reading it (:func:`check_samples`).

This module imports only the standard library.
"""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Callable

__all__ = [
    "MAX_FORCE_N",
    "MAX_MOMENT_NM",
    "MAX_SAMPLES",
    "check_samples",
    "count",
    "number",
    "percent",
    "wrench",
]

#: Largest force on a robot tool [N]: 10x the heaviest FSW process (the same bound as the
#: measurement checks of :mod:`rfsw_plan.validation.sanity`).
MAX_FORCE_N = 2e5
#: Largest moment on a robot tool [N m] (MAX_FORCE_N at a 1 m lever).
MAX_MOMENT_NM = 2e5
#: Most time samples a command allocates for one schedule or simulation (a 100 s weld at 0.1 ms).
MAX_SAMPLES = 1_000_000

_PERCENT = re.compile(r"^\s*([+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?)\s*%\s*$")


def _float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"'{text}' is not a finite number")
    return v + 0.0  # -0 is 0: a negative zero passes ">= 0" but numpy refuses it as a scale


def _fmt(v: float, unit: str) -> str:
    return f"{v:g}{' ' + unit if unit else ''}"


def number(lo: float, hi: float, unit: str = "", *, lo_open: bool = False,
           why: str = "") -> Callable[[str], float]:
    """An argparse ``type``: a finite float in ``[lo, hi]`` (``(lo, hi]`` if ``lo_open``), in the
    option's own unit (the caller converts to SI).

    Args:
        lo: Smallest value.
        hi: Largest value.
        unit: Unit shown in the message (``s``, ``mm``, ``ms``).
        lo_open: Exclude ``lo`` itself.
        why: Where the range comes from, appended to the message.
    """
    def parse(text: str) -> float:
        v = _float(text)
        if v < lo or v > hi or (lo_open and v == lo):
            bound = "(" if lo_open else "["
            raise argparse.ArgumentTypeError(
                f"{_fmt(v, unit)} is out of range; expected a number in {bound}{lo:g}, {hi:g}]"
                f"{' ' + unit if unit else ''}{f' ({why})' if why else ''}")
        return v

    parse.__name__ = "number"  # argparse names the type in its messages
    return parse


def count(lo: int, hi: int, what: str = "") -> Callable[[str], int]:
    """An argparse ``type``: an integer in ``[lo, hi]``."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"'{text}' is not an integer") from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(
                f"{v} is out of range; expected an integer in [{lo}, {hi}]"
                f"{f' ({what})' if what else ''}")
        return v

    parse.__name__ = "count"
    return parse


def percent(hi_percent: float = 1000.0) -> Callable[[str], float]:
    """An argparse ``type`` for a relative uncertainty: ``20%``, ``20 %`` or the fraction
    ``0.2``, returned as a fraction (0.2). A bare number above 1 is refused with the fix
    (``did you mean 20 %?``): ``--force-uncertainty 20`` is never read as +-2000 %.
    """
    def parse(text: str) -> float:
        m = _PERCENT.match(text)
        if m:
            v = _float(m.group(1)) / 100.0
        else:
            v = _float(text)
            if v > 1.0:
                raise argparse.ArgumentTypeError(
                    f"{v:g} is a fraction above 1 (+-{100 * v:g} %); did you mean {v:g} %? "
                    f"(give '{v:g}%' or the fraction {v / 100:g})")
        if v < 0 or v > hi_percent / 100.0:
            raise argparse.ArgumentTypeError(
                f"{100 * v:g} % is out of range; expected 0 % to {hi_percent:g} %")
        return v

    parse.__name__ = "percent"
    return parse


def wrench(text: str) -> list[float]:
    """An argparse ``type``: ``FX,FY,FZ[,MX,MY,MZ]`` [N, N m] (moments default to 0), each
    finite, forces within +-:data:`MAX_FORCE_N` and moments within +-:data:`MAX_MOMENT_NM`."""
    parts = text.split(",")
    if len(parts) not in (3, 6):
        raise argparse.ArgumentTypeError(
            f"got {len(parts)} values; expected FX,FY,FZ or FX,FY,FZ,MX,MY,MZ [N, N m]")
    vals = [_float(p.strip()) for p in parts] + [0.0] * (6 - len(parts))
    for k, v in enumerate(vals):
        lim, unit = (MAX_FORCE_N, "N") if k < 3 else (MAX_MOMENT_NM, "N m")
        if abs(v) > lim:
            name = ("fx", "fy", "fz", "mx", "my", "mz")[k]
            raise argparse.ArgumentTypeError(
                f"{name} = {v:g} {unit} is beyond what a robot cell applies; expected "
                f"|{name}| <= {lim:g} {unit}")
    return vals


def check_samples(option: str, step: float, duration: float, unit_scale: float = 1.0,
                  unit: str = "s", max_samples: int = MAX_SAMPLES) -> int:
    """:func:`rfsw_plan.process.frames.check_samples` for an option (imported when called, so
    the parser stays free of NumPy)."""
    from rfsw_plan.process.frames import check_samples as check

    return check(option, step, duration, unit_scale, unit, max_samples)
