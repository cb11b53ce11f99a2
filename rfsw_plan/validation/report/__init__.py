"""The workbench reports: one self-contained HTML page, PNG plots and a JSON file per command.

* :mod:`~rfsw_plan.validation.report.validate`: the report of ``validate``;
* :mod:`~rfsw_plan.validation.report.validate_weld`: the report of ``validate-weld``;
* :mod:`~rfsw_plan.validation.report.html_page`: the page head, stylesheet, tables and figures
  both share.
"""
