"""Bundled FSW processes from the seed papers (a problem file can start from one).

Numbers marked ASSUMED are not in the seeds; they are plausible values for the material and
thickness and can be overridden in the problem file or fitted to a measured force series.
"""

from __future__ import annotations

from rfsw_plan.exceptions import UnknownNameError
from rfsw_plan.process.cosim import PenetrationObservation
from rfsw_plan.process.forces import ProcessForces, ProcessModel

_SEED001 = ProcessModel(
    forces=ProcessForces(
        axial=4842.58, lateral=1350.87, traverse=899.80, lateral_sign=1.0,
        plunge_peak_axial=None, dwell_lateral_fraction=0.5, dwell_tau=2.0, ramp_length=1e-3,
        spindle_torque=0.0,
        source="seed 001 §3: measured steady Fd0 4842.58 N, Fl0 1350.87 N, Fr0 899.80 N; "
        "plunge peak = steady, dwell fraction 0.5, T_d 2 s, L 1 mm and torque 0 ASSUMED",
    ),
    travel_speed=3e-3, plunge_speed=2e-3, plunge_depth=4.8e-3, dwell_time=10.0,
    retract_speed=2e-3, approach_height=0.0, approach_speed=10e-3, rotation_speed_rpm=1500.0,
    name="seed001_aa6061_5mm", material="AA6061-T6", thickness=5e-3,
    source="seed 001 §2.1 and Table 6: 1500 rpm, 3 mm/s, plunge 2 mm/s, tilt 2 deg, pin 4.8 mm "
    "(depth); dwell 10 s from Fig. 10 (stable after ~12-16 s) and retract speed ASSUMED",
)

_SEED000 = ProcessModel(
    forces=ProcessForces(
        axial=3100.0, lateral=1000.0, traverse=1000.0, lateral_sign=1.0,
        plunge_peak_axial=None, dwell_lateral_fraction=0.5, dwell_tau=2.0, ramp_length=1e-3,
        spindle_torque=0.0,
        source="seed 000 §2: forge force 3.1 kN (force control); lateral and traverse 1 kN "
        "ASSUMED (Fig. 22 is not legible in the extracted text); ramps ASSUMED",
    ),
    travel_speed=6e-3, plunge_speed=0.5e-3, plunge_depth=2.9e-3, dwell_time=5.0,
    retract_speed=2e-3, approach_height=0.0, approach_speed=10e-3, rotation_speed_rpm=1200.0,
    axial_control="force",
    name="seed000_aa5754_3mm", material="AA5754-H22", thickness=3e-3,
    source="seed 000 §2: 1200 rpm, 6 mm/s, tilt 0, pin 2.8 mm + 0.1 mm shoulder depth, axial "
    "force control at the 3.1 kN forge force; plunge speed 0.5 mm/s, dwell 5 s and retract "
    "speed ASSUMED",
)

#: Bundled processes by name.
PROCESS_PRESETS: dict[str, ProcessModel] = {p.name: p for p in (_SEED000, _SEED001)}


def process_preset(name: str) -> ProcessModel:
    """A bundled process by name.

    Raises:
        UnknownNameError: Lists the bundled process names.
    """
    try:
        return PROCESS_PRESETS[name]
    except KeyError:
        raise UnknownNameError("process preset", name, PROCESS_PRESETS) from None


#: Seed 001 §4 and Fig. 10a-c: commanded plunge 7 / 8 / 9 mm (after surface contact) for the
#: 4.8 mm pin settled at about 4.2 mm, about 4.8 mm and "exceeded the thickness of the base
#: material" (5 mm plate), read as a lower bound of 5.0 mm.
SEED001_FIG10 = (
    PenetrationObservation(commanded_depth=7e-3, penetration=4.2e-3),
    PenetrationObservation(commanded_depth=8e-3, penetration=4.8e-3),
    PenetrationObservation(commanded_depth=9e-3, penetration=5.0e-3, at_least=True),
)

#: Observed plunges a ``[process.coupling] calibration`` can name.
PENETRATION_CALIBRATIONS: dict[str, tuple[PenetrationObservation, ...]] = {
    "seed001_fig10": SEED001_FIG10,
}


def penetration_calibration(name: str) -> tuple[PenetrationObservation, ...]:
    """Observed plunges of a bundled calibration by name.

    Raises:
        UnknownNameError: Lists the bundled calibration names.
    """
    try:
        return PENETRATION_CALIBRATIONS[name]
    except KeyError:
        raise UnknownNameError("penetration calibration", name, PENETRATION_CALIBRATIONS
                               ) from None
