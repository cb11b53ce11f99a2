"""Synthetic load campaigns with hidden effects: data on which the validator must find them.

A *truth model* is the robot's elastostatic model plus one or more hidden effects from the
library (:data:`rfsw_plan.elastostatics.effects.EFFECTS`) with given or randomised plausible
parameters. The campaign poses the robot the way a stiffness campaign would (tool roughly down,
in front of the robot, inside reach and joint limits, away from singularities), applies a set
of wrenches per pose and records

    x_meas = FK(q) + dX_truth(q, F_logged)[:3] + drift(t) + N(0, noise^2)   (base frame [m]).

One hidden effect is deliberately *not* in the library: ``thermal_drift``, a TCP drift that
grows linearly with time (warm-up of the arm), with a ``temperature_C`` column that follows it.
No library effect can explain it, so the validator must answer ``unexplained``.

Per pose, the ``loads_per_pose`` samples are: a zero-load sample first; with three or more
samples, a zero-load repeat last (repeated samples give the noise floor); in between, wrench
pairs ``+W, -W`` (W: a force of 1-5 kN in a random direction plus moments of ~100 N m), so
every joint torque changes sign within the pose (backlash is identifiable).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from rfsw_plan.elastostatics.approach import approach_directions, load_changes, load_history
from rfsw_plan.elastostatics.effects import EFFECTS, PoseBatch, parse_effect_label
from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError, UnknownNameError, UnreachableError
from rfsw_plan.progress import progress
from rfsw_plan.robot.description import RobotDescription
from rfsw_plan.robot.kinematics import Robot, load_robot

log = logging.getLogger(__name__)

#: The hidden effect that is not in the library (a slow drift with time).
THERMAL_DRIFT = "thermal_drift"
#: Its parameters: drift rate [mm/h] and drift direction (base frame, normalised).
THERMAL_DRIFT_PARAMS = ("rate_mm_per_h", "dir_x", "dir_y", "dir_z")
#: Temperature rise that goes with the drift [K/h] (``temperature_C`` column).
HEATING_K_PER_H = 2.0
#: Ambient temperature at the start of a campaign [deg C].
AMBIENT_C = 21.5

#: Tool axis within this angle of straight down [deg].
TOOL_DOWN_DEG = 35.0
#: Azimuth of the TCP within +- this angle of the base x axis ("in front") [deg].
FRONT_DEG = 60.0
#: Joint-limit margin of the sampled poses [deg].
LIMIT_MARGIN_DEG = 5.0
#: Upper bound on the condition number of the TCP Jacobian (translation rows / reach).
MAX_CONDITION = 30.0
#: Force magnitude range of the loaded samples [N].
FORCE_RANGE_N = (1000.0, 5000.0)
#: 1-sigma of each moment component of the loaded samples [N m].
MOMENT_SIGMA_NM = 100.0
#: Dwell per sample and move time between poses [s].
DWELL_S, MOVE_S = 8.0, 40.0
#: A randomised hidden effect whose RMS contribution would be below this multiple of the
#: noise (or below :data:`MIN_VISIBLE_MM`) is scaled up to it, so that it can be found.
VISIBILITY_FACTOR = 10.0
MIN_VISIBLE_MM = 0.05

HiddenSpec = tuple[str, Mapping[str, float] | None]


@dataclass(frozen=True)
class CampaignResult:
    """A simulated campaign and the truth behind it.

    Attributes:
        data: The measurement set (what a real campaign would log).
        truth: The truth model (robot model plus the hidden library effects).
        hidden: Hidden effects with the parameter values used [SI; thermal drift in mm/h].
        contribution_rms_mm: RMS of each hidden effect's contribution to the measured position
            over the campaign [mm] (truth with minus truth without it).
    """

    data: MeasurementSet
    truth: ElastostaticModel
    hidden: dict[str, dict[str, float]] = field(default_factory=dict)
    contribution_rms_mm: dict[str, float] = field(default_factory=dict)


# -- parsing ------------------------------------------------------------------------------------
_PARAM = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*:\s*([^,:]+?)\s*$")


def parse_hidden(spec: str, n_joints: int, source: str = "hidden") -> HiddenSpec:
    """Parse ``EFFECT[:jN][=name:value,name:value]`` into (label, params or None).

    Values are in the effect's SI units (rad, m, kg, N, N m, kg m); ``thermal_drift`` takes
    ``rate_mm_per_h`` [mm/h] and an optional direction ``dir_x, dir_y, dir_z`` (base frame).
    Example: ``payload_gravity=m:150,m_rz:-37.5``, ``joint_backlash:j2=b:3e-4``.

    Raises:
        UnknownNameError: Unknown effect (lists the library effects and thermal_drift).
        InputError: Bad joint index, malformed or non-numeric parameter.
    """
    label, _, rest = spec.partition("=")
    label = label.strip()
    check_hidden_label(label, n_joints, source)
    if not rest.strip():
        return label, None
    params: dict[str, float] = {}
    for item in rest.split(","):
        m = _PARAM.match(item)
        if not m:
            raise InputError(source, spec, f"cannot read parameter '{item.strip()}'",
                             "name:value pairs separated by commas, e.g. m:150,m_rz:-37.5")
        try:
            value = float(m.group(2))
        except ValueError:
            raise InputError(source, f"{label}.{m.group(1)}", f"'{m.group(2)}' is not a number"
                             ) from None
        if not np.isfinite(value):
            raise InputError(source, f"{label}.{m.group(1)}", "value is not finite")
        params[m.group(1)] = value
    return label, params


def check_hidden_label(label: str, n_joints: int, source: str = "hidden") -> None:
    """Validate a hidden-effect label (library effect with joint, or ``thermal_drift``)."""
    if label == THERMAL_DRIFT:
        return
    name = label.split(":")[0]
    if name not in EFFECTS:
        raise UnknownNameError("hidden effect", name, [*EFFECTS, THERMAL_DRIFT])
    parse_effect_label(label, n_joints)


# -- poses and loads ----------------------------------------------------------------------------
def campaign_poses(robot: Robot, n: int, rng: np.random.Generator) -> FloatArray:
    """Joint values [rad], shape (n, nq), of a load campaign.

    Samples joints uniformly inside the limits (less :data:`LIMIT_MARGIN_DEG`; joint 1 within
    +-:data:`FRONT_DEG`) and keeps poses with the tool axis within :data:`TOOL_DOWN_DEG` of
    straight down, the TCP in front of the robot (azimuth within +-FRONT_DEG, horizontal
    distance 35-90 % of the tool-down reach, height from 0.1 m to 0.6 m above the shoulder)
    and a well-conditioned Jacobian. No IK: joints are sampled, the TCP is checked with FK.

    Raises:
        UnreachableError: Fewer than n such poses found (robot cannot reach the region).
    """
    d = robot.description
    margin = np.radians(LIMIT_MARGIN_DEG)
    wide = np.full(robot.nq, np.pi)
    wide[0] = np.radians(FRONT_DEG)
    lo = np.maximum(d.lower + margin, -wide)
    hi = np.minimum(d.upper - margin, wide)
    shoulder_z = float(robot.joint_frames(np.zeros(robot.nq))[min(1, robot.nq - 1), 2, 3])
    cos_down = np.cos(np.radians(TOOL_DOWN_DEG))
    chunk = 8192
    reach = 0.0
    kept: list[FloatArray] = []
    count = 0
    for _ in range(400):
        Q = rng.uniform(lo, hi, (chunk, robot.nq))
        T, J = robot.batch_fk_jacobian(Q)
        down = -T[:, 2, 2] >= cos_down
        p = T[:, :3, 3]
        radius = np.hypot(p[:, 0], p[:, 1])
        if reach == 0.0:
            reach = float(np.max(radius[down])) if np.any(down) else 0.0
            if reach == 0.0:
                continue
        ok = down & (radius > 0.35 * reach) & (radius < 0.9 * reach)
        ok &= np.abs(np.degrees(np.arctan2(p[:, 1], p[:, 0]))) <= FRONT_DEG
        ok &= (p[:, 2] > 0.1) & (p[:, 2] < shoulder_z + 0.6)
        if np.any(ok):
            Js = J[ok].copy()
            Js[:, :3, :] /= reach
            good = np.linalg.cond(Js) < MAX_CONDITION
            kept.append(Q[ok][good])
            count += int(good.sum())
        if count >= n:
            return np.concatenate(kept)[:n]
    raise UnreachableError(
        f"robot {robot.name}: found only {count} of {n} tool-down poses in front of the robot"
    )


def campaign_wrenches(
    n_poses: int, loads_per_pose: int, rng: np.random.Generator
) -> FloatArray:
    """Logged wrenches [N, N m], base frame, shape (n_poses * loads_per_pose, 6).

    Per pose: zero load, read twice in a row (with >= 3 samples: a repeat at the same load
    step, adjacent in time, gives the noise floor), then +W/-W pairs (W: force 1-5 kN in a
    random direction, moments N(0, 100 N m) per axis).
    """
    M = loads_per_pose
    W = np.zeros((n_poses, M, 6))
    loaded = list(range(2 if M >= 3 else 1, M))
    for k in range(0, len(loaded), 2):
        u = rng.normal(size=(n_poses, 3))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        w = np.concatenate(
            [u * rng.uniform(*FORCE_RANGE_N, (n_poses, 1)),
             rng.normal(size=(n_poses, 3)) * MOMENT_SIGMA_NM], axis=1)
        W[:, loaded[k]] = w
        if k + 1 < len(loaded):
            W[:, loaded[k + 1]] = -w
    return W.reshape(n_poses * M, 6)


def _positions(model: ElastostaticModel, batch: PoseBatch, wrench: FloatArray) -> FloatArray:
    return batch.T[:, :3, 3] + model.deflection_batch(batch, wrench)[:, :3]


def _without(model: ElastostaticModel, label: str) -> ElastostaticModel:
    return ElastostaticModel(model.robot, [e for e in model.copy().effects if e.label != label])


def _rms_mm(d: FloatArray) -> float:
    return float(np.sqrt(np.mean(d**2)) * 1e3)


# -- the campaign -------------------------------------------------------------------------------
def run_campaign(
    robot_or_model: Robot | RobotDescription | ElastostaticModel | str,
    hidden: Sequence[HiddenSpec | str] = (),
    poses: int = 40,
    loads_per_pose: int = 8,
    noise_mm: float = 0.01,
    seed: int = 0,
) -> CampaignResult:
    """Simulate a load campaign of a truth model with hidden effects.

    Args:
        robot_or_model: The robot (bundled name, file, description, Robot) or a model; the
            truth is its elastostatic model (with the effects in its description) plus
            ``hidden``.
        hidden: Hidden effects as (label, params or None) or ``"label[=k:v,...]"`` strings;
            None draws the effect's random plausible values
            (:meth:`~rfsw_plan.elastostatics.effects.Effect.plausible_params`), scaled up, if
            needed, to at least :data:`VISIBILITY_FACTOR` x noise RMS unless the physics fixes
            their size (:attr:`~rfsw_plan.elastostatics.effects.Effect.fixed_size`: Kc keeps
            its gain 1). Given params are SI; missing ones take the effect's prior.
        poses: Number of poses N.
        loads_per_pose: Samples per pose M (>= 1), see the module docstring.
        noise_mm: 1-sigma position noise per axis [mm].
        seed: Random seed (poses, loads, parameters, noise).

    Raises:
        InputError: Bad counts, noise, parameter, an effect hidden twice or already in the
            model.
        UnknownNameError: Unknown effect name.
        UnreachableError: The robot cannot be posed as a campaign needs.
    """
    _check_counts(poses, loads_per_pose, noise_mm)
    truth, specs = _truth_and_hidden(robot_or_model, hidden)
    robot = truth.robot
    rng = np.random.default_rng(seed)
    q_pose = campaign_poses(robot, poses, rng)
    M = loads_per_pose
    q = np.repeat(q_pose, M, axis=0)
    wrench = campaign_wrenches(poses, M, rng)
    pose_idx = np.repeat(np.arange(poses), M)
    t = pose_idx * MOVE_S + np.arange(poses * M) * DWELL_S
    # The samples in time order: the robot moves pose to pose, so each joint's approach
    # direction is in the order (lost motion needs it).
    approach = approach_directions(q, t)
    batch = PoseBatch.from_q(robot, q, approach, load_change=load_changes(q, wrench, t),
                             load_history=load_history(q, wrench, t))
    visible_mm = max(VISIBILITY_FACTOR * noise_mm, MIN_VISIBLE_MM)
    truth, used = _hide(truth, specs, batch, wrench, rng, visible_mm)

    position = _positions(truth, batch, wrench)
    contrib = {
        lab: _rms_mm(position - _positions(_without(truth, lab), batch, wrench))
        for lab in used if lab != THERMAL_DRIFT
    }
    # Ambient: a 20-minute air-conditioning cycle of +-0.3 K, not a trend.
    temperature = AMBIENT_C + 0.3 * np.sin(2 * np.pi * t / 1200.0 + rng.uniform(0, 2 * np.pi))
    if THERMAL_DRIFT in used:
        drift = _drift(used[THERMAL_DRIFT], t)
        position = position + drift
        contrib[THERMAL_DRIFT] = _rms_mm(drift)
        temperature = AMBIENT_C + HEATING_K_PER_H * t / 3600.0
    temperature = temperature + rng.normal(0.0, 0.05, t.size)
    for lab, v in contrib.items():
        if v < 3.0 * noise_mm:
            log.warning("hidden %s contributes %.3g mm RMS, below 3x the noise (%.3g mm)",
                        lab, v, noise_mm)
    position = position + rng.normal(0.0, abs(noise_mm) * 1e-3, position.shape)  # abs: -0.0
    pose_id: NDArray[np.str_] = np.array([f"P{i + 1:04d}" for i in pose_idx])
    data = MeasurementSet(
        q=q, wrench=wrench, position=position, t=t, pose_id=pose_id,
        extra={"temperature_C": temperature}, source="<simulated campaign>",
        approach=approach, load_change=batch.load_change, load_history=batch.load_history,
    )
    return CampaignResult(data=data, truth=truth, hidden=used, contribution_rms_mm=contrib)


def _check_counts(poses: int, loads_per_pose: int, noise_mm: float) -> None:
    if poses < 1:
        raise InputError("poses", "", f"{poses}", "at least 1 pose")
    if loads_per_pose < 1:
        raise InputError("loads_per_pose", "", f"{loads_per_pose}", "at least 1 sample")
    if not np.isfinite(noise_mm) or noise_mm < 0:
        raise InputError("noise_mm", "", f"{noise_mm}", "a noise >= 0 mm")


def _truth_and_hidden(
    robot_or_model: Robot | RobotDescription | ElastostaticModel | str,
    hidden: Sequence[HiddenSpec | str],
) -> tuple[ElastostaticModel, list[HiddenSpec]]:
    """The truth's model before hiding, and the checked hidden effects."""
    if isinstance(robot_or_model, ElastostaticModel):
        truth = robot_or_model.copy()
    else:
        truth = ElastostaticModel(load_robot(robot_or_model))
    robot = truth.robot
    specs = [parse_hidden(h, robot.nq) if isinstance(h, str) else h for h in hidden]
    labels = [lab for lab, _ in specs]
    for lab, _ in specs:
        check_hidden_label(lab, robot.nq)
        if labels.count(lab) > 1:
            raise InputError("hidden", lab, "effect hidden more than once")
        if truth.has(lab):
            raise InputError("hidden", lab, f"already in the model of robot {robot.name}",
                             f"an effect the robot file does not contain (it has "
                             f"{', '.join(truth.labels)})")
    return truth, specs


def _hide(
    truth: ElastostaticModel, specs: Sequence[HiddenSpec], batch: PoseBatch, wrench: FloatArray,
    rng: np.random.Generator, visible_mm: float,
) -> tuple[ElastostaticModel, dict[str, dict[str, float]]]:
    """Add the hidden effects to the truth (random plausible values where none are given);
    returns the truth and the parameters used [SI]."""
    robot = truth.robot
    used: dict[str, dict[str, float]] = {}
    for lab, params in progress(specs, desc="campaign: hidden effects", total=len(specs),
                                unit="effect"):
        if lab == THERMAL_DRIFT:
            used[lab] = _drift_params(params, rng)
            continue
        cls, joint = parse_effect_label(lab, robot.nq)
        randomised = params is None
        eff = cls(robot, joint, params)
        if randomised:
            eff = cls(robot, joint, eff.plausible_params(batch, wrench, rng))
        truth = ElastostaticModel(robot, [*truth.effects, eff])
        if randomised and not cls.fixed_size:
            truth = _make_visible(truth, lab, batch, wrench, visible_mm)
        used[lab] = next(e for e in truth.effects if e.label == lab).param_dict()
    return truth, used


def _drift(p: Mapping[str, float], t: FloatArray) -> FloatArray:
    """The thermal drift of the TCP at times t [s] [m], base frame, shape (m, 3)."""
    u = np.array([p["dir_x"], p["dir_y"], p["dir_z"]])
    out: FloatArray = (p["rate_mm_per_h"] * 1e-3) * (t / 3600.0)[:, None] * u[None, :]
    return out


def simulate_campaign(
    robot_or_model: Robot | RobotDescription | ElastostaticModel | str,
    hidden: Sequence[HiddenSpec | str] = (),
    poses: int = 40,
    loads_per_pose: int = 8,
    noise_mm: float = 0.01,
    seed: int = 0,
) -> MeasurementSet:
    """The measurement set of :func:`run_campaign` (same arguments)."""
    return run_campaign(robot_or_model, hidden, poses, loads_per_pose, noise_mm, seed).data


def _drift_params(params: Mapping[str, float] | None, rng: np.random.Generator
                  ) -> dict[str, float]:
    out = {"rate_mm_per_h": float(rng.uniform(0.3, 0.8))}
    u = np.array([rng.normal(0, 0.3), rng.normal(0, 0.3), 1.0])
    out.update(zip(THERMAL_DRIFT_PARAMS[1:], u.tolist(), strict=True))
    for k, v in (params or {}).items():
        if k not in THERMAL_DRIFT_PARAMS:
            raise InputError("hidden", f"{THERMAL_DRIFT}.{k}", "unknown parameter",
                             ", ".join(THERMAL_DRIFT_PARAMS))
        out[k] = float(v)
    u = np.array([out["dir_x"], out["dir_y"], out["dir_z"]])
    if np.linalg.norm(u) == 0:
        raise InputError("hidden", f"{THERMAL_DRIFT}.dir", "direction is zero")
    out.update(zip(THERMAL_DRIFT_PARAMS[1:], (u / np.linalg.norm(u)).tolist(), strict=True))
    return out


def _make_visible(
    truth: ElastostaticModel, label: str, batch: PoseBatch, wrench: FloatArray, floor_mm: float
) -> ElastostaticModel:
    """Scale a randomised effect's parameters up until its RMS contribution reaches floor_mm."""
    base = _positions(_without(truth, label), batch, wrench)
    eff = next(e for e in truth.effects if e.label == label)
    for _ in range(5):  # linear effects need one step; misalignment is nearly linear
        size = _rms_mm(_positions(truth, batch, wrench) - base)
        if size >= floor_mm or size == 0.0:
            break
        eff.params = eff.params * (floor_mm / size) * 1.02
    return truth

