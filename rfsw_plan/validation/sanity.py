"""Sanity of measured data before any fit: can it belong to this robot, in these units?

A fit always "succeeds": positions in metres in ``x_mm`` columns give a stiffness 1000x off and
an RMS of a metre. :func:`check_data` stops before that, with one line naming the likely cause:

* joint values: outside the robot's limits, or revolute values that look like radians in a
  ``_deg`` column (or degrees in a ``_rad`` column);
* forces: magnitudes no robot cell applies;
* positions at zero load against the nominal model: a scale of ~1000 (metres vs mm), or a
  residual of metres (wrong robot, or a device frame given as the base frame);
* deflection per newton: measured deflection ~1000x (or 1/1000x) what the model predicts for
  the logged forces (kN logged in ``_N`` columns).
"""

from __future__ import annotations

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.elastostatics.registration import DeviceSetup, prepare_device_setup
from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.description import DeviceFrame

#: Joint values beyond the limits by more than this [rad] (or 10 % of a prismatic range) are
#: not a calibration error.
LIMIT_SLACK_RAD = np.radians(10.0)
#: Largest plausible force on a robot tool [N] (10x the heaviest FSW process).
MAX_FORCE_N = 2e5
#: A zero-load residual above this [m] is not a model error but wrong data.
MAX_RESIDUAL_M = 0.2
#: Measured / predicted deflection ratios beyond this factor mean wrong units.
DEFLECTION_FACTOR = 30.0


def _col(data: MeasurementSet, key: str, fallback: str) -> str:
    return data.columns.get(key, fallback)


def check_joints(model: ElastostaticModel, data: MeasurementSet) -> None:
    """Joint values within the limits (with slack), in the units their columns claim."""
    robot = model.robot
    desc = robot.description
    rev = ~robot.prismatic
    q = data.q
    names = [_col(data, f"q{j + 1}", f"q{j + 1}") for j in range(robot.nq)]
    deg_cols = np.array([n.endswith("_deg") for n in names])
    span = desc.upper - desc.lower
    if rev.any() and (deg_cols & rev).any() and len(data) >= 3:
        sel = deg_cols & rev
        big = np.degrees(np.abs(q[:, sel])).max()
        wide = np.degrees(span[sel]).max()
        if big <= 2 * np.pi and wide > 60.0 and np.ptp(np.degrees(q[:, sel])) < 2 * np.pi:
            raise InputError(data.source, f"columns {names[int(np.flatnonzero(sel)[0])]}..",
                             f"q values look like radians: max |q| {big:.3g} in columns named "
                             "*_deg", "degrees in *_deg columns (or name them *_rad)")
    slack = np.where(robot.prismatic, 0.1 * span, LIMIT_SLACK_RAD)
    low = q < desc.lower - slack
    high = q > desc.upper + slack
    bad = np.argwhere(low | high)
    if bad.size:
        r, j = (int(x) for x in bad[0])
        unit, scale = ("mm", 1e3) if robot.prismatic[j] else ("deg", float(np.degrees(1.0)))
        hint = ""
        if not robot.prismatic[j] and names[j].endswith("_rad"):
            hint = "; values look like degrees in a *_rad column"
        raise InputError(
            data.source, f"sample {r + 1}, column {names[j]}",
            f"joint {j + 1} at {q[r, j] * scale:.4g} {unit} is outside robot {robot.name}'s "
            f"limits [{desc.lower[j] * scale:.4g}, {desc.upper[j] * scale:.4g}] {unit}{hint}",
            "the data of this robot (check the robot, the joint order and the units)")


def check_forces(data: MeasurementSet) -> None:
    """Force magnitudes a robot cell can apply."""
    f = np.linalg.norm(data.wrench[:, :3], axis=1)
    if f.size and float(f.max()) > MAX_FORCE_N:
        r = int(np.argmax(f))
        raise InputError(data.source, f"sample {r + 1}, columns fx..fz",
                         f"force {f[r]:.4g} N is implausible for a robot tool",
                         f"at most {MAX_FORCE_N:g} N (kN in a *_N column? name it *_kN)")


def check_positions(model: ElastostaticModel, data: MeasurementSet) -> None:
    """Zero-load residual and deflection per newton against the nominal model (base frame)."""
    batch = model.batch_of(data)
    fk = batch.T[:, :3, 3]
    zero = model.deflection_batch(batch, np.zeros_like(data.wrench))[:, :3]
    loaded = model.deflection_batch(batch, data.wrench)[:, :3]
    pred = fk + loaded
    meas = data.position
    ok = np.isfinite(meas)
    if not ok.any():
        return
    x_name = _col(data, "x", "x_mm")
    med_meas = float(np.median(np.abs(meas[ok])))
    med_pred = float(np.median(np.abs(pred[ok])))
    res = np.where(ok, meas - pred, np.nan)
    rms = float(np.sqrt(np.nanmean(res**2)))
    if rms <= MAX_RESIDUAL_M:
        forces_only = data.wrench.copy()
        forces_only[:, 3:] = 0.0
        by_force = model.deflection_batch(batch, forces_only)[:, :3] - zero
        _check_deflection(model, data, meas - fk - zero, by_force, loaded - zero - by_force)
        return
    ratio = med_meas / med_pred if med_pred > 0 else float("nan")
    file_unit = 1e-3 if x_name.endswith("_mm") else 1.0
    if 3e-4 < ratio < 3e-3:
        raise InputError(data.source, f"column {x_name}",
                         f"positions look like metres: median |x| {med_meas / file_unit:.3g} "
                         f"in a column named {x_name}", "millimetres in *_mm columns")
    if 300 < ratio < 3000:
        raise InputError(data.source, f"column {x_name}",
                         f"positions look like millimetres: median |x| "
                         f"{med_meas / file_unit:.3g} in a column named {x_name}",
                         "metres in *_m columns")
    raise InputError(data.source, "positions",
                     f"residual {rms:.3g} m RMS against the nominal model: wrong robot or "
                     "frame, try `frame` device", f"positions of robot {model.robot.name}'s "
                     "TCP in its base frame")


def _check_deflection(
    model: ElastostaticModel, data: MeasurementSet, measured: np.ndarray,
    by_force: np.ndarray, by_moment: np.ndarray,
) -> None:
    """Measured load deflection against the model's, force and moment parts apart.

    The measured deflection d is fitted as ``g_f d_f + g_m d_m`` (d_f, d_m: the model's
    deflection under the logged forces alone and the logged moments alone, [m], shape (m, 3)).
    A gain of ~1000 on one part means that part is logged in the wrong unit (kN in ``*_N``
    columns, moments left in N m), even when the other part is right; a gain of ~1000 on both
    means the stiffness is off or both are. Noise-free truth gives g_f = g_m = 1.
    """
    ok = np.isfinite(measured).all(axis=1)
    if not ok.any():
        return
    parts = [(name, d[ok].ravel()) for name, d in (("forces", by_force), ("moments", by_moment))
             if np.any(d[ok])]
    if not parts:
        return
    d_meas = measured[ok].ravel()
    A = np.stack([d for _, d in parts], axis=1)
    gains, *_ = np.linalg.lstsq(A, d_meas, rcond=None)
    fitted = A @ gains
    r2 = 1.0 - float(np.sum((d_meas - fitted) ** 2)) / max(float(np.sum(d_meas**2)), 1e-300)
    if r2 <= 0.5:
        return
    for (name, d), g in zip(parts, gains, strict=True):
        size = float(np.sqrt(np.mean((g * d) ** 2)))
        if size < 1e-4 and float(np.sqrt(np.mean(d**2))) < 1e-4:
            continue  # this part moves nothing by 0.1 mm either way: nothing to compare
        if g > DEFLECTION_FACTOR or 0 < g < 1.0 / DEFLECTION_FACTOR:
            cols = "fx..fz" if name == "forces" else "mx..mz"
            unit = ("N in *_N columns (or name them *_kN)" if name == "forces"
                    else "N m in *_Nm columns (or name them *_kNm)")
            raise InputError(
                data.source, f"columns {cols}",
                f"measured deflections are {g:.3g}x what robot {model.robot.name} predicts for "
                f"the logged {name}: {name[:-1]} units off (kN logged as N?) or the "
                "robot's stiffness is off", unit)


def check_data(model: ElastostaticModel, data: MeasurementSet) -> None:
    """All checks of the module docstring; base-frame positions only for the position checks.

    Raises:
        InputError: One line naming the likely cause.
    """
    check_joints(model, data)
    check_forces(data)
    if data.frame == "base":
        check_positions(model, data)


def check_registered(model: ElastostaticModel, data: MeasurementSet) -> None:
    """After registration (positions brought to the base frame): the residual must be a model
    error, not wrong data."""
    batch = model.batch_of(data)
    pred = batch.T[:, :3, 3] + model.deflection_batch(batch, data.wrench)[:, :3]
    res = data.position - pred
    rms = float(np.sqrt(np.nanmean(res**2)))
    if rms > 0.05:
        raise InputError(
            data.source, "positions",
            f"after registering the device frame the residual is still {rms * 1e3:.4g} mm RMS: "
            f"wrong robot, joint order, joint units or marker", f"motion of robot "
            f"{model.robot.name}'s tool seen from a fixed device")


def prepare_data(
    model: ElastostaticModel, data: MeasurementSet, held: DeviceFrame | None = None,
    marker: FloatArray | None = None,
) -> DeviceSetup | None:
    """Check measured data for ``model`` and set up the registration of device-frame data.

    :func:`check_data`; for device-frame positions the registration and marker offset
    (:func:`~rfsw_plan.elastostatics.registration.prepare_device_setup`: held where given,
    else fitted with everything else) and :func:`check_registered` on the registered data.

    Args:
        model: The robot model.
        data: The measurements.
        held: A known registration (default: the robot file's ``[device_frame]``, if any;
            one that says ``registration = "each_file"`` is registered again on ``data``,
            its marker held).
        marker: A known marker offset in the tool frame [m], shape (3,).

    Returns:
        The set-up, or None for base-frame data.

    Raises:
        InputError: Data that cannot belong to this robot in these units (one line).
    """
    check_data(model, data)
    if data.frame != "device":
        return None
    own = model.robot.description.device_frame
    if held is None and own is not None and own.each_file:
        # The device was set up anew for this file: register it again, hold the marker.
        setup = prepare_device_setup(model, data, None, own.marker if marker is None else marker)
    else:
        setup = prepare_device_setup(model, data, held if held is not None else own, marker)
    check_registered(setup.model(model), setup.data(data))
    return setup
