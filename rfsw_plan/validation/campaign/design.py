"""What to measure next: a campaign designed so that the model and the named effects are
identifiable (``rfsw-plan design-campaign``).

The design picks N samples from a pool of candidates: reachable campaign poses
(:func:`~rfsw_plan.validation.campaign.simulation.campaign_poses`), each with one load from a set of
directions and both signs (or none), and, where an effect depends on the side of a joint's
play, each approach direction of that joint. The criterion is FIGAROH's (its
``BaseOptimalCalibration``: maximise det(sum_i w_i R_i^T R_i) over the candidates'
regressors R_i): D-optimality of the identification Jacobian A (d position / d parameters, 3
rows per sample, :func:`~rfsw_plan.elastostatics.identification.position_jacobian`) with its
columns scaled to unit norm over the pool, so that mm and kg do not weigh against each other;
an effect that is a constant joint offset when seen from one side (a play, a hysteresis loop:
:attr:`~rfsw_plan.elastostatics.effects.base.Effect.offset_like`) brings its joint's zero
offset as a nuisance column, so that the design shows both sides.
FIGAROH solves the convex relaxation in the weights with an SOCP and keeps the samples of
large weight; here the N samples are chosen greedily, one at a time, each maximising

    log det(M + R_i^T R_i) = log det M + log det(I_3 + R_i M^-1 R_i^T),

(the classical sequential D-optimal design; M starts as a small ridge), with at most one
sample per pose. The result states the condition number and log det of the selected Jacobian
and of a random selection of the same size from the same pool, for comparison.

Joint values are written as controller axis values in degrees, loads as the force to apply at
the TCP in the base frame [N], the approach as ``dir_qN`` (+1: reach the pose with joint N
moving up, -1: moving down, 0: either, where the load torque decides the side of the play)
for the joints whose play the campaign must show: the columns of a
measurement file (docs/formats/measurements.md), to which the user adds the measured
positions.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray, PoseBatch
from rfsw_plan.elastostatics.identification import position_jacobian
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import InputError
from rfsw_plan.files import write_json, write_text
from rfsw_plan.numfmt import fixed, general
from rfsw_plan.robot.kinematics import Robot
from rfsw_plan.validation.campaign.simulation import campaign_poses
from rfsw_plan.validation.workbench import check_effect_labels

#: Candidate poses in the pool per designed pose (at least POOL_MIN).
POOL_PER_POSE = 12
POOL_MIN = 120
#: Load directions of the pool (base frame), each with both signs, and no load.
LOAD_DIRECTIONS = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
#: Force noise assumed for the side of a play (a load cell's 1 sigma) [N].
FORCE_NOISE_N = 5.0
#: Ridge of the start information matrix (scaled columns).
RIDGE = 1e-6


@dataclass(frozen=True)
class DesignRequest:
    """What to design.

    Attributes:
        robot: The robot (its model: joint compliance and the effects of its file).
        poses: Number of poses N (one sample each).
        effects: Effect labels to make identifiable besides the model's own parameters.
        load_n: Force to apply [N].
        seed: Seed of the pose pool and of the random comparison.
    """

    robot: Robot
    poses: int
    effects: tuple[str, ...] = ()
    load_n: float = 2000.0
    seed: int = 0


@dataclass(frozen=True)
class CampaignDesign:
    """A designed campaign (module docstring).

    Attributes:
        request: What was asked.
        labels: The model's effects, the requested ones included.
        q: Joint values [rad], shape (N, n).
        force: Force to apply at the TCP, base frame [N], shape (N, 3).
        approach: Approach direction of each joint (+1 up, -1 down, 0 any), shape (N, n).
        play_joints: 0-based joints whose approach is written (their play needs it).
        log_det: log det(A^T A) of the selected, column-scaled Jacobian.
        condition: Its condition number.
        random_log_det: The same for a random selection of N samples from the pool.
        random_condition: Its condition number.
        n_params: Parameters of the model.
        unseen: Parameters no sample of such a campaign moves the TCP with (the joint
            compliances of an unloaded one): left out of the criterion.
    """

    request: DesignRequest
    labels: tuple[str, ...]
    q: FloatArray = field(repr=False)
    force: FloatArray = field(repr=False)
    approach: FloatArray = field(repr=False)
    play_joints: tuple[int, ...]
    log_det: float
    condition: float
    random_log_det: float
    random_condition: float
    n_params: int
    unseen: tuple[str, ...] = ()

    def to_json(self) -> dict[str, Any]:
        """Summary (numbers as computed; joint values in the CSV)."""
        return {"robot": self.request.robot.name, "poses": int(self.q.shape[0]),
                "effects": list(self.labels), "n_params": self.n_params,
                "criterion": "D-optimality of the column-scaled identification Jacobian",
                "log_det": _num(self.log_det), "condition_number": _num(self.condition),
                "random_log_det": _num(self.random_log_det),
                "random_condition_number": _num(self.random_condition),
                "load_N": self.request.load_n, "seed": self.request.seed,
                "approach_joints": [f"j{j + 1}" for j in self.play_joints],
                "not_seen": list(self.unseen)}

    def csv_text(self) -> str:
        """The campaign as a measurement-file CSV without the measured columns."""
        n = self.q.shape[1]
        head = ["pose_id", *(f"q{j + 1}_deg" for j in range(n)), "fx_N", "fy_N", "fz_N",
                "mx_Nm", "my_Nm", "mz_Nm"]
        dirs = bool(self.play_joints)
        if dirs:
            head += [f"dir_q{j + 1}" for j in range(n)]
        lines = [",".join(head)]
        for i in range(self.q.shape[0]):
            row = [f"D{i + 1:03d}", *(fixed(np.degrees(v), 6) for v in self.q[i]),
                   *(fixed(f, 1) for f in self.force[i]), "0", "0", "0"]
            if dirs:
                row += [str(int(a)) for a in self.approach[i]]
            lines.append(",".join(row))
        return "\n".join(lines) + "\n"

    def write(self, folder: str | Path) -> tuple[Path, Path]:
        """Write ``design.csv`` and ``design.json`` into ``folder``; returns their paths."""
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        csv = write_text(out / "design.csv", self.csv_text())
        js = write_json(out / "design.json", self.to_json())
        return csv, js

    def text(self) -> str:
        """What the command prints."""
        return (f"designed {self.q.shape[0]} poses for {self.request.robot.name} "
                f"({', '.join(self.labels)}: {self.n_params} parameters); D-optimal: log det "
                f"{general(self.log_det, 5)}, condition number {general(self.condition, 4)} "
                f"(a random campaign of the same size: log det "
                f"{general(self.random_log_det, 5)}, condition number "
                f"{general(self.random_condition, 4)})"
                + (f"; no such campaign sees {', '.join(self.unseen)}" if self.unseen else ""))


def _num(x: float) -> float | None:
    """A finite number, or None (a singular design: log det -inf, condition inf)."""
    return float(x) if np.isfinite(x) else None


@dataclass(frozen=True)
class _Pool:
    pose: np.ndarray  # pose index of each candidate
    q: FloatArray
    force: FloatArray
    approach: FloatArray
    A: FloatArray  # (m, 3, p), columns scaled
    unseen: tuple[str, ...]  # parameters no candidate moves the TCP with (dropped from A)


def _pool(model: ElastostaticModel, request: DesignRequest, play: tuple[int, ...],
          rng: np.random.Generator) -> _Pool:
    robot = model.robot
    n_pose = max(POOL_MIN, POOL_PER_POSE * request.poses)
    qp = campaign_poses(robot, n_pose, rng)
    loads = [np.zeros(3)] + ([s * request.load_n * d for d in LOAD_DIRECTIONS for s in (1, -1)]
                             if request.load_n > 0 else [])
    approaches = [np.zeros(robot.nq)]
    if play:
        approaches = []
        for signs in itertools.product((1.0, -1.0), repeat=len(play)):
            a = np.zeros(robot.nq)
            a[list(play)] = signs
            approaches.append(a)
    rows = [(i, f, a) for i in range(n_pose) for f in loads for a in approaches]
    pose = np.array([r[0] for r in rows])
    q = qp[pose]
    force = np.array([r[1] for r in rows])
    approach = np.array([r[2] for r in rows])
    wrench = np.concatenate([force, np.zeros_like(force)], axis=1)
    batch = PoseBatch.from_q(robot, q, approach, force_noise=FORCE_NOISE_N)
    A = position_jacobian(model, batch, wrench, model.effects)
    # A play seen from one side is the joint's zero offset: its offset is a nuisance column.
    offsets = sorted({e.joint for e in model.effects if e.offset_like and e.joint is not None})
    if offsets:
        A = np.concatenate([A, batch.J[:, :3, offsets]], axis=2)
    scale = np.sqrt(np.sum(A**2, axis=(0, 1)))
    seen = scale > 1e-12 * max(float(scale.max()), 1e-300)
    names = [f"{e.label}.{n}" for e in model.effects for n in e.param_names()]
    names += [f"zero offset of joint {j + 1}" for j in offsets]
    return _Pool(pose, q, force, approach, A[:, :, seen] / scale[seen],
                 tuple(n for n, v in zip(names, seen, strict=True) if not v))


def _approach_needed(pool: _Pool, k: int, play: tuple[int, ...]) -> FloatArray:
    """Candidate k's approach, 0 for the joints where it does not change the regressor (the
    load torque decides the side there)."""
    a = pool.approach[k].copy()
    same = (pool.pose == pool.pose[k]) & np.all(pool.force == pool.force[k], axis=1)
    for j in play:
        flip = pool.approach[k].copy()
        flip[j] = -flip[j]
        other = np.flatnonzero(same & np.all(pool.approach == flip, axis=1))
        if other.size and np.allclose(pool.A[other[0]], pool.A[k], rtol=0.0, atol=1e-12):
            a[j] = 0.0
    return a


def _criteria(A: FloatArray) -> tuple[float, float]:
    """(log det(A^T A), condition number) of the stacked (m, 3, p) Jacobian."""
    M = A.reshape(-1, A.shape[2])
    sv = np.linalg.svd(M, compute_uv=False)
    if sv[-1] <= 0:
        return float("-inf"), float("inf")
    return float(2.0 * np.sum(np.log(sv))), float(sv[0] / sv[-1])


def _greedy(pool: _Pool, n: int) -> list[int]:
    """Sequential D-optimal choice of n candidates, one per pose (module docstring)."""
    p = pool.A.shape[2]
    M = RIDGE * np.eye(p)
    chosen: list[int] = []
    free = np.ones(len(pool.pose), dtype=bool)
    for _ in range(n):
        Minv = np.linalg.inv(M)
        S = np.einsum("mip,pq,mjq->mij", pool.A, Minv, pool.A)
        gain = np.linalg.slogdet(np.eye(3)[None] + S)[1]
        gain[~free] = -np.inf
        k = int(np.argmax(gain))
        chosen.append(k)
        free &= pool.pose != pool.pose[k]
        M = M + pool.A[k].T @ pool.A[k]
    return chosen


def _model(request: DesignRequest) -> tuple[ElastostaticModel, tuple[int, ...]]:
    """The model with the requested effects, and the joints whose approach matters."""
    if not request.load_n >= 0:
        raise InputError("load_n", "", f"{request.load_n:g}",
                         "a force >= 0 N (0: an unloaded campaign)")
    model = ElastostaticModel(request.robot)
    for label in check_effect_labels(model, request.effects):
        model = model.with_effect(label)
    play = tuple(sorted({e.joint for e in model.effects
                         if e.uses_approach and e.joint is not None}))
    return model, play


def run(request: DesignRequest) -> CampaignDesign:
    """Design the campaign (module docstring).

    Raises:
        InputError: Fewer poses than needed for the parameters, a bad effect label or load.
        UnreachableError: The robot cannot be posed as a campaign needs.
    """
    model, play = _model(request)
    n_params = sum(e.params.size for e in model.effects) + len(
        {e.joint for e in model.effects if e.offset_like})
    need = -(-n_params // 3)
    if request.poses < need:
        raise InputError("poses", "", f"{request.poses}",
                         f"at least {need} poses for the {n_params} parameters of "
                         f"{', '.join(model.labels)} (3 measured coordinates each; a play "
                         "counts its joint's zero offset too)")
    rng = np.random.default_rng(request.seed)
    pool = _pool(model, request, play, rng)
    chosen = _greedy(pool, request.poses)
    log_det, cond = _criteria(pool.A[chosen])
    rand = _random_pick(pool, request.poses, rng)
    r_log_det, r_cond = _criteria(pool.A[rand])
    approach = np.array([_approach_needed(pool, k, play) for k in chosen])
    return CampaignDesign(request, tuple(model.labels), pool.q[chosen], pool.force[chosen],
                          approach, play, log_det, cond, r_log_det, r_cond, n_params,
                          pool.unseen)


def _random_pick(pool: _Pool, n: int, rng: np.random.Generator) -> list[int]:
    """n random candidates of n different poses."""
    poses = rng.choice(int(pool.pose.max()) + 1, size=n, replace=False)
    return [int(rng.choice(np.flatnonzero(pool.pose == i))) for i in poses]


def random_campaign(request: DesignRequest, seed: int) -> CampaignDesign:
    """A random campaign of ``request.poses`` samples from the design's pool (one per pose,
    each with a random load and approach): what the design is compared with."""
    model, play = _model(request)
    pool = _pool(model, request, play, np.random.default_rng(request.seed))
    pick = _random_pick(pool, request.poses, np.random.default_rng(seed))
    log_det, cond = _criteria(pool.A[pick])
    return CampaignDesign(request, tuple(model.labels), pool.q[pick], pool.force[pick],
                          pool.approach[pick], play, log_det, cond, log_det, cond,
                          sum(e.params.size for e in model.effects), pool.unseen)


__all__ = ["CampaignDesign", "DesignRequest", "random_campaign", "run"]
