"""Lab-style measurement campaigns generated outside the project (issue 34).

Nothing of the project's campaign or effect code is used: the truth is written here in plain
numpy on the robot's Pinocchio model (the kinematic chain of the robot file, nothing else).
A lab moves the robot from pose to pose in a random order, reads a laser tracker at every
pose without load, then under a cable pull in several directions (each direction and its
reverse), then without load again. Gear play in joint N puts the joint's output half the play
off its encoder:

* under a clear load, on the flank the load torque presses it to: dq_N = +b/2 sign(tau_N);
* without one, on the flank the last clear load at this pose pressed it to (friction holds
  it there, issue 40), or before any, the flank its last motion left it on (the output lags
  the motor): dq_N = -b/2 a_N, a_N the sign of the joint's last move.

The TCP position is the exact forward kinematics at q + C J^T F + dq (joint compliance
C = diag(1/k) of the robot file), plus the tracker's Gaussian noise. The CSV is written with
the csv module in the documented measurement format (joint values in degrees, wrench in N and
N m, positions in mm, time in s).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from rfsw_plan.robot.kinematics import load_robot


@dataclass(frozen=True)
class LabCampaign:
    """What was generated.

    Attributes:
        path: The CSV file.
        n_samples: Rows.
        play_mm: RMS of the play's effect on the TCP [mm].
    """

    path: Path
    n_samples: int
    play_mm: float


def lab_campaign(
    robot_name: str, out: Path, *, play_joint: int, play_rad: float, poses: int = 30,
    force_n: float = 2000.0, loaded: bool = True, noise_mm: float = 0.01,
    force_noise_n: float = 5.0, seed: int = 0, approach_columns: bool = False,
    offsets_rad: tuple[float, ...] = (), from_below_only: bool = False,
) -> LabCampaign:
    """Write a lab campaign with gear play of ``play_rad`` [rad] in joint ``play_joint``
    (0-based) to ``out`` (module docstring).

    Args:
        robot_name: A bundled robot (its kinematic chain and joint stiffness).
        out: CSV file to write.
        play_joint: Joint with play, 0-based.
        play_rad: Total play [rad].
        poses: Poses visited.
        force_n: Cable pull [N] (``loaded``: +-x, +-y of the base, then -z).
        loaded: Load the robot at every pose (else an unloaded ISO 9283-style campaign whose
            poses are reached from both directions).
        noise_mm: Tracker noise, 1 sigma per axis [mm].
        force_noise_n: Load cell noise per axis [N].
        seed: Random seed.
        approach_columns: Also write ``dir_qN`` columns (the approach of each joint).
        offsets_rad: A second effect: zero offsets of the joints [rad] (the encoders' zeros
            are off by these), shape (n,) or empty.
        from_below_only: Unloaded: reach every pose from below only (one flank of the play).
    """
    rng = np.random.default_rng(seed)
    robot = load_robot(robot_name)
    model = robot.model
    data = model.createData()
    tcp = model.getFrameId("tcp") if model.existFrame("tcp") else model.nframes - 1
    G = np.asarray(robot.description.coupling, dtype=float)
    k = np.asarray(robot.description.stiffness, dtype=float)
    lo = np.asarray(robot.description.lower, dtype=float)
    hi = np.asarray(robot.description.upper, dtype=float)
    n = G.shape[0]

    def fk_jac(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        qc = G @ q
        J = pin.computeFrameJacobian(model, data, qc, tcp, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        pin.updateFramePlacement(model, data, tcp)
        return data.oMf[tcp].translation.copy(), J @ G

    # Poses: anywhere in the middle half of every joint's range where the TCP is in front of
    # the robot at working height and the wrist is away from its singularity.
    mid, half = (lo + hi) / 2, (hi - lo) / 4
    targets: list[np.ndarray] = []
    while len(targets) < poses:
        q = mid + rng.uniform(-1, 1, n) * half
        p, J = fk_jac(q)
        if (np.linalg.svd(J, compute_uv=False)[-1] > 1e-2 and np.hypot(p[0], p[1]) > 1.0
                and 0.2 < p[2] < 2.5):
            targets.append(q)
    if loaded:
        pulls = [np.array(v, dtype=float) * force_n for v in
                 ([1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, -1])]
    else:
        pulls = []
    rows: list[dict[str, str]] = []
    play_moves: list[np.ndarray] = []
    t = 0.0
    last = np.zeros(n)
    here = targets[0].copy()
    for i, q in enumerate(targets):
        # Unloaded: reach each pose from both sides (or from below only).
        visits = [q] if loaded else [q] if from_below_only else [q, q]
        for v, qv in enumerate(visits):
            if not loaded:
                # Come from below on the first visit and from above on the second.
                via = qv + (-1 if v == 0 else 1) * np.radians(5.0) * np.ones(n)
                d = via - here
                last = np.where(np.abs(d) > 1e-9, np.sign(d), last)
                here = via
            d = qv - here
            last = np.where(np.abs(d) > 1e-9, np.sign(d), last)
            here = qv.copy()
            held = 0.0  # the flank the last clear load at this visit pushed the output to
            for F3 in [np.zeros(3), np.zeros(3), *pulls, np.zeros(3)]:
                W = np.concatenate([F3, np.zeros(3)])
                _, J = fk_jac(qv)
                tau = J.T @ W
                dq = tau / k + (np.asarray(offsets_rad) if len(offsets_rad) else 0.0)
                # A clear load (50 N m) presses the output to a flank; else the last move.
                if abs(tau[play_joint]) > 50.0:
                    held = float(np.sign(tau[play_joint]))
                side = held if held else -last[play_joint]
                dq_play = np.zeros(n)
                dq_play[play_joint] = 0.5 * play_rad * side
                pin.framesForwardKinematics(model, data, G @ (qv + dq + dq_play))
                p = data.oMf[tcp].translation.copy()
                pin.framesForwardKinematics(model, data, G @ (qv + dq))
                play_moves.append(p - data.oMf[tcp].translation)
                p_meas = p + rng.normal(0, noise_mm * 1e-3, 3)
                w_log = (W + np.concatenate([rng.normal(0, force_noise_n, 3), np.zeros(3)])
                         if loaded else W)
                row = {"t_s": f"{t:.3f}", "pose_id": f"L{i + 1:03d}"}
                row |= {f"q{j + 1}_deg": f"{np.degrees(qv[j]):.8f}" for j in range(n)}
                row |= {c: f"{x:.4f}" for c, x in zip(
                    ("fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"), w_log, strict=True)}
                row |= {c: f"{x * 1e3:.5f}" for c, x in zip(("x_mm", "y_mm", "z_mm"), p_meas,
                                                              strict=True)}
                if approach_columns:
                    row |= {f"dir_q{j + 1}": f"{int(last[j]):d}" for j in range(n)}
                rows.append(row)
                t += 6.0
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    moves = np.array(play_moves)
    return LabCampaign(out, len(rows), float(np.sqrt(np.mean(moves**2))) * 1e3)
