"""Controller programs of a verified plan: KUKA KRL, FANUC TP, ABB RAPID and a stream file.

See :mod:`rfsw_plan.export.program` (points, motions, blending rule, frames),
:mod:`rfsw_plan.export.config` (postures), the writers and readers per vendor, and
:func:`rfsw_plan.export.api.export_programs` (write, re-read, check, commit).
"""

from rfsw_plan.export.api import FORMATS, ExportResult, export_programs, parse_formats
from rfsw_plan.export.program import Program, ProgramHeader, Samples, build_program
from rfsw_plan.export.readback import RoundTrip

__all__ = ["FORMATS", "ExportResult", "Program", "ProgramHeader", "RoundTrip", "Samples",
           "build_program", "export_programs", "parse_formats"]
