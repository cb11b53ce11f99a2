"""The one table from library parameter names to command-line flags.

Library jobs name their own parameters in errors (``dt: 100 s is longer than the process it
samples``), never a flag; the CLI shows the flag the user typed (``--dt: ...``) by looking the
error's source up here (:func:`as_flag_error`, applied by :mod:`rfsw_plan.cli.main` to every
:class:`~rfsw_plan.exceptions.InputError`). A parameter not in the table is shown as it is.
A library message that names another parameter writes it in backquotes (``given without
`forces` ``), which the CLI turns into the flag too.
"""

from __future__ import annotations

import re

from rfsw_plan.exceptions import InputError, RfswError

#: Library parameter -> command-line flag (the same for every command that has it).
PARAMETER_FLAGS: dict[str, str] = {
    # deviation (rfsw_plan.process.deviation_job.DeviationRequest), force logs
    "dt": "--dt",
    "cosim": "--cosim",
    "forces": "--forces",
    "forces_frame": "--forces-frame",
    # map and place (rfsw_plan.placement: MapRequest, PlaceRequest)
    "region": "--region",
    "yaw_range_deg": "--yaw-range",
    "base_height": "--robot-base-height",
    "shape": "--grid",
    "max_weld": "--waypoints",
    "candidates": "--candidates",
    "force_uncertainty": "--force-uncertainty",
    # plan (rfsw_plan.planfiles.job.PlanRequest)
    "overrides": "--set",
    "spacing": "--spacing-mm",
    # compare (rfsw_plan.realtime.compare.parse_effect_arg)
    "truth_effect": "--truth-effect",
    # export (rfsw_plan.export.format: get_format, parse_formats)
    "format": "--format",
    "formats": "--format",
    # design-campaign (rfsw_plan.validation.campaign.design.DesignRequest)
    "poses": "--poses",
    "load_n": "--load-N",
    # export (rfsw_plan.export.program.ProgramOptions)
    "cell_data": "--cell-data",
    # a lab's column map (rfsw_plan.table: read_measurements, read_force_series... columns)
    "columns": "--columns",
    # measurement files (rfsw_plan.io.measurements.read_measurements)
    "frame": "--frame",
    "wrench_frame": "--wrench-frame",
    "sensor_pose": "--sensor-pose",
    # a saved robot file (rfsw_plan.robot.description.derived_description)
    "name": "--name",
    # export (rfsw_plan.export.api.export_programs, ProgramHeader; fanuc_tp.write_tp)
    "export_spacing": "--export-spacing-mm",
    "path_tol": "--path-tol-mm",
    # calibrate (rfsw_plan.validation.calibrate.CalibrateRequest)
    "data": "--data",
    "score": "--score",
    "max_effects": "--max-effects",
    "folds": "--folds",
    "heldout_folds": "--heldout-folds",
    "every": "--every",
    # simulate-campaign (rfsw_plan.validation.campaign.simulation)
    "hidden": "--hidden",
    "loads_per_pose": "--loads-per-pose",
    "noise_mm": "--noise-mm",
    # validate, validate-weld (rfsw_plan.validation: commands, engine, weld)
    "noise_m": "--noise-mm",
    "force_noise_n": "--force-noise-N",
    "add": "--add",
    "save_robot": "--save-robot",
    "blocks": "--blocks",
}


def flag_of(parameter: str) -> str:
    """The flag of a library parameter (the parameter itself if it has none)."""
    return PARAMETER_FLAGS.get(parameter, parameter)


def as_flag_error(exc: RfswError) -> RfswError:
    """``exc`` as the CLI shows it: an :class:`InputError` whose source is a parameter of the
    table gets the flag as its source, and every parameter its source or text names in
    backquotes (```region```) becomes the flag; another error whose message names a parameter
    in backquotes (``use `folds` 3``) gets the flag there; any other error is ``exc`` itself."""
    if not isinstance(exc, InputError):
        text = str(exc)
        flagged = _flags_in(text)
        if flagged == text:
            return exc
        other = exc.__class__.__new__(exc.__class__)  # same class, exit code and attributes
        other.__dict__.update(exc.__dict__)
        other.args = (flagged,)
        return other
    source = PARAMETER_FLAGS.get(exc.source) or _flags_in(exc.source)
    problem, expected = _flags_in(exc.problem), _flags_in(exc.expected)
    if (source, problem, expected) == (exc.source, exc.problem, exc.expected):
        return exc
    out = InputError(source, exc.where, problem, expected)
    out.exit_code = exc.exit_code
    return out


def _flags_in(text: str) -> str:
    """```name``` -> the flag of ``name`` (names not in the table keep their backquotes)."""
    return _QUOTED.sub(lambda m: PARAMETER_FLAGS.get(m.group(1), m.group(0)), text)


_QUOTED = re.compile(r"`([a-z][a-z0-9_]*)`")


__all__ = ["PARAMETER_FLAGS", "as_flag_error", "flag_of"]
