"""The weld workbench (``validate-weld``): a plan against the weld it gave.

* :mod:`~rfsw_plan.validation.weld.workbench`: :func:`validate_weld`, the command's result and
  its next step;
* :mod:`~rfsw_plan.validation.weld.track`: the measured track as offsets along the seam;
* :mod:`~rfsw_plan.validation.weld.samples`: the executed pin path and forces per sample;
* :mod:`~rfsw_plan.validation.weld.fit`: a candidate form fitted to the weld;
* :mod:`~rfsw_plan.validation.weld.identifiability`: what one weld can identify;
* :mod:`~rfsw_plan.validation.weld.diagnosis`: the candidates scored by the engine on blocks
  of arc length;
* :mod:`~rfsw_plan.validation.weld.add`: ``--add``, the named effect added and identified.
"""
