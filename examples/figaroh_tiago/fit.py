"""The recommended real-data fit: choose the model on the training recording, save it, score it.

Usage (from the repository root; ``fit.sh`` runs the same choice as ``rfsw-plan calibrate``;
this script prints more about it)::

    python examples/figaroh_tiago/fit.py TRAIN.csv FITTED.toml [OTHER.csv ...]

1. The physics every real arm has, fitted on TRAIN: the registration of the motion-capture
   frame and of the marker on the hand, the joint compliance under the links' weight (the
   robot file's model), and its geometry: joint zero offsets and a full geometric
   calibration of the links (``link_errors``, with a prior of its plausible size). These are
   not put to a vote: a real arm has them. What the data cannot identify is named.
2. Forward selection on TRAIN only, as ``rfsw-plan calibrate`` does it (``fit.sh`` is that
   command): the workbench's diagnosis scores every other library effect by 5-fold
   cross-validation on TRAIN; the best one whose gain is significant is added and everything
   is re-identified; repeated until no candidate is significant (at most MAX_EFFECTS).
   Identification keeps a parameter only where it is plausible (a joint softer than
   100 N m/rad, a link off by 5 mm or 3 deg, is a stand-in, not a calibration).
3. FITTED.toml: the robot with the chosen effects and the registration, which
   ``rfsw-plan validate --robot FITTED.toml --data OTHER.csv --columns
   examples/figaroh_tiago/columns.toml --frame device --json`` evaluates with no refit.
4. Each OTHER.csv is scored with nothing refitted, by posture group as FIGAROH does: postures
   repeated within 0.01 rad of a training posture, new ones inside the training joint
   ranges, and ones outside them. The held-out files are never used to choose anything.

Data: FIGAROH TIAGo recordings (Apache-2.0; credit Thanh Nguyen, CNRS, Toward SAS).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rfsw_plan.elastostatics.identification import identify, predicted_positions
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel, load_model
from rfsw_plan.elastostatics.registration import DeviceSetup, prepare_device_setup
from rfsw_plan.io.measurements import read_measurements
from rfsw_plan.validation.calibrate import CalibrationRequest, choose_effects
from rfsw_plan.validation.engine.diagnosis import make_folds
from rfsw_plan.validation.workbench import ValidationResult, save_extended_robot, validate

HERE = Path(__file__).resolve().parent
COLUMNS = HERE / "columns.toml"
ROBOT = "tiago_arm"
#: The geometry of a real arm, always fitted: joint zeros and the links' own errors.
GEOMETRY = ("kinematic_offsets", "link_errors")
#: At most this many effects are added by forward selection.
MAX_EFFECTS = 4
#: A posture repeats a training posture when every joint is within this [rad or m] (FIGAROH).
REPEAT_TOL = 0.01
#: The joint whose lost motion the FIGAROH authors name (arm_6, 1-based chain index 7).
ARM6 = 7


def read(path: str | Path, model: ElastostaticModel) -> MeasurementSet:
    """A recording in SI units, positions of point BL in the motion-capture frame."""
    r = model.robot
    return read_measurements(path, r.nq, prismatic=list(r.prismatic), columns=COLUMNS)


def choose_model(model: ElastostaticModel, train: MeasurementSet) -> ValidationResult:
    """The choice ``rfsw-plan calibrate`` makes (:func:`rfsw_plan.validation.calibrate.
    choose_effects`: the geometry, then the diagnosis's best significant effect at a time)."""
    setup = prepare_device_setup(model, train)
    request = CalibrationRequest(robot=ROBOT, data=(train.source,), geometry=GEOMETRY,
                                 max_effects=MAX_EFFECTS)
    _, chosen, steps = choose_effects(model, train, setup, request)
    for k, step in enumerate(steps):
        label = step.added if k == 0 else f"+ {step.added}"
        print(f"  {label:<50} training CV {step.cv_rms * 1e3:6.3f} mm/axis")
    return validate(model, train, add=chosen, setup=setup)


def _shown(value: float, std: float, unit: str) -> str:
    """A value and its standard error in engineering units (mrad, mm, N m/rad)."""
    if unit == "rad/(N m)":  # a compliance: its stiffness reads better
        k = 1.0 / value if value > 0 else float("inf")
        return f"stiffness {k:.3g} +- {std * k * k:.2g} N m/rad"
    scale, shown = {"rad": (1e3, "mrad"), "m": (1e3, "mm")}.get(unit, (1.0, unit or "SI"))
    return f"{value * scale:.3g} +- {std * scale:.2g} {shown}"


def carried(res: ValidationResult) -> list[str]:
    """One line per identified robot parameter: value and standard error in engineering
    units, and its note (poorly determined...); the plausibility check already held the
    implausible ones at their prior."""
    effects = {e.label: e for e in res.identification.model.effects}
    out = []
    for e in res.identification.estimates:
        eff = effects[e.effect]
        if eff.setup or not e.identified:
            continue
        flag = f"  ({e.note})" if e.note else ""
        out.append(f"  {e.effect}.{e.name} = {_shown(e.value, e.std_error, eff.param_unit(e.name))}"
                   f"{flag}")
    return out


def _cv(model: ElastostaticModel, data: MeasurementSet, free: list[str],
        plausibility: bool) -> tuple[float, dict[str, float]]:
    """5-fold CV RMS per axis [m] of a model form on base-frame data, and its full fit."""
    folds = make_folds(data, 5)
    res = np.full(data.position.shape, np.nan)
    for f in range(5):
        fit = identify(model, data.subset(folds != f), free=free, plausibility=plausibility)
        test = data.subset(folds == f)
        res[folds == f] = test.position - predicted_positions(fit.model, test)
    full = identify(model, data, free=free, plausibility=plausibility)
    values = {f"{e.effect}.{e.name}": e.value for e in full.estimates}
    return float(np.sqrt(np.nanmean(res**2))), values


@dataclass(frozen=True)
class Arm6:
    """Soft arm_6 against arm_6 lost motion, on the training recording only."""

    soft_cv: float
    soft_stiffness: float
    play_cv: float
    play: float

    def lines(self) -> list[str]:
        better = "lost motion" if self.play_cv < self.soft_cv else "a soft joint"
        return [
            "arm_6: a soft joint or lost motion? (5-fold CV on the training file, joint "
            "offsets in both)",
            f"  soft arm_6 (compliance free, no plausibility check): CV "
            f"{self.soft_cv * 1e3:.3f} mm/axis, arm_6 stiffness {self.soft_stiffness:.3g} N m/rad",
            f"  arm_6 lost motion (stiffness as in the robot file):  CV "
            f"{self.play_cv * 1e3:.3f} mm/axis, play {self.play * 1e3:.1f} mrad",
            f"  -> {better} explains the residual better",
        ]


def compare_arm6(model: ElastostaticModel, train: MeasurementSet,
                 setup: DeviceSetup) -> Arm6:
    """The FIGAROH authors' question: is arm_6's residual a soft joint or its gear play?"""
    data = setup.data(train)
    form = setup.model(model).with_effect("kinematic_offsets")
    base = ["kinematic_offsets", *setup.effect_labels]
    soft_cv, soft = _cv(form, data, ["joint_compliance", *base], plausibility=False)
    label = f"lost_motion:j{ARM6}"
    play_cv, play = _cv(form.with_effect(label), data, [label, *base], plausibility=True)
    return Arm6(soft_cv, 1.0 / soft[f"joint_compliance.c{ARM6}"], play_cv, play[f"{label}.b"])


def posture_groups(train_q: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``repeated`` / ``new in range`` / ``out of range`` of every posture of q (m, n)."""
    near = np.min(np.max(np.abs(q[:, None, :] - train_q[None]), axis=2), axis=1) <= REPEAT_TOL
    inside = np.all((q >= train_q.min(axis=0)) & (q <= train_q.max(axis=0)), axis=1)
    return np.where(near, "repeated", np.where(inside, "new in range", "out of range"))


def score(fitted: str | Path, train: MeasurementSet, other: str | Path) -> list[str]:
    """RMSE per axis and norm, and the largest norm error [mm] of point BL on ``other``,
    with everything held as fitted (registration included), by posture group."""
    model = load_model(str(fitted))
    data = read(other, model)
    held = prepare_device_setup(model, data, held=model.robot.description.device_frame)
    d = held.data(data)
    err = d.position - predicted_positions(held.model(model), d)
    norm = np.linalg.norm(err, axis=1)
    groups = posture_groups(train.q, data.q)
    out = [f"{Path(other).name}: point BL, nothing refitted [mm]",
           f"  {'postures':<14}{'n':>4}{'x':>8}{'y':>8}{'z':>8}{'norm':>8}{'max':>8}"]
    for name in ("all", "repeated", "new in range", "out of range"):
        sel = np.ones(len(d), bool) if name == "all" else groups == name
        if not sel.any():
            continue
        axes = np.sqrt(np.mean(err[sel] ** 2, axis=0)) * 1e3
        out.append(f"  {name:<14}{int(sel.sum()):>4}" + "".join(f"{v:8.2f}" for v in axes)
                   + f"{np.sqrt(np.mean(norm[sel] ** 2)) * 1e3:8.2f}"
                   f"{norm[sel].max() * 1e3:8.2f}")
    return out


def main(argv: list[str]) -> int:
    if len(argv) < 3:
        print(__doc__.split("\n\n")[1], file=sys.stderr)
        return 2
    train_path, fitted = argv[1], argv[2]
    model = load_model(ROBOT)
    train = read(train_path, model)
    print(f"choosing the model on {Path(train_path).name} ({len(train)} postures):")
    res = choose_model(model, train)
    path = save_extended_robot(res, fitted)
    print(f"wrote {path}")
    print("what carried the gain (identified robot parameters, +- 1 standard error):")
    print("\n".join(carried(res)))
    assert res.setup is not None
    print("\n".join(compare_arm6(model, train, res.setup).lines()))
    for other in argv[3:]:
        print("\n".join(score(fitted, train, other)))
    return 0


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("train", help="training recording (CSV)")
    ap.add_argument("fitted", help="robot file to write (TOML)")
    ap.add_argument("other", nargs="*", help="held-out recordings to score")
    a = ap.parse_args()
    sys.exit(main([sys.argv[0], a.train, a.fitted, *a.other]))
