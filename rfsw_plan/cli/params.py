"""The one table from library parameter names to command-line flags.

Library jobs name their own parameters in errors (``dt: 100 s is longer than the process it
samples``), never a flag; the CLI shows the flag the user typed (``--dt: ...``) by looking the
error's source up here (:func:`as_flag_error`, applied by :mod:`rfsw_plan.cli.main` to every
:class:`~rfsw_plan.exceptions.InputError`). A parameter not in the table is shown as it is.
"""

from __future__ import annotations

from rfsw_plan.exceptions import InputError, RfswError

#: Library parameter -> command-line flag (the same for every command that has it).
PARAMETER_FLAGS: dict[str, str] = {
    "dt": "--dt",
    "cosim": "--cosim",
    "forces": "--forces",
    "forces_frame": "--forces-frame",
    "candidates": "--candidates",
    "workers": "--workers",
    "dask": "--dask",
    "output": "-o",
    "region_mm": "--region-mm",
    "grid": "--grid",
    "yaw_deg": "--yaw-deg",
    "heights_mm": "--heights-mm",
    "height_mm": "--height-mm",
    "force_uncertainty": "--force-uncertainty",
}


def flag_of(parameter: str) -> str:
    """The flag of a library parameter (the parameter itself if it has none)."""
    return PARAMETER_FLAGS.get(parameter, parameter)


def as_flag_error(exc: RfswError) -> RfswError:
    """``exc`` with its source shown as the flag, if it is an :class:`InputError` whose source
    is a library parameter of the table; otherwise ``exc`` itself."""
    if isinstance(exc, InputError) and exc.source in PARAMETER_FLAGS:
        out = InputError(PARAMETER_FLAGS[exc.source], exc.where, exc.problem, exc.expected)
        out.exit_code = exc.exit_code
        return out
    return exc


__all__ = ["PARAMETER_FLAGS", "as_flag_error", "flag_of"]
