"""The workbench commands as library calls: ``validate`` and ``validate-weld`` from their inputs
to the files they write.

Each function does what its command does after parsing: checks, computes, writes the report
and the re-identified robot file, and returns what the command prints. The CLI modules only
parse, call one of these, and print.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError
from rfsw_plan.files import OutputLock
from rfsw_plan.robot.description import DeviceFrame
from rfsw_plan.validation.derived_robot import save_derived_robot
from rfsw_plan.validation.report.validate import ReportFiles, write_report
from rfsw_plan.validation.sanity import prepare_data
from rfsw_plan.validation.workbench import ValidationResult, save_extended_robot, validate

if TYPE_CHECKING:  # validate-weld's modules (the process package) load when it runs
    from rfsw_plan.validation.report.validate_weld import WeldReportFiles
    from rfsw_plan.validation.weld.workbench import WeldValidation

#: Called with the name of each stage as it starts (the CLI's progress line).
OnStage = Callable[[str], None]


def _nothing(stage: str) -> None:
    """No progress display."""


def fresh_folder(default: str | Path) -> Path:
    """``default``, or if it already holds files, the first of ``default_2``, ``default_3``
    ... that does not: a default report folder never overwrites an earlier report."""
    p = Path(default)
    k = 2
    while p.exists() and (not p.is_dir() or any(p.iterdir())):
        p = Path(f"{default}_{k}")
        k += 1
    return p


@dataclass(frozen=True)
class ValidateRun:
    """What ``rfsw-plan validate`` made.

    Attributes:
        result: The validation.
        files: The report, or None when none was asked for.
        saved: The re-identified robot file, or None.
    """

    result: ValidationResult
    files: ReportFiles | None
    saved: Path | None


def run_validate(
    model: ElastostaticModel, data: MeasurementSet, *, held: DeviceFrame | None = None,
    marker: FloatArray | None = None, noise_m: float | None = None, add: Sequence[str] = (),
    folds: int = 5, seed: int = 0, force_noise_n: float | None = None,
    report: Path | None = None, save_robot: Path | None = None, name: str | None = None,
    argv: list[str] | None = None,
    on_stage: OnStage = _nothing,
) -> ValidateRun:
    """Check the data, validate (:func:`~rfsw_plan.validation.workbench.validate`), write the
    report into ``report`` and the re-identified robot into ``save_robot``.

    Args:
        model: The robot file's model.
        data: The measurements.
        held: A known registration of device-frame data.
        marker: A known marker offset in the tool frame [m], shape (3,).
        noise_m: 1-sigma position noise [m] (default: from repeated samples).
        add: Effects to add and re-identify.
        folds: Cross-validation folds.
        seed: Seed of the fold split.
        force_noise_n: 1-sigma force sensor noise [N].
        report: Report folder, already checked (None: no report).
        save_robot: Robot file to write, already checked (None: none).
        name: Robot name in that file.
        argv: The command line (the report prints the next command).
        on_stage: Progress callback, called with "diagnosis" and "plots and report".

    Raises:
        InputError: Bad data or options (one line).
        IdentificationError: Too few samples or poses (says how many).
    """
    if noise_m is not None and not noise_m > 0:
        raise InputError("noise_m", "", f"{noise_m * 1e3:g}", "a positive noise in mm")
    setup = prepare_data(model, data, held, marker)
    on_stage("diagnosis")
    result = validate(model, data, noise_m=noise_m, add=add, folds=folds, seed=seed,
                      setup=setup, force_noise_n=force_noise_n)
    files = None
    if report is not None:
        on_stage("plots and report")
        with OutputLock(report):
            files = write_report(result, report, argv=argv)
    saved = save_extended_robot(result, save_robot, name=name) if save_robot else None
    return ValidateRun(result, files, saved)


@dataclass(frozen=True)
class WeldRun:
    """What ``rfsw-plan validate-weld`` made.

    Attributes:
        result: The weld validation.
        files: The report.
        saved: The re-identified robot file, or None.
        next: The command to run next.
    """

    result: WeldValidation
    files: WeldReportFiles
    saved: Path | None
    next: str


def run_validate_weld(
    plan_dir: str, track: str, out: Path, *, forces: str | None = None,
    forces_frame: str | None = None, problem: str | None = None, robot: str | None = None,
    add: Sequence[str] = (), save_robot: Path | None = None, name: str | None = None,
    blocks: int = 5, on_stage: OnStage = _nothing,
) -> WeldRun:
    """Read the plan, the track and the force log, validate the weld
    (:func:`~rfsw_plan.validation.weld.workbench.validate_weld`), write the report into ``out``
    and the re-identified robot into ``save_robot``.

    Args:
        plan_dir: The plan folder that was run.
        track: The measured track file.
        out: Report folder, already checked.
        forces: The force log of the weld (None: the planned forces).
        forces_frame: Frame of the force log if it has no ``frame`` column.
        problem: Problem file (default: the one ``plan.json`` names).
        robot: Current robot model (default: the plan's).
        add: Candidates to add and fit.
        save_robot: Robot file to write (needs ``add``), already checked.
        name: Robot name in that file.
        blocks: Blocks of s of the cross-validation.
        on_stage: Progress callback, called with "diagnosis" and "plots and report".

    Raises:
        InputError: Bad files or options (one line).
    """
    from rfsw_plan.io.force_series import read_force_series
    from rfsw_plan.io.weld_track import read_weld_track
    from rfsw_plan.planfiles.folder import PlanFolder
    from rfsw_plan.robot.kinematics import load_robot
    from rfsw_plan.validation.report.validate_weld import write_weld_report
    from rfsw_plan.validation.weld.workbench import next_command, validate_weld

    if save_robot is not None and not add:
        raise InputError("save_robot", str(save_robot), "given without `add`",
                         "`add` EFFECT with `save_robot` NEW.toml (the weld re-identifies only "
                         "what you add)")
    if forces_frame and not forces:
        raise InputError("forces_frame", "", "given without `forces`", "`forces` LOG.csv")
    record = PlanFolder.open(plan_dir).rebuild(problem)
    measured = read_weld_track(track)
    series = read_force_series(forces, forces_frame) if forces else None
    model = ElastostaticModel(load_robot(robot or record.problem.robot))
    with OutputLock(out):
        on_stage("diagnosis")
        result = validate_weld(record, measured, series, model, add=add, blocks=blocks)
        saved = None
        if save_robot is not None and result.add is not None:
            a = result.add
            note = (f"re-identified by rfsw-plan validate-weld from {track} (plan "
                    f"{plan_dir}): {', '.join(a.labels)}; lateral RMS "
                    f"{a.rms_before * 1e3:.4g} -> {a.rms_after * 1e3:.4g} mm")
            saved = save_derived_robot(a.model, save_robot, parent=model.robot.description,
                                       note=note, data=track, command="rfsw-plan validate-weld",
                                       name=name, added=a.labels, forces=forces)
        nxt = next_command(result, plan_dir, track, forces, saved)
        on_stage("plots and report")
        files = write_weld_report(result, out, nxt,
                                  {"saved_robot": str(saved) if saved else None})
    return WeldRun(result, files, saved, nxt)


__all__ = ["ValidateRun", "WeldRun", "fresh_folder", "run_validate", "run_validate_weld"]
