"""Controller programs of a verified plan: KUKA KRL, FANUC TP, ABB RAPID and a stream file.

One module per format behind :class:`~rfsw_plan.export.format.ControllerFormat` (the registry
:data:`~rfsw_plan.export.format.FORMATS`); :mod:`rfsw_plan.export.program` holds the
vendor-neutral program (points, motions, blending model, plate frame, hooks),
:mod:`rfsw_plan.export.config` the postures, :func:`rfsw_plan.export.api.export_programs`
writes, re-reads, checks and commits, and :mod:`rfsw_plan.export.check` re-verifies a
(possibly edited) program against its plan.
"""

from rfsw_plan.export.api import ExportResult, export_plan_folder, export_programs
from rfsw_plan.export.format import (
    FORMATS,
    ControllerFormat,
    FormatLimits,
    ReadPoint,
    ReadProgram,
    format_names,
    formats,
    parse_formats,
)
from rfsw_plan.export.program import (
    Hooks,
    Program,
    ProgramHeader,
    ProgramOptions,
    Samples,
    build_program,
)
from rfsw_plan.export.readback import RoundTrip

__all__ = ["FORMATS", "ControllerFormat", "ExportResult", "FormatLimits", "Hooks", "Program",
           "ProgramHeader", "ProgramOptions", "ReadPoint", "ReadProgram", "RoundTrip",
           "Samples", "build_program", "export_plan_folder", "export_programs", "format_names",
           "formats", "parse_formats"]
