"""A re-identified robot written as a new robot file, with its provenance.

The one writer behind ``identify -o``, ``validate --save-robot`` and
``validate-weld --save-robot``: device-frame set-up effects are folded into the file's
``[device_frame]`` table, the robot gets a new name (the parent's plus what was added, e.g.
``zk500+payload_gravity``) and a ``[provenance]`` table (parent file, data file and its
SHA-256, the command, the date).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from rfsw_plan.elastostatics.identification import ParameterEstimate
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.elastostatics.registration import DeviceSetup
from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.description import (
    DeviceFrame,
    RobotDescription,
    derived_description,
    save_robot_description,
)


def added_effects(model: ElastostaticModel, parent: RobotDescription) -> tuple[str, ...]:
    """Labels of the robot effects of ``model`` that the parent robot file does not have
    (set-up effects left out)."""
    before = {e.name for e in parent.effects}
    return tuple(e.label for e in model.effects[1:] if not e.setup and e.label not in before)


def save_derived_robot(
    model: ElastostaticModel, path: str | Path, *, parent: RobotDescription, note: str,
    data: str | Path, command: str, name: str | None = None,
    added: Sequence[str] | None = None, forces: str | Path | None = None,
    setup: DeviceSetup | None = None, estimates: Sequence[ParameterEstimate] = (),
    device_note: str | None = None, device_frame: DeviceFrame | None = None,
) -> Path:
    """Write ``model`` as a robot description TOML derived from ``parent``.

    Args:
        model: The re-identified model (with its set-up effects for device-frame data).
        path: The new robot file.
        parent: The robot file it was derived from.
        note: Where the stiffness values come from (the file's ``sources``).
        data: The measurement file (or weld track) it was identified on.
        command: The command that made it.
        name: The new robot name (default: the parent's plus the added effects).
        added: What was added (default: :func:`added_effects`).
        forces: The force log, for a weld.
        setup: The device set-up of device-frame data: its effects go into ``[device_frame]``.
        estimates: The identification's estimates (to fold the set-up effects).
        device_note: Where a fitted registration comes from (``sources.device_frame``).
        device_frame: A registration already folded (``calibrate``), written as the file's
            ``[device_frame]`` when there is no ``setup``.

    Returns:
        The path written.

    Raises:
        InputError: An identified parameter outside its effect's physical range: the robot
            file would not load, so it is not written (one line naming the effect parameter).
    """
    if setup is None:
        robot_model, desc = model, model.to_description(note)
        if device_frame is not None:
            desc = replace(desc, device_frame=device_frame)
            if device_note:
                desc.sources["device_frame"] = device_note
    else:
        robot_model, frame = setup.fold(model, tuple(estimates))
        desc = replace(robot_model.to_description(note), device_frame=frame)
        if device_note and (setup.fit_registration or setup.fit_marker):
            desc.sources["device_frame"] = device_note
    _check_loadable(robot_model, path)
    added = tuple(added) if added is not None else added_effects(robot_model, parent)
    desc = derived_description(desc, name=name, parent=parent.path, data=data, command=command,
                               added=added, forces=forces)
    return save_robot_description(desc, path)


def _check_loadable(model: ElastostaticModel, path: str | Path) -> None:
    """What reading the robot file will check of its effects, before the file exists."""
    for effect in model.effects:
        try:
            effect.check_params()
        except InputError as exc:
            raise InputError(path, exc.where, f"not written: {exc.problem}, and a robot file "
                             "with it would not load", f"{exc.expected}; see the report's "
                             "plausibility column, or fit without this effect") from None


__all__ = ["added_effects", "save_derived_robot"]
