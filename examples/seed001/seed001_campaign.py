"""Seed 001's joint-stiffness campaign (§2.2.2, Table 2 -> Table 3), simulated and identified.

The paper ties the ZK-500's end-effector to the workbench with a steel cable through its
six-axis force sensor (SRI M4347D1, 15 kN / 6 kN m), poses the robot in the five poses of
Table 2, tensions the cable with several loads per pose, averages about 50 sensor samples over
about 5 s per reading, and fits the joint compliances by least squares (eq. 7-11):

    dX = J K^-1 J^T F,     F = T u at the attachment point, u: unit vector towards the anchor.

This module rebuilds that campaign on ``robots/zk500`` with its Table 3 stiffness as the truth
and records what a measuring device would see:

    x_meas = FK(q) + dX(q, F)[:3] + mean of 50 N(0, sigma_x^2)           (base frame [m])
    R_meas = exp(mean of 50 N(0, sigma_r^2)) exp(dX[3:]) R_FK(q)          (6-D data only)
    F_log  = F + mean of 50 N(0, sigma_F^2)                               (base frame [N, N m])

then calls :func:`rfsw_plan.elastostatics.identification.identify` on it. What the paper does
not give is ASSUMED and named as such: the anchor point, the tension steps, the attachment
point, and the noise of each device.

``measurement="commanded"`` reproduces the paper's own reading instead: the TCP is taken as
held by the cable, so the robot's commanded move along the cable is read as the deflection.
A cable holds the TCP only along itself; the deflection across it and the tool's rotation do
not enter that move, and the cable's stretch does.

Joint 6: the ZK-500's TCP lies on the joint-6 axis (tool 390 mm along z6). A cable force at the
TCP puts no torque on joint 6 (z6 . (r x f) = 0 for r along z6), so k6 leaves no trace in any
data, 3-D or 6-D. It needs a torque about z6, i.e. an attachment point off the z6 axis and a
cable that is not in the plane of z6 and that point, *and* an observation that sees a rotation
about z6 (orientation data, or a tracked point off the axis).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from rfsw_plan.elastostatics.effects import PoseBatch
from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.identification import IdentificationResult, identify
from rfsw_plan.elastostatics.measurement_set import MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel, load_model
from rfsw_plan.exceptions import InputError
from rfsw_plan.robot.kinematics import Robot

#: Seed 001 Table 2: joint angles of the five poses (controller axis values J1..J6) [deg].
TABLE2_DEG = np.array([
    [-96.24, 3.91, 25.45, -2.10, 57.17, 2.90],
    [-96.10, 23.70, -1.25, 1.48, 66.89, 1.50],
    [-49.90, 13.09, 13.03, 1.48, 63.22, 4.94],
    [-43.38, 18.77, 27.96, 1.90, 42.54, 7.15],
    [-53.40, -5.53, 30.57, -3.90, 59.00, 3.19],
])
#: Seed 001 Table 3: identified joint stiffness [N m/rad] (the truth of the simulation).
TABLE3_K = np.array([1.1676e6, 1.2731e8, 1.7187e6, 7.3227e5, 1.1011e6, 8.8932e6])
#: Seed 001 §2.2.2: about 50 sensor samples over about 5 s are averaged per reading.
SAMPLES_PER_READING = 50
READING_S = 5.0
#: ASSUMED cable anchor on the welding workbench: the Table 6 seam start, base frame [mm]
#: (the paper's Fig. 5a shows a cable to the workbench but gives no coordinates).
ANCHOR_MM = (269.52, -2070.91, 663.15)
#: ASSUMED cable tension steps per pose [N]: "varying loading forces", below the spindle's
#: 5000 N load limit (the paper gives no values). A slack-cable reading (0 N) comes first.
TENSIONS_N = (1000.0, 2000.0, 3000.0, 4000.0)
#: ASSUMED 1-sigma noise of one force-sensor sample [N], [N m]: 0.1 % of the M4347D1's
#: 15 kN / 6 kN m full scale (the paper gives no noise figure).
FORCE_NOISE_N, MOMENT_NOISE_NM = 15.0, 6.0
#: ASSUMED 1-sigma noise of one sample of the measured TCP position [mm] and orientation
#: [deg] (laser-tracker class; a 6-DoF probe for the orientation).
POSITION_NOISE_MM, ROTATION_NOISE_DEG = 0.02, 0.01
#: ASSUMED orientation noise of a better device [deg] (precision inclinometer class).
FINE_ROTATION_NOISE_DEG = 0.001
#: ASSUMED stretch of the cable [mm/kN]: about 1 m of 6 mm steel wire rope (EA ~ 2 MN).
CABLE_COMPLIANCE_MM_PER_KN = 0.5
#: ASSUMED off-axis attachment used to show k6: a bracket on the spindle, 150 mm from the
#: tool axis, tool frame [mm].
OFF_AXIS_ATTACHMENT_MM = (150.0, 0.0, 0.0)

#: How the deflection is observed (see :class:`CableCampaign`).
MEASUREMENTS = ("device", "commanded")


@dataclass(frozen=True)
class CableCampaign:
    """The set-up of a cable campaign (file units: mm, deg, N).

    Attributes:
        poses_deg: Controller axis values of each pose [deg], shape (p, 6).
        anchor_mm: Cable anchor, base frame [mm], shape (3,); None = straight below each TCP.
        attachment_mm: Cable attachment point in the tool (TCP) frame [mm], shape (3,).
        tensions_N: Cable tension steps per pose [N] (a 0 N slack reading is added first).
        samples: Sensor samples averaged per reading.
        force_noise_N: 1-sigma force noise of one sample [N].
        moment_noise_Nm: 1-sigma moment noise of one sample [N m].
        position_noise_mm: 1-sigma noise of one position sample [mm].
        rotation_noise_deg: 1-sigma noise of one orientation sample [deg].
        orientation: Record the tool orientation too (6-D data).
        measurement: ``device``: the TCP pose is measured (tracker, 6-DoF probe).
            ``commanded``: the paper's reading of §2.2.2: the TCP is taken as held by the cable,
            so the measured deflection is the commanded move along the cable (the robot moves
            until the tension is reached; it covers the deflection along the cable plus the
            cable's stretch) and the commanded orientation does not change; the deflection
            across the cable (the cable swings freely) and the tool rotation are not seen.
        cable_compliance_mm_per_kN: Stretch of the cable per kN of tension [mm/kN]
            (``commanded`` only; 0 = rigid, the paper's assumption).
    """

    poses_deg: tuple[tuple[float, ...], ...] = tuple(tuple(r) for r in TABLE2_DEG.tolist())
    anchor_mm: tuple[float, float, float] | None = ANCHOR_MM
    attachment_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tensions_N: tuple[float, ...] = TENSIONS_N
    samples: int = SAMPLES_PER_READING
    force_noise_N: float = FORCE_NOISE_N
    moment_noise_Nm: float = MOMENT_NOISE_NM
    position_noise_mm: float = POSITION_NOISE_MM
    rotation_noise_deg: float = ROTATION_NOISE_DEG
    orientation: bool = False
    measurement: str = "device"
    cable_compliance_mm_per_kN: float = 0.0

    def check(self, n_joints: int) -> None:
        """Raise :class:`InputError` on an impossible set-up."""
        src = "seed 001 campaign"
        poses = np.asarray(self.poses_deg, dtype=float)
        if poses.ndim != 2 or poses.shape[0] < 1 or poses.shape[1] != n_joints:
            raise InputError(src, "poses_deg", f"shape {poses.shape}",
                             f"at least one pose of {n_joints} joint values")
        if len(self.tensions_N) < 1 or not all(
                np.isfinite(t) and t > 0 for t in self.tensions_N):
            raise InputError(src, "tensions_N", f"{self.tensions_N}",
                             "at least one finite tension > 0 N (a cable only pulls)")
        if self.samples < 1:
            raise InputError(src, "samples", f"{self.samples}", "at least 1 sample per reading")
        for name in ("force_noise_N", "moment_noise_Nm", "position_noise_mm",
                     "rotation_noise_deg"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise InputError(src, name, f"{v}", "a noise >= 0")
        if self.measurement not in MEASUREMENTS:
            raise InputError(src, "measurement", f"'{self.measurement}'",
                             f"one of {', '.join(MEASUREMENTS)}")
        c = self.cable_compliance_mm_per_kN
        if not np.isfinite(c) or c < 0:
            raise InputError(src, "cable_compliance_mm_per_kN", f"{c}", "a stretch >= 0 mm/kN")


@dataclass(frozen=True)
class CableSimulation:
    """A simulated campaign and the truth behind it.

    Attributes:
        setup: The set-up.
        data: What the campaign logs: encoder values, averaged sensor wrench at the TCP (base
            frame), averaged measured TCP position (and orientation if ``setup.orientation``).
        truth: The truth model (zk500 with its Table 3 stiffness).
        cable_direction: Unit vector from the attachment point to the anchor, base frame,
            one per pose, shape (p, 3).
        j6_torque_per_kN: Torque the cable puts on joint 6 per kN of tension [N m/kN], (p,).
    """

    setup: CableCampaign
    data: MeasurementSet
    truth: ElastostaticModel
    cable_direction: FloatArray
    j6_torque_per_kN: FloatArray


def cable_wrenches(
    robot: Robot, q: FloatArray, anchor: FloatArray | None, attachment: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Unit-tension cable wrench at the TCP and the cable direction, per pose.

    The cable pulls the attachment point P towards the anchor A with f = T u,
    u = (A - P) / |A - P|; moved to the TCP it is the wrench (f, (P - TCP) x f).

    Args:
        robot: The robot.
        q: Joint values [rad], shape (p, n).
        anchor: Anchor, base frame [m], shape (3,); None = straight below each attachment.
        attachment: Attachment point in the tool frame [m], shape (3,).

    Returns:
        Wrench per newton of tension at the TCP, base frame [N/N, m], shape (p, 6), and the
        cable direction u, base frame, shape (p, 3).

    Raises:
        InputError: The anchor coincides with an attachment point.
    """
    T = PoseBatch.from_q(robot, q).T
    tcp = T[:, :3, 3]
    P = tcp + T[:, :3, :3] @ attachment
    if anchor is None:
        u = np.tile([0.0, 0.0, -1.0], (len(q), 1))
    else:
        d = anchor[None, :] - P
        length = np.linalg.norm(d, axis=1)
        if np.any(length < 1e-3):
            raise InputError("seed 001 campaign", "anchor_mm",
                             "anchor at the attachment point", "a cable of some length")
        u = d / length[:, None]
    return np.concatenate([u, np.cross(P - tcp, u)], axis=1), u


def simulate_cable_campaign(
    setup: CableCampaign | None = None,
    truth: ElastostaticModel | None = None,
    seed: int = 0,
) -> CableSimulation:
    """Simulate seed 001's cable campaign on the truth model (default: zk500, Table 3).

    Per pose: a slack-cable reading, then one reading per tension step; each reading is the
    mean of ``setup.samples`` noisy samples of the sensor wrench, the TCP position and (6-D)
    the tool orientation. The joint values are the pose's (the few millimetres the robot moves
    to tension the cable change the Jacobian by far less than the noise).

    Raises:
        InputError: Impossible set-up (see :meth:`CableCampaign.check`).
    """
    setup = setup or CableCampaign()
    truth = (truth or load_model("zk500")).copy()
    robot = truth.robot
    setup.check(robot.nq)
    rng = np.random.default_rng(seed)
    q_pose = np.radians(np.asarray(setup.poses_deg, dtype=float))
    anchor = None if setup.anchor_mm is None else np.asarray(setup.anchor_mm, float) * 1e-3
    attach = np.asarray(setup.attachment_mm, dtype=float) * 1e-3
    unit, u = cable_wrenches(robot, q_pose, anchor, attach)
    steps = np.array([0.0, *setup.tensions_N])
    p, s = len(q_pose), steps.size
    q = np.repeat(q_pose, s, axis=0)
    wrench = (unit[:, None, :] * steps[None, :, None]).reshape(p * s, 6)
    batch = PoseBatch.from_q(robot, q)
    dX = truth.deflection_batch(batch, wrench)
    position = batch.T[:, :3, 3] + dX[:, :3]

    m, n = p * s, setup.samples

    def averaged(sigma: float, width: int) -> FloatArray:
        return np.asarray(rng.normal(0.0, sigma, (m, n, width)).mean(axis=1))

    logged = wrench + np.concatenate([averaged(setup.force_noise_N, 3),
                                      averaged(setup.moment_noise_Nm, 3)], axis=1)
    rot = dX[:, 3:]
    if setup.measurement == "commanded":
        # Held TCP: the robot is commanded along -u by the deflection along the cable plus the
        # stretch; identify reads that move as a deflection d u and no rotation.
        ui = np.repeat(u, s, axis=0)
        tension = np.repeat(steps[None, :], p, axis=0).reshape(-1)
        along = np.einsum("mi,mi->m", dX[:, :3], ui) + (
            tension * 1e-3 * setup.cable_compliance_mm_per_kN * 1e-3)
        position = batch.T[:, :3, 3] + along[:, None] * ui
        rot = np.zeros_like(rot)
    measured = position + averaged(setup.position_noise_mm * 1e-3, 3)
    rotation = None
    if setup.orientation:
        noise = Rotation.from_rotvec(averaged(np.radians(setup.rotation_noise_deg), 3))
        rotation = (noise * Rotation.from_rotvec(rot)
                    * Rotation.from_matrix(batch.T[:, :3, :3])).as_rotvec()
    pose_idx = np.repeat(np.arange(p), s)
    pose_id: NDArray[np.str_] = np.array([f"T2-P{i + 1}" for i in pose_idx])
    load_step = np.tile(np.arange(s), p)
    data = MeasurementSet(
        q=q, wrench=logged, position=measured,
        t=np.arange(m, dtype=np.float64) * READING_S, pose_id=pose_id, load_step=load_step,
        rotation=rotation, source="<seed 001 cable campaign>",
    )
    # Joint-6 torque per kN of tension: tau = J^T F (seed 001 eq. 5), last joint.
    j6 = np.einsum("pi,pi->p", batch.J[::s, :, -1], unit) * 1e3
    return CableSimulation(setup, data, truth, u, j6)


@dataclass(frozen=True)
class CampaignIdentification:
    """Joint stiffness identified from one simulated campaign, against the truth.

    Attributes:
        label: What was simulated.
        simulation: The campaign.
        result: The identification (joint compliance free, everything else fixed).
        truth_k: Truth stiffness [N m/rad], shape (n,).
        prior_k: Stiffness the identification started from (kept where not identified).
    """

    label: str
    simulation: CableSimulation
    result: IdentificationResult
    truth_k: FloatArray
    prior_k: FloatArray

    @property
    def identified(self) -> NDArray[np.bool_]:
        """Joints the data identified, shape (n,)."""
        return np.asarray(self.result.joint_identified, dtype=bool)

    @property
    def relative_error(self) -> FloatArray:
        """(identified - truth) / truth, NaN where not identified, shape (n,)."""
        err = self.result.stiffness / self.truth_k - 1.0
        return np.where(self.identified, err, np.nan)

    @property
    def relative_std(self) -> FloatArray:
        """Standard error / truth, NaN where not identified, shape (n,)."""
        return np.where(self.identified, self.result.stiffness_std / self.truth_k, np.nan)

    def notes(self) -> list[str]:
        """Why each unidentified joint compliance was not identified."""
        return [e.note for e in self.result.estimates
                if e.effect == self.result.model.joint_compliance.label and not e.identified]


#: The prior every identification starts from [N m/rad]: one round guess for all joints, so a
#: joint the data cannot identify visibly keeps it instead of the truth.
PRIOR_K = 1.0e6


def identify_cable_campaign(
    label: str, setup: CableCampaign, seed: int = 0, prior_k: float = PRIOR_K,
) -> CampaignIdentification:
    """Simulate ``setup`` on zk500 (Table 3 truth) and identify the joint compliances.

    Args:
        label: Name of the case, for tables.
        setup: The campaign set-up.
        seed: Random seed of the noise.
        prior_k: Starting stiffness of every joint [N m/rad].
    """
    sim = simulate_cable_campaign(setup, seed=seed)
    start = sim.truth.copy()
    start.joint_compliance.params = np.full(start.robot.nq, 1.0 / prior_k)
    result = identify(start, sim.data, free=["joint_compliance"])
    return CampaignIdentification(label, sim, result, sim.truth.stiffness.copy(),
                                  np.full(start.robot.nq, prior_k))


def seed001_cases(
    seed: int = 0, attachments: Sequence[tuple[float, float, float]] | None = None,
) -> list[CampaignIdentification]:
    """The study of issue 15 item 2 on Table 2's five poses, in this order: cable at the TCP
    (3-D, 6-D), a vertical cable (6-D), an attachment off the tool axis (3-D, 6-D, and 6-D with
    a 10x finer orientation device), then the paper's own reading of the data (the commanded
    move along the cable taken as the deflection; rigid cable, then a stretching one)."""
    off = OFF_AXIS_ATTACHMENT_MM if attachments is None else attachments[0]
    cases = [
        ("TCP attachment, positions (3-D)", CableCampaign()),
        ("TCP attachment, positions + orientation (6-D)", CableCampaign(orientation=True)),
        ("TCP attachment, vertical cable, 6-D", CableCampaign(anchor_mm=None, orientation=True)),
        (f"attachment {off[0]:g}/{off[1]:g}/{off[2]:g} mm off the tool axis, 3-D",
         CableCampaign(attachment_mm=off)),
        (f"attachment {off[0]:g}/{off[1]:g}/{off[2]:g} mm off the tool axis, 6-D",
         CableCampaign(attachment_mm=off, orientation=True)),
        (f"attachment {off[0]:g}/{off[1]:g}/{off[2]:g} mm off the tool axis, 6-D, "
         f"{FINE_ROTATION_NOISE_DEG:g} deg orientation noise",
         CableCampaign(attachment_mm=off, orientation=True,
                       rotation_noise_deg=FINE_ROTATION_NOISE_DEG)),
        ("paper's reading: commanded move along a rigid cable, 3-D",
         CableCampaign(measurement="commanded")),
        (f"paper's reading: commanded move, cable {CABLE_COMPLIANCE_MM_PER_KN:g} mm/kN, 3-D",
         CableCampaign(measurement="commanded",
                       cable_compliance_mm_per_kN=CABLE_COMPLIANCE_MM_PER_KN)),
    ]
    return [identify_cable_campaign(lab, setup, seed) for lab, setup in cases]


if __name__ == "__main__":
    ap = argparse.ArgumentParser(
        description="Seed 001's cable campaign (Table 2 -> Table 3) simulated with Table 3 as the "
                    "truth and identified, case by case: the error of each identified joint "
                    "stiffness against Table 3 (examples/paper_checks.py reports the finding).")
    ap.add_argument("--seed", type=int, default=0, help="random seed of the noise (default 0)")
    args = ap.parse_args()
    for case in seed001_cases(args.seed):
        errors = " ".join(f"{'--':>5}" if np.isnan(e) else f"{e * 100:+5.1f}"
                          for e in case.relative_error)
        print(f"{case.label}\n  k1..k6 error [%]: {errors}")
