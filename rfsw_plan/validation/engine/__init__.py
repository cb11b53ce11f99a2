"""The one diagnosis engine of the workbench, shared by ``validate`` and ``validate-weld``.

* :mod:`~rfsw_plan.validation.engine.residuals`: the residual of a model against a
  measurement set, its statistics, correlations and noise floor;
* :mod:`~rfsw_plan.validation.engine.candidates`: what could be missing from a model, as
  labels and parameters to fit;
* :mod:`~rfsw_plan.validation.engine.crossval`: folds and held-out residuals of a fitted form;
* :mod:`~rfsw_plan.validation.engine.scoring`: the held-out F test, ranking and ties;
* :mod:`~rfsw_plan.validation.engine.diagnosis`: the forward selection of ``validate`` on a
  load campaign.
"""
