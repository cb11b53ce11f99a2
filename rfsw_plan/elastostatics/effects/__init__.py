"""Library of elastostatic effects and the registry that turns names into instances.

Effect labels are ``name`` or ``name:jN`` (N 1-based) for per-joint effects. Every module of
this folder is imported here, and every concrete effect class registers itself in
:data:`EFFECTS` (:meth:`Effect.__init_subclass__`): a new effect is one file in this folder.
"""

from __future__ import annotations

import importlib
import pkgutil
import re
from collections.abc import Mapping

from rfsw_plan.elastostatics.effects.base import (
    EFFECTS,
    ComplianceEffect,
    Effect,
    EffectGroups,
    GeometricEffect,
    PoseBatch,
    WrenchEffect,
)
from rfsw_plan.elastostatics.effects.complementary_stiffness import ComplementaryStiffness
from rfsw_plan.elastostatics.effects.device_registration import DeviceRegistration, MarkerOffset
from rfsw_plan.elastostatics.effects.force_sensor_bias import ForceSensorBias
from rfsw_plan.elastostatics.effects.joint_backlash import JointBacklash
from rfsw_plan.elastostatics.effects.joint_compliance import JointCompliance
from rfsw_plan.elastostatics.effects.kinematic_offsets import KinematicOffsets
from rfsw_plan.elastostatics.effects.link_errors import LinkErrors
from rfsw_plan.elastostatics.effects.load_hysteresis import LoadHysteresis
from rfsw_plan.elastostatics.effects.lost_motion import LostMotion
from rfsw_plan.elastostatics.effects.payload_gravity import PayloadGravity
from rfsw_plan.elastostatics.effects.sensor_misalignment import SensorMisalignment
from rfsw_plan.elastostatics.effects.tilting_compliance import TiltingCompliance
from rfsw_plan.elastostatics.effects.torque_dependent_stiffness import TorqueDependentStiffness
from rfsw_plan.exceptions import InputError, UnknownNameError
from rfsw_plan.robot.kinematics import Robot

for _module in pkgutil.iter_modules(__path__):
    importlib.import_module(f"{__name__}.{_module.name}")

#: The library's order (the base model first, then compliance, wrench and geometric effects)
#: for listings; effects of other files follow in the order they registered.
_LIBRARY = (JointCompliance, ComplementaryStiffness, TiltingCompliance, TorqueDependentStiffness,
            JointBacklash, LostMotion, LoadHysteresis, PayloadGravity, SensorMisalignment,
            ForceSensorBias, KinematicOffsets, LinkErrors, DeviceRegistration, MarkerOffset)
_others = {k: v for k, v in EFFECTS.items() if v not in _LIBRARY}
EFFECTS.clear()
EFFECTS.update({cls.name: cls for cls in _LIBRARY} | _others)

_LABEL = re.compile(r"^([a-z_]+)(?::j(\d+))?$")


def parse_effect_label(label: str, n_joints: int) -> tuple[type[Effect], int | None]:
    """Split ``name[:jN]`` into the effect class and a 0-based joint index.

    Raises:
        UnknownNameError: Unknown effect name (lists the known ones).
        InputError: Joint index missing, not expected, or out of range.
    """
    m = _LABEL.match(label.strip())
    name = m.group(1) if m else label
    if name not in EFFECTS:
        raise UnknownNameError("effect", name, EFFECTS)
    cls = EFFECTS[name]
    assert m is not None
    joint = int(m.group(2)) - 1 if m.group(2) else None
    if cls.per_joint:
        if joint is None:
            raise InputError("effect", label, "needs a joint", f"{name}:jN with N in 1..{n_joints}")
        if not 0 <= joint < n_joints:
            raise InputError("effect", label, f"joint {joint + 1} out of range", f"1..{n_joints}")
    elif joint is not None:
        raise InputError("effect", label, "takes no joint index", name)
    return cls, joint


def make_effect(robot: Robot, label: str, params: Mapping[str, float] | None = None) -> Effect:
    """Instantiate an effect from its label (``tilting_compliance:j2``) and parameters."""
    cls, joint = parse_effect_label(label, robot.nq)
    return cls(robot, joint, params)


__all__ = [
    "EFFECTS",
    "ComplementaryStiffness",
    "ComplianceEffect",
    "DeviceRegistration",
    "Effect",
    "EffectGroups",
    "ForceSensorBias",
    "GeometricEffect",
    "JointBacklash",
    "JointCompliance",
    "KinematicOffsets",
    "LinkErrors",
    "LoadHysteresis",
    "LostMotion",
    "MarkerOffset",
    "PayloadGravity",
    "PoseBatch",
    "SensorMisalignment",
    "TiltingCompliance",
    "TorqueDependentStiffness",
    "WrenchEffect",
    "make_effect",
    "parse_effect_label",
]
