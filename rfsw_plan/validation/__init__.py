"""Model against measurement: simulated campaigns, residuals, diagnosis and reports.

Data flow: :func:`run_campaign` simulates a :class:`~rfsw_plan.io.measurements.MeasurementSet`
(or one is read from a file); :func:`validate` cross-validates the model on it, analyses the
residuals (:func:`analyze_residuals`, :func:`estimate_noise_floor`) and diagnoses missing
effects (:func:`diagnose`); :func:`write_report` turns the :class:`ValidationResult` into plots,
HTML and JSON.

Layout, one concept per folder: ``engine/`` the one diagnosis engine (residuals, candidates,
cross-validation, scoring, the forward selection) shared by ``validate`` and ``validate-weld``;
``campaign/`` simulated campaigns and the design of the next one; ``weld/`` the weld workbench;
``report/`` the reports. The modules at this level are the commands and what they share:
``workbench`` (``validate``), ``commands`` (each workbench command as a library call),
``identify_robot``, ``derived_robot`` (the re-identified robot file) and ``sanity`` (measured
data before any fit). A plan folder is read through :mod:`rfsw_plan.planfiles`.

The names are imported on first use (PEP 562), so
``import rfsw_plan.validation.campaign.simulation`` does not load SciPy's statistics or,
through the report, matplotlib (which the report only imports inside
:func:`~rfsw_plan.validation.report.validate.make_plots` anyway).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rfsw_plan.validation.campaign.simulation import (
        THERMAL_DRIFT,
        CampaignResult,
        HiddenSpec,
        campaign_poses,
        campaign_wrenches,
        check_hidden_label,
        parse_hidden,
        run_campaign,
        simulate_campaign,
    )
    from rfsw_plan.validation.engine.diagnosis import (
        DEFAULT_FOLDS,
        Candidate,
        ChainStep,
        CrossValidation,
        Diagnosis,
        Selection,
        Skipped,
        candidate_labels,
        cross_validate,
        diagnose,
        evaluate_candidates,
        forward_select,
        make_folds,
    )
    from rfsw_plan.validation.engine.residuals import (
        AxisStats,
        FeatureCorrelation,
        JointBreakdown,
        NoiseFloor,
        ResidualAnalysis,
        analyze_residuals,
        correlations,
        estimate_noise_floor,
        explained_share,
        repeat_groups,
        residual_features,
    )
    from rfsw_plan.validation.report.validate import (
        ReportFiles,
        make_plots,
        render_html,
        result_json,
        write_report,
    )
    from rfsw_plan.validation.workbench import (
        AddResult,
        ValidationResult,
        check_effect_labels,
        save_extended_robot,
        validate,
    )

#: Public name -> submodule that defines it.
_SOURCES: dict[str, str] = {
    **dict.fromkeys(
        ("THERMAL_DRIFT", "CampaignResult", "HiddenSpec", "campaign_poses", "campaign_wrenches",
         "check_hidden_label", "parse_hidden", "run_campaign", "simulate_campaign"),
        "campaign.simulation",
    ),
    **dict.fromkeys(
        ("AxisStats", "FeatureCorrelation", "JointBreakdown", "NoiseFloor", "ResidualAnalysis",
         "analyze_residuals", "correlations", "estimate_noise_floor", "explained_share",
         "repeat_groups", "residual_features"),
        "engine.residuals",
    ),
    **dict.fromkeys(
        ("DEFAULT_FOLDS", "Candidate", "ChainStep", "CrossValidation", "Diagnosis", "Selection",
         "Skipped", "candidate_labels", "cross_validate", "diagnose", "evaluate_candidates",
         "forward_select", "make_folds"),
        "engine.diagnosis",
    ),
    **dict.fromkeys(
        ("AddResult", "ValidationResult", "check_effect_labels", "save_extended_robot",
         "validate"),
        "workbench",
    ),
    **dict.fromkeys(
        ("ReportFiles", "make_plots", "render_html", "result_json", "write_report"),
        "report.validate",
    ),
}

__all__ = [
    "DEFAULT_FOLDS",
    "THERMAL_DRIFT",
    "AddResult",
    "AxisStats",
    "CampaignResult",
    "Candidate",
    "ChainStep",
    "CrossValidation",
    "Diagnosis",
    "FeatureCorrelation",
    "HiddenSpec",
    "JointBreakdown",
    "NoiseFloor",
    "ReportFiles",
    "ResidualAnalysis",
    "Selection",
    "Skipped",
    "ValidationResult",
    "analyze_residuals",
    "campaign_poses",
    "campaign_wrenches",
    "candidate_labels",
    "check_effect_labels",
    "check_hidden_label",
    "correlations",
    "cross_validate",
    "diagnose",
    "estimate_noise_floor",
    "evaluate_candidates",
    "explained_share",
    "forward_select",
    "make_folds",
    "make_plots",
    "parse_hidden",
    "render_html",
    "repeat_groups",
    "residual_features",
    "result_json",
    "run_campaign",
    "save_extended_robot",
    "simulate_campaign",
    "validate",
    "write_report",
]


def __getattr__(name: str) -> Any:
    module = _SOURCES.get(name)
    if module is None:
        raise AttributeError(f"module 'rfsw_plan.validation' has no attribute '{name}'")
    value = getattr(importlib.import_module(f"rfsw_plan.validation.{module}"), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
