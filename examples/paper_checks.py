"""Checks of the elastostatic model against the seed papers (issue 2 §8).

Run: ``.venv/bin/python examples/paper_checks.py``

(a) ZK-500, seed 001: lateral TCP deflection at the start of the Table 6 seam under the
    measured welding forces, compared with the 4.9 mm measured; the Fig. 10 co-simulation of
    the 7 / 8 / 9 mm plunge problems (penetration law fitted to Fig. 10 by least squares on
    each run) compared with the 5.24 mm and 5-7 mm co-simulated and 4842.58 N measured, and
    the joint check: penetration, steady axial force and lateral deviation of one run each,
    reproduced together (issue 28). The robot is the problems' ``zk500_seed001`` (Table 3
    re-identified by ``validate`` on ``examples/seed001``); ``zk500`` is Table 3 as published.
    Table 2 -> Table 3: the cable campaign of §2.2.2 simulated on the five Table 2 poses with
    the Table 3 stiffness as truth and identified (examples/seed001/seed001_campaign.py).
(b) FANUC S-900iB/400, seed 000: the influence index nu_p of the complementary stiffness Kc
    (eq. 9) over the vertical workspace plane of Fig. 13 (q1 = 0, wrist joints at 45 deg) with
    the wrench and joint stiffness of eq. 10.

Eq. 10 as extracted lists only five joint stiffnesses, "1e6 4e5 4e5 1e4 1e4"; the sixth is
taken as 1e4 N m/rad (the wrist joints 4-6 share one value, the list lost a repeated entry).
"""

from __future__ import annotations

import sys
import textwrap
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.elastostatics.effects.base import FloatArray
from rfsw_plan.elastostatics.model import load_model
from rfsw_plan.elastostatics.workspace import (
    IndexMap,
    JointGrid,
    index_map,
    sample_joint_grid,
)
from rfsw_plan.process.deviation import DeviationResult, problem_deviation
from rfsw_plan.process.problem import Problem, load_problem
from rfsw_plan.robot.description import ModifiedDH, load_robot_description
from rfsw_plan.robot.ik import solve_ik
from rfsw_plan.robot.kinematics import Robot, load_robot

# The seed 001 reproductions live beside the paper's evidence files, not in the package.
sys.path.insert(0, str(Path(__file__).resolve().parent / "seed001"))
from seed001_campaign import (
    CABLE_COMPLIANCE_MM_PER_KN,
    OFF_AXIS_ATTACHMENT_MM,
    CampaignIdentification,
    seed001_cases,
)

#: Seed 001 Table 6 seam start and end, base frame [m].
SEAM_START = np.array([269.52, -2070.91, 663.15]) / 1000.0
SEAM_END = np.array([278.10, -1957.60, 664.05]) / 1000.0
#: Seed 001 Table 2 pose 1 [deg]: the elbow-up branch used to seed the IK.
POSE1_DEG = np.array([-96.24, 3.91, 25.45, -2.10, 57.17, 2.90])
#: Seed 001 §3 welding forces [N]: axial (down force), traverse, lateral.
FD_N, FR_N, FL_N = 4842.58, 899.80, 1350.87
MEASURED_MM, COSIM_MM = 4.9, 5.24
#: Seed 001 Fig. 10: the three virtual welds (commanded plunge [mm] -> bundled problem).
PLUNGE_CASES = {7.0: "zk500_plunge7mm", 8.0: "zk500_table6_seam", 9.0: "zk500_plunge9mm"}
#: Seed 001 Fig. 10d-f: lateral deviation of every virtual weld [mm].
COSIM_RANGE_MM = (5.0, 7.0)
#: The ZK-500 the zk500 problems use: Table 3 re-identified on examples/seed001 (issue 28).
ZK500 = "zk500_seed001"
#: Joint check tolerances (issue 28): penetration +-0.3 mm, steady axial force 15 %, largest
#: lateral deviation in the weld 10 % of 5.24 mm.
PEN_TOL_MM, FORCE_TOL, LATERAL_TOL = 0.3, 0.15, 0.10

#: Seed 000 eq. 10: wrench [N, N m] and joint stiffness [N m/rad] (k6 assumed = k5).
EQ10_WRENCH = np.array([1000.0, -3000.0, -4000.0, -200.0, 200.0, -200.0])
EQ10_KQ = np.array([1e6, 4e5, 4e5, 1e4, 1e4, 1e4])
#: Seed 000 Fig. 12-13 plane: q1 = 0, wrist joints at 45 deg [deg].
FIG13_Q_DEG = np.array([0.0, 0.0, 0.0, 45.0, 45.0, 45.0])


@dataclass(frozen=True)
class SeamCheck:
    """ZK-500 deflection at the seam start.

    Attributes:
        q_deg: IK configuration [deg], shape (6,).
        wrench: Process wrench on the tool, base frame [N, N m], shape (6,).
        deflection_mm: TCP translation, base frame [mm], shape (3,).
        lateral_mm: Component along l = Z x t (advancing side positive) [mm].
        travel_mm: Component along the travel direction t [mm].
        axial_mm: Component along +Z [mm].
    """

    q_deg: np.ndarray
    wrench: np.ndarray
    deflection_mm: np.ndarray
    lateral_mm: float
    travel_mm: float
    axial_mm: float


def zk500_seam_check() -> SeamCheck:
    """Seed 001: tool straight down at the Table 6 seam start, elbow-up near Table 2 pose 1."""
    robot = load_robot(ZK500)
    model = load_model(robot)
    t = (SEAM_END - SEAM_START) / np.linalg.norm(SEAM_END - SEAM_START)
    up = np.array([0.0, 0.0, 1.0])
    lat = np.cross(up, t)
    lat /= np.linalg.norm(lat)  # the seam climbs 0.9 mm: t is not exactly horizontal
    q_seed = np.radians(POSE1_DEG)
    # Tool axis straight down (TCP z = -Z); keep pose 1's rotation about the tool axis.
    z = -up
    x = robot.fk(q_seed)[:3, 0]
    x = x - z * (x @ z)
    x /= np.linalg.norm(x)
    target = np.eye(4)
    target[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    target[:3, 3] = SEAM_START
    ik = solve_ik(robot, target, q_seed)
    if not ik.converged:
        raise RuntimeError(f"IK did not converge at the seam start: {ik}")
    # Down force pushes the tool up; traverse force opposes travel; lateral force along l.
    force = FD_N * up - FR_N * t + FL_N * lat
    wrench = np.concatenate([force, np.zeros(3)])
    d = model.deflection(ik.q, wrench)[:3] * 1e3
    return SeamCheck(np.degrees(ik.q), wrench, d, float(d @ lat), float(d @ t), float(d @ up))


@dataclass(frozen=True)
class PlungeCase:
    """One seed 001 Fig. 10 virtual weld co-simulated with the project's robot model.

    Attributes:
        commanded_mm: Commanded plunge after contact [mm].
        result: Deviation with the co-simulation (law fitted to Fig. 10 on each run).
        penetration_mm: Penetration over the steady weld (min, max) [mm].
        force_N: Axial force over the steady weld (min, max) [N].
        lateral_mm: Lateral deviation over the steady weld (min, max) [mm].
        last10_lateral_mm: Mean lateral deviation of the last ten weld samples [mm] (seed 001
            §4 averages the final ten iterations).
        max_penetration_mm: Largest co-simulated penetration [mm] (``cosim.max_penetration_mm``).
        steady_force_N: Median axial force where the penetration is above 90 % of its largest
            [N] (``cosim.steady_axial_force_N``).
        max_lateral_mm: Largest |lateral deviation| in the weld, under the co-simulated forces
            [mm] (``cosim.max_abs_lateral_weld_mm``).
    """

    commanded_mm: float
    result: DeviationResult
    penetration_mm: tuple[float, float]
    force_N: tuple[float, float]
    lateral_mm: tuple[float, float]
    last10_lateral_mm: float
    max_penetration_mm: float
    steady_force_N: float
    max_lateral_mm: float


def zk500_plunge_cases() -> list[PlungeCase]:
    """Seed 001 Fig. 10: the 7 / 8 / 9 mm plunge problems through ``deviation --cosim``."""
    return [_plunge_case(depth, problem_deviation(load_problem(name), cosim=True))
            for depth, name in PLUNGE_CASES.items()]


def _plunge_case(depth: float, res: DeviationResult) -> PlungeCase:
    """The numbers of one co-simulated plunge problem."""
    c = res.cosim
    if c is None or not c.all_converged:
        raise RuntimeError(f"{depth:g} mm plunge: the co-simulation did not converge")
    m = res.steady_weld
    weld = res.schedule.mask("weld")
    return PlungeCase(
        depth, res,
        (float(c.penetration[m].min() * 1e3), float(c.penetration[m].max() * 1e3)),
        (float(c.axial_force[m].min()), float(c.axial_force[m].max())),
        (float(res.lateral_t[m].min() * 1e3), float(res.lateral_t[m].max() * 1e3)),
        float(res.lateral_t[np.flatnonzero(weld)[-10:]].mean() * 1e3),
        float(c.largest_penetration * 1e3), c.steady_axial_force,
        float(np.max(np.abs(res.lateral_t[weld])) * 1e3),
    )


def table3_eight_mm() -> PlungeCase:
    """The 8 mm run on ``zk500`` (Table 3 as published, no added effect): what issue 28
    started from."""
    problem = load_problem(PLUNGE_CASES[8.0])
    res = problem_deviation(replace(problem, robot=load_robot_description("zk500")), cosim=True)
    return _plunge_case(8.0, res)


def t3_compliance(case: PlungeCase) -> float:
    """The robot's axial compliance at the fitted sample of a case [mm/kN]."""
    fit = case.result.penetration_fit
    return float("nan") if fit is None else fit.axial_compliance * 1e6


def joint_check(cases: list[PlungeCase]) -> tuple[bool, str]:
    """Seed 001's numbers together (issue 28): each plunge is one ``deviation --cosim`` run;
    the 8 mm run must give its penetration, the measured axial force and the lateral deviation
    at once, the 7 and 9 mm runs their penetrations.

    Returns:
        Whether all five hold, and the measured numbers as text.
    """
    by = {c.commanded_mm: c for c in cases}
    seven, eight, nine = by[7.0], by[8.0], by[9.0]
    f_err = eight.steady_force_N / FD_N - 1.0
    l_err = eight.max_lateral_mm / COSIM_MM - 1.0
    holds = (abs(seven.max_penetration_mm - 4.2) <= PEN_TOL_MM
             and abs(eight.max_penetration_mm - 4.8) <= PEN_TOL_MM
             and nine.max_penetration_mm > 5.0 and abs(f_err) <= FORCE_TOL
             and abs(l_err) <= LATERAL_TOL)
    text = (f"7 mm run: {seven.max_penetration_mm:.2f} mm; 8 mm run: "
            f"{eight.max_penetration_mm:.2f} mm, {eight.steady_force_N:.0f} N "
            f"({f_err * 100:+.1f} %), lateral {eight.max_lateral_mm:.2f} mm "
            f"({l_err * 100:+.1f} %); 9 mm run: {nine.max_penetration_mm:.2f} mm")
    return holds, text


def fanuc_nu_p_maps(n_points: int = 41) -> dict[str, IndexMap]:
    """nu_p and kappa_f over the seed 000 Fig. 13 plane for three stiffness sets."""
    robot = load_robot("fanuc_s900ib_400")
    grid = sample_joint_grid(robot, np.radians(FIG13_Q_DEG), n_points=(n_points, n_points))
    wrist_1e5 = EQ10_KQ.copy()
    wrist_1e5[3:] = 1e5
    return {
        "eq. 10 Kq (k6 = 1e4 assumed)": index_map(robot, grid, EQ10_WRENCH, EQ10_KQ),
        "eq. 10 Kq with wrist 1e5": index_map(robot, grid, EQ10_WRENCH, wrist_1e5),
        "Table 2 (identified)": index_map(robot, grid, EQ10_WRENCH, None),
    }


# --------------------------------------------------------------------------------------------
# Seed 000 §3.2.6: the laser check at 1400 mm (Figs. 15-17) and the 1700 mm butt weld

#: Seed 000 Figs. 16-17 (1400 mm, y+ and y-) and the 1700 mm weld of Fig. 19 (bundled problems;
#: the 1700 mm y- case is the same file with ``reverse = true``).
FANUC_LASER = {"1400 mm y+": "fanuc_laser_1400mm_yplus", "1400 mm y-": "fanuc_laser_1400mm_yminus"}
FANUC_1700 = "fanuc_butt_1700mm"
#: Seed 000 §3.2.6: lateral tool deviation "about 7 mm when the pin enters into the material".
PAPER_1700_MM = 7.0
#: Force components of the seed 000 preset, as keyword names of ProcessForces.
FORCE_PARTS = ("axial", "lateral", "traverse")
#: Seed 000 (test-bed, Fig. 4): maximum reach of the S-900iB/400 [mm] (no public lengths).
S900_REACH_MM = 2488.0


@dataclass(frozen=True)
class LateralSplit:
    """Uncompensated lateral deviation of one FANUC weld and what it is made of.

    The model is linear in the wrench and in the joint compliances (seed 000 eq. 11,
    dX = J Kq^-1 J^T F), so the deviation splits exactly into one part per force component
    (the other two set to zero) and one part per joint (halving k_i doubles joint i's part).

    Attributes:
        case: Short label (distance and travel direction).
        lateral_mm: Lateral deviation at the first and last waypoint (steady force) [mm].
        by_force_mm: Part of the start value due to the axial, lateral and traverse force [mm].
        by_joint_mm: Part of the start value due to each joint's compliance [mm], shape (6,).
        lateral_force_N: The lateral force of the process model [N].
    """

    case: str
    lateral_mm: tuple[float, float]
    by_force_mm: dict[str, float]
    by_joint_mm: tuple[float, ...]
    lateral_force_N: float

    def lateral_force_for(self, target_mm: float) -> float:
        """Lateral force [N] that puts the start value at ``target_mm`` (all else kept)."""
        per_n = self.by_force_mm["lateral"] / self.lateral_force_N
        return (target_mm - self.lateral_mm[0]) / per_n + self.lateral_force_N


def _start_end(problem: Problem) -> tuple[float, float]:
    lat = problem_deviation(problem).lateral * 1e3
    return float(lat[0]), float(lat[-1])


def _with_forces(problem: Problem, **forces: Any) -> Problem:
    proc = problem.process
    return replace(problem, process=replace(proc, forces=replace(proc.forces, **forces)))


def _with_robot(problem: Problem, **fields: Any) -> Problem:
    return replace(problem, robot=replace(problem.robot, **fields))


def lateral_split(case: str, problem: Problem) -> LateralSplit:
    """Deviation of ``problem`` split by force component and by joint (seed 000 eq. 11)."""
    start, end = _start_end(problem)
    by_force = {}
    for part in FORCE_PARTS:
        zero = {p: 0.0 for p in FORCE_PARTS if p != part}
        by_force[part] = _start_end(_with_forces(problem, **zero))[0]
    by_joint = []
    for i in range(problem.robot.n_joints):
        k = problem.robot.stiffness.copy()
        k[i] *= 0.5
        by_joint.append(_start_end(_with_robot(problem, stiffness=k))[0] - start)
    return LateralSplit(case, (start, end), by_force, tuple(by_joint),
                        problem.process.forces.lateral)


def fanuc_reversed(problem: Problem) -> Problem:
    """The same weld travelled the other way (``reverse = true``)."""
    return replace(problem, seam=replace(problem.seam, reverse=True))


def fanuc_direction_cases() -> list[LateralSplit]:
    """Seed 000 Figs. 16-17 at 1400 mm and the 1700 mm weld, each along y+ and y-."""
    out = [lateral_split(case, load_problem(name)) for case, name in FANUC_LASER.items()]
    p1700 = load_problem(FANUC_1700)
    out.append(lateral_split("1700 mm y+", p1700))
    out.append(lateral_split("1700 mm y-", fanuc_reversed(p1700)))
    return out


@dataclass(frozen=True)
class Sensitivity:
    """Lateral deviation of the 1700 mm weld with one assumption changed.

    Attributes:
        assumption: Which group of assumptions (geometry, force direction, force magnitude,
            stiffness, coupling, seam placement).
        variant: What was changed.
        y_plus_mm: Lateral deviation at the first and last waypoint along y+ [mm].
        y_minus_mm: The same along y- [mm].
    """

    assumption: str
    variant: str
    y_plus_mm: tuple[float, float]
    y_minus_mm: tuple[float, float]


def fanuc_1700_sensitivity() -> list[Sensitivity]:
    """The 1700 mm weld (both directions) with each assumption of the model changed in turn."""
    base = load_problem(FANUC_1700)
    desc = base.robot
    chain = desc.chain
    if not isinstance(chain, ModifiedDH):
        raise RuntimeError(f"{FANUC_1700}: expected an MDH robot, got {type(chain).__name__}")
    f = base.process.forces
    tool = {}
    for length in (300.0, 600.0):
        T = desc.tool.copy()
        T[2, 3] = length * 1e-3
        tool[length] = T
    # Wrist-centre reach of the chain: a1 + a2 + |(a3, d4)| (2839 mm for the M-900iB/700
    # lengths); scale the arm (not the base height or the faceplate) to the S-900iB/400's.
    reach = chain.a[1] + chain.a[2] + np.hypot(chain.a[3], chain.d[3])
    scale = S900_REACH_MM * 1e-3 / reach
    arm = np.array([1.0, scale, scale, scale, 1.0, 1.0])
    arm_d = np.array([1.0, 1.0, 1.0, scale, 1.0, 1.0])
    k_half = {}
    for i in (2, 4):
        k = desc.stiffness.copy()
        k[i] *= 0.5
        k_half[i] = k

    def seam_z(p: Problem, z_mm: float) -> Problem:
        pts = p.seam.points.copy()
        pts[:, 2] = z_mm * 1e-3
        return replace(p, seam=replace(p.seam, points=pts))

    variants: list[tuple[str, str, Callable[[Problem], Problem]]] = [
        ("baseline", f"as bundled (M-900iB/700 lengths, tool {desc.tool[2, 3] * 1e3:g} mm, "
         f"Fn {f.axial:g} N, Fl {f.lateral:g} N, Ft {f.traverse:g} N)", lambda p: p),
        ("force direction", "spindle ccw (advancing side on the other side)",
         lambda p: replace(p, seam=replace(p.seam, rotation="ccw"))),
        ("force direction", "lateral force toward the retreating side",
         lambda p: _with_forces(p, lateral_sign=-1.0)),
        ("force magnitude", "Fl = Ft = 0.5 kN", lambda p: _with_forces(p, lateral=500.0,
                                                                        traverse=500.0)),
        ("force magnitude", "Fl = Ft = 1.5 kN", lambda p: _with_forces(p, lateral=1500.0,
                                                                        traverse=1500.0)),
        ("force magnitude", "Fn 3.1 -> 4.0 kN", lambda p: _with_forces(p, axial=4000.0)),
        ("stiffness", "k3 halved", lambda p: _with_robot(p, stiffness=k_half[2])),
        ("stiffness", "k5 halved", lambda p: _with_robot(p, stiffness=k_half[4])),
        ("coupling", "no parallelogram (k3 on the elbow angle)",
         lambda p: _with_robot(p, coupling=np.diag(np.diag(desc.coupling)))),
        ("geometry", "tool 300 mm (flange to pin tip)", lambda p: _with_robot(p, tool=tool[300.0])),
        ("geometry", "tool 600 mm", lambda p: _with_robot(p, tool=tool[600.0])),
        ("geometry", f"arm lengths x {scale:.3f} (S-900iB/400 reach {S900_REACH_MM:g} mm)",
         lambda p: _with_robot(p, chain=replace(chain, a=chain.a * arm, d=chain.d * arm_d))),
        ("seam placement", "plate at z = 300 mm", lambda p: seam_z(p, 300.0)),
        ("seam placement", "plate at z = 900 mm", lambda p: seam_z(p, 900.0)),
    ]
    return [Sensitivity(group, name, _start_end(f(base)), _start_end(f(fanuc_reversed(base))))
            for group, name, f in variants]


def sensitivity_spread(rows: list[Sensitivity]) -> dict[str, float]:
    """Largest change of the start value [mm] per assumption group, over both directions."""
    base = next(r for r in rows if r.assumption == "baseline")
    out: dict[str, float] = {}
    for r in rows:
        if r.assumption == "baseline":
            continue
        d = max(abs(r.y_plus_mm[0] - base.y_plus_mm[0]), abs(r.y_minus_mm[0] - base.y_minus_mm[0]))
        out[r.assumption] = max(out.get(r.assumption, 0.0), d)
    return out


#: Seed 000 eq. 10 as extracted: five joint stiffnesses for six joints [N m/rad].
EQ10_FIVE = (1e6, 4e5, 4e5, 1e4, 1e4)


@dataclass(frozen=True)
class Eq10Reading:
    """nu_p over the Fig. 13 plane for one reading of the garbled eq. 10.

    Attributes:
        reading: How the five listed stiffnesses (and the wrench) are read.
        Kq: The six joint stiffnesses [N m/rad], shape (6,).
        wrench_frame: ``base`` (eq. 10's wrench in the base frame) or ``tool`` (in the TCP
            frame, turned into the base frame at each pose).
        median: Median nu_p over the plane [-].
        max: Largest nu_p over the plane [-].
    """

    reading: str
    Kq: tuple[float, ...]
    wrench_frame: str
    median: float
    max: float

    @property
    def holds(self) -> bool:
        """The paper's nu_p <= 0.03 over the whole plane."""
        return self.max <= 0.03


def _nu_p(robot: Robot, grid: JointGrid, Kq: FloatArray, frame: str) -> FloatArray:
    if frame == "base":
        return index_map(robot, grid, EQ10_WRENCH, Kq).nu_p
    T, _ = robot.batch_fk_jacobian(grid.q)
    out = np.empty(len(grid.q))
    for i, Ti in enumerate(T):  # the wrench turns with the tool: one map per pose
        R = Ti[:3, :3]
        Fb = np.concatenate([R @ EQ10_WRENCH[:3], R @ EQ10_WRENCH[3:]])
        one = JointGrid(grid.q[i:i + 1], grid.position[i:i + 1], grid.swept, grid.axes, (1, 1))
        out[i] = index_map(robot, one, Fb, Kq).nu_p[0]
    return out


def eq10_readings(n_points: int = 41) -> list[Eq10Reading]:
    """Every plausible reading of eq. 10's five stiffnesses, and Table 2 for reference.

    The extracted list "1e6 4e5 4e5 1e4 1e4" lost one entry; a lost entry most likely repeats
    a neighbour (k2 = k1, k4 = k3 or k6 = k5). Other readings: an exponent misread (wrist 1e5),
    the values in kN m/rad, and the wrench given in the tool frame instead of the base frame.
    """
    robot = load_robot("fanuc_s900ib_400")
    grid = sample_joint_grid(robot, np.radians(FIG13_Q_DEG), n_points=(n_points, n_points))
    a, b, c, d, e = EQ10_FIVE
    readings: list[tuple[str, tuple[float, ...], str]] = [
        ("k6 = k5 lost (wrist 1e4)", (a, b, c, d, e, e), "base"),
        ("k2 = k1 lost", (a, a, b, c, d, e), "base"),
        ("k4 = k3 lost", (a, b, c, c, d, e), "base"),
        ("wrist exponent misread (1e5)", (a, b, c, 10 * d, 10 * e, 10 * e), "base"),
        ("values in kN m/rad (x 1e3)", tuple(1e3 * k for k in (a, b, c, d, e, e)), "base"),
        ("k6 = k5, wrench in the tool frame", (a, b, c, d, e, e), "tool"),
        ("Table 2 (identified)", tuple(float(k) for k in robot.stiffness), "base"),
        ("Table 2, wrench in the tool frame", tuple(float(k) for k in robot.stiffness), "tool"),
    ]
    out = []
    for name, k, frame in readings:
        nu = _nu_p(robot, grid, np.array(k), frame)
        v = nu[np.isfinite(nu)]
        out.append(Eq10Reading(name, k, frame, float(np.median(v)), float(v.max())))
    return out


def eq10_scale_for_limit(limit: float = 0.03, n_points: int = 41) -> float:
    """Smallest factor on eq. 10's stiffness (k6 = k5 reading) for which nu_p <= ``limit``
    over the whole Fig. 13 plane (bisection in log scale; nu_p falls as Kq rises)."""
    robot = load_robot("fanuc_s900ib_400")
    grid = sample_joint_grid(robot, np.radians(FIG13_Q_DEG), n_points=(n_points, n_points))
    k = np.array([*EQ10_FIVE, EQ10_FIVE[-1]])

    def worst(f: float) -> float:
        return float(np.nanmax(index_map(robot, grid, EQ10_WRENCH, f * k).nu_p))

    lo, hi = 1.0, 1e4
    if worst(hi) > limit:
        raise RuntimeError(f"nu_p stays above {limit} with eq. 10's stiffness x {hi:g}")
    for _ in range(20):
        mid = float(np.sqrt(lo * hi))
        lo, hi = (lo, mid) if worst(mid) <= limit else (mid, hi)
    return hi


@dataclass(frozen=True)
class Check:
    """One row of the table: a paper's number, ours, and whether it is reproduced.

    Attributes:
        paper: Seed, where in it, and the paper's number.
        project: The number this project measures (or "not measured").
        reproduced: True only when our number matches the paper's within the stated tolerance.
        why: How it was measured, and the reason when it is not reproduced.
    """

    paper: str
    project: str
    reproduced: bool
    why: str


def _seed001_rows() -> list[Check]:
    """Seed 001 (ZK-500): measured deflection, Fig. 10 co-simulation, the joint check of issue
    28, Table 3 stiffness."""
    s = zk500_seam_check()
    err = (s.lateral_mm - MEASURED_MM) / MEASURED_MM * 100
    cases = zk500_plunge_cases()
    fit = cases[0].result.penetration_fit
    if fit is None:
        raise RuntimeError(f"{PLUNGE_CASES[7.0]}: no penetration-law calibration")
    by = {c.commanded_mm: c for c in cases}
    eight = by[8.0]
    implied = (8.0 - 4.8) / FD_N * 1e3  # [mm/kN]: 3.2 mm taken up by the robot at Fd
    pen = ", ".join(f"{o.commanded_mm:g} -> {o.max_penetration_mm:.2f}" for o in cases)
    lat = ", ".join(f"{o.commanded_mm:g}: {o.lateral_mm[0]:.2f}-{o.lateral_mm[1]:.2f}"
                    for o in cases)
    lo = min(o.lateral_mm[0] for o in cases)
    hi = max(o.lateral_mm[1] for o in cases)
    cos_err = (eight.last10_lateral_mm - COSIM_MM) / COSIM_MM * 100
    f_err = (eight.steady_force_N / FD_N - 1) * 100
    pen_ok = (abs(by[7.0].max_penetration_mm - 4.2) <= PEN_TOL_MM
              and abs(by[8.0].max_penetration_mm - 4.8) <= PEN_TOL_MM
              and by[9.0].max_penetration_mm > 5.0)
    together, numbers = joint_check(cases)
    t3 = table3_eight_mm()
    return [
        Check(
            "001 §4: lateral deflection 4.9 mm (measured)",
            f"{s.lateral_mm:.2f} mm ({err:+.1f} %)",
            abs(err) <= 10.0,
            f"elastostatic model ({ZK500}), Table 6 seam start, §3 forces; tolerance 10 %",
        ),
        Check(
            "001 Fig. 10a-c: penetration ~4.2 / ~4.8 / >5 mm for 7 / 8 / 9 mm plunge",
            f"largest co-simulated penetration: {pen} mm; law fit "
            + ", ".join(f"{o.commanded_depth * 1e3:g} -> {p * 1e3:.2f}"
                        for o, p in zip(fit.observations, fit.predicted, strict=True))
            + f" mm (RMS residual {fit.rms_residual * 1e3:.3f} mm)",
            pen_ok,
            f"calibrated, not predicted: the law through zero (1 parameter, k_p "
            f"{fit.law.stiffness * 1e-3:.0f} N/mm) fitted by least squares to the 3 points "
            "(the >5 mm one as a bound), like eq. 15's f*, through the robot's compliance; "
            f"tolerance +-{PEN_TOL_MM:g} mm on each run's largest penetration (issue 28)",
        ),
        Check(
            "001 §3: axial force 4842.58 N (measured, 8 mm plunge)",
            f"{eight.steady_force_N:.0f} N ({f_err:+.1f} %; median where the penetration is "
            f"above 90 % of its largest; steady weld {eight.force_N[0]:.0f}-"
            f"{eight.force_N[1]:.0f} N)",
            abs(f_err) <= 10.0,
            f"Fig. 10's 3.2 mm taken up at 8 mm needs {implied:.3f} mm/kN along the tool "
            f"axis; Table 3 alone gives {t3_compliance(t3):.3f} mm/kN (the law then pushes "
            f"{t3.steady_force_N:.0f} N); {ZK500}'s "
            "joint 2 gives way more under the weld's torque (torque_dependent_stiffness:j2, "
            f"named by validate on examples/seed001: {fit.axial_compliance * 1e6:.2f} mm/kN "
            "locally at Fd); tolerance 10 %",
        ),
        Check(
            "001 §4: co-simulated lateral 5.24 mm (8 mm, mean of the final 10 iterations)",
            f"{eight.last10_lateral_mm:.2f} mm ({cos_err:+.1f} %)",
            abs(cos_err) <= 10.0,
            "mean of the last 10 weld samples of deviation --cosim (the seam's end); the "
            f"lateral deviation falls along the seam ({eight.lateral_mm[1]:.2f} -> "
            f"{eight.lateral_mm[0]:.2f} mm) as the arm moves in; the paper's 5.24 mm is its "
            f"own model's, the real weld measured ~4.9 mm (Fig. 3b); tolerance 10 %",
        ),
        Check(
            "001 Fig. 10d-f: lateral 5-7 mm in every virtual weld",
            f"{lat} mm (steady weld)",
            lo >= COSIM_RANGE_MM[0] - 0.5 and hi <= COSIM_RANGE_MM[1] + 0.5,
            f"all cases {lo:.2f}-{hi:.2f} mm: the model gives {s.lateral_mm:.2f} mm at the "
            "measured forces, like the 4.9 mm measured; the paper's virtual welds are above "
            "its own measurement; tolerance 0.5 mm",
        ),
        Check(
            "001 §2.1/§3/§4 together: 4.2 / 4.8 / >5 mm, Fd0 4842.58 N, lateral 5.24 mm",
            numbers,
            together,
            f"one deviation --cosim run per plunge on {ZK500} (law fitted on each run): "
            f"largest penetration +-{PEN_TOL_MM:g} mm, steady axial force (median where "
            f"the penetration is above 90 % of its largest) {FORCE_TOL * 100:.0f} %, largest "
            f"|cosim.lateral_mm| in the weld {LATERAL_TOL * 100:.0f} %; with Table 3 alone "
            f"(zk500) the 8 mm run gives {t3.max_penetration_mm:.2f} mm, "
            f"{t3.steady_force_N:.0f} N ({(t3.steady_force_N / FD_N - 1) * 100:+.0f} %), "
            f"lateral {t3.max_lateral_mm:.2f} mm",
        ),
        *_seed001_table3_rows(seed001_cases()),
    ]


def _pct(values: np.ndarray) -> str:
    return " / ".join("-" if not np.isfinite(v) else f"{v * 100:+.2g}" for v in values)


def _seed001_table3_rows(cases: list[CampaignIdentification]) -> list[Check]:
    """Seed 001 Table 2 -> Table 3: which joints the five poses identify, and k6."""
    tcp3, tcp6 = cases[0], cases[1]
    off3, off6, fine = cases[3], cases[4], cases[5]
    rigid, stretch = cases[6], cases[7]
    vertical = cases[2]
    first5 = bool(tcp3.identified[:5].all()) and bool(np.all(
        np.abs(tcp3.relative_error[:5]) <= 3.0 * tcp3.relative_std[:5]))
    k6_signal = float(np.max(np.abs(tcp3.simulation.j6_torque_per_kN)))
    off_torque = np.abs(off6.simulation.j6_torque_per_kN)
    vert_lost = ", ".join(f"k{j + 1}" for j in np.flatnonzero(~vertical.identified))
    return [
        Check(
            "001 Table 3: k1-k5 identified from the 5 Table 2 poses (cable at the TCP)",
            f"errors {_pct(tcp3.relative_error[:5])} %, standard errors "
            f"{_pct(tcp3.relative_std[:5])} % (3-D, 4 tensions 1-4 kN, 50-sample means)",
            first5,
            "simulated campaign with Table 3 as truth (examples/seed001/seed001_campaign.py); "
            "cable anchor at the Table 6 seam start, tensions and device noise ASSUMED; "
            "reproduced = every error within 3 standard errors; a vertical cable loses "
            f"{vert_lost or 'nothing'} (no torque about the vertical j1 axis)",
        ),
        Check(
            "001 Table 3: k6 = 8.8932e6 N m/rad",
            f"not identifiable with the cable at the TCP: j6 torque {k6_signal:.1g} N m/kN "
            "(rounding) at all 5 poses; 3-D and 6-D keep the prior; "
            f"{OFF_AXIS_ATTACHMENT_MM[0]:g} mm off axis + 6-D: error "
            f"{off6.relative_error[5] * 100:+.0f} %, standard error "
            f"{off6.relative_std[5] * 100:.0f} % (0.01 deg orientation noise), "
            f"{fine.relative_error[5] * 100:+.0f} % / {fine.relative_std[5] * 100:.0f} % "
            f"(0.001 deg)",
            False,
            "zk500's TCP lies on the j6 axis, so a cable at the TCP puts no torque on j6 "
            f"({tcp6.label}: k6 {'identified' if tcp6.identified[5] else 'not identified'}); "
            f"an attachment off the tool axis gives {off_torque.min():.0f}-"
            f"{off_torque.max():.0f} N m/kN, which only orientation data see "
            f"(3-D: k6 {'identified' if off3.identified[5] else 'not identified'}); "
            "the paper states no such attachment",
        ),
        Check(
            "001 §2.2.2 method: commanded move with the TCP held by the cable read as dX",
            f"k1-k6 errors {_pct(rigid.relative_error)} % (rigid cable), "
            f"{_pct(stretch.relative_error)} % ({CABLE_COMPLIANCE_MM_PER_KN:g} mm/kN cable); "
            f"RMS residual {rigid.result.rms_after * 1e3:.2f} mm vs "
            f"{cases[0].result.rms_after * 1e3:.3f} mm with the TCP measured",
            False,
            "same campaign, the paper's reading of it: a cable holds the TCP only along itself, "
            "so the commanded move is the deflection along the cable (plus the cable's "
            "stretch) and eq. 8's other rows read zero; '-' = not identified (estimate not "
            "positive or invisible, prior kept); measure the TCP (tracker) instead",
        ),
    ]


def _seed000_rows(n_points: int = 41) -> list[Check]:
    """Seed 000 (FANUC S-900iB/400) rows, computed on each run."""
    readings = {r.reading: r for r in eq10_readings(n_points)}
    tab2 = readings["Table 2 (identified)"]
    tab2_tool = readings["Table 2, wrench in the tool frame"]
    eq10 = [r for r in readings.values() if not r.reading.startswith("Table 2")]
    holding = [r.reading for r in eq10 if r.holds]
    scale = eq10_scale_for_limit(0.03, n_points)
    listed = "; ".join(f"{r.reading}: {r.median:.3f} / {r.max:.3f}" for r in eq10)
    return [
        Check(
            "000 eq. 8-10 / Fig. 13: nu_p <= 0.03 with eq. 10's Kq",
            f"median / max nu_p: {listed}",
            False,
            f"only {', '.join(holding) or 'no reading'} gives max <= 0.03, i.e. a Kq 100-1000x "
            "Table 2's identified one (not plausible); with a 1e4 N m/rad wrist eq. 10's "
            f"wrench bends the robot so far that Kc matters; eq. 10's Kq needs x {scale:.1f} "
            "for max <= 0.03 (k6 = k5 reading)",
        ),
        Check(
            "000 Table 2 stiffness: nu_p <= 0.03",
            f"median {tab2.median:.4f}, max {tab2.max:.4f} (wrench in the tool frame: "
            f"{tab2_tool.median:.4f}, {tab2_tool.max:.4f})",
            bool(tab2.median <= 0.03 and tab2.max <= 0.035),
            "reproduced to within 0.005 at the worst pose with eq. 10's wrench in the base "
            "frame, within 0.03 everywhere in the tool frame (M-900iB/700 lengths, assumed tool)",
        ),
        *_fanuc_direction_rows(),
    ]


def _fanuc_direction_rows() -> list[Check]:
    """Seed 000 §3.2.6: 1400 mm y+/y- (Figs. 16-17) and the ~7 mm at 1700 mm."""
    cases = {c.case: c for c in fanuc_direction_cases()}
    yp, ym = cases["1400 mm y+"], cases["1400 mm y-"]
    p17, m17 = cases["1700 mm y+"], cases["1700 mm y-"]

    def rng(c: LateralSplit) -> str:
        return f"{c.lateral_mm[0]:+.2f} ... {c.lateral_mm[1]:+.2f} mm"

    lower_yp = max(map(abs, yp.lateral_mm)) < min(map(abs, ym.lateral_mm))
    j = yp.by_joint_mm
    spread = sensitivity_spread(fanuc_1700_sensitivity())
    moves = ", ".join(f"{k} {v:.1f}" for k, v in spread.items())
    return [
        Check(
            "000 Figs. 16-17: 1400 mm, lateral deviation lower along y+ than y-",
            f"y+ {rng(yp)}, y- {rng(ym)} (fanuc_laser_1400mm_yplus / _yminus)",
            lower_yp,
            f"the {yp.lateral_force_N * 1e-3:g} kN lateral force gives "
            f"{yp.by_force_mm['lateral']:+.2f} mm in both directions (joint 5 {j[4]:+.2f}, "
            f"joint 3 {j[2]:+.2f} mm along y+), the axial force "
            f"{yp.by_force_mm['axial']:+.2f} mm along y+ and "
            f"{ym.by_force_mm['axial']:+.2f} mm along y- (it keeps its direction in the base "
            "while the lateral axis reverses), as the paper explains; which direction is "
            "lower follows the ASSUMED cw spindle (ccw swaps them); the paper's magnitudes "
            "are only in the figures (not in the extracted text)",
        ),
        Check(
            "000 §3.2.6: ~7 mm lateral deviation at 1700 mm (pin entering)",
            f"y+ {rng(p17)}, y- {rng(m17)} (fanuc_butt_1700mm, reverse = true for y-)",
            abs(p17.lateral_mm[0] - PAPER_1700_MM) <= 1.0
            or abs(m17.lateral_mm[0] - PAPER_1700_MM) <= 1.0,
            f"the ASSUMED {p17.lateral_force_N * 1e-3:g} kN lateral force drives it "
            f"({p17.by_force_mm['lateral']:+.2f} mm, {p17.by_joint_mm[4]:+.2f} mm of it "
            "joint 5's compliance through the ASSUMED 450 mm tool); "
            f"7 mm needs Fl = {p17.lateral_force_for(PAPER_1700_MM) * 1e-3:.2f} kN along y+ "
            f"or {m17.lateral_force_for(PAPER_1700_MM) * 1e-3:.2f} kN along y-; the axial "
            f"force adds {p17.by_force_mm['axial']:+.2f} / {m17.by_force_mm['axial']:+.2f} mm; "
            f"largest change per assumption (fanuc_1700_sensitivity, mm): {moves}; "
            "the paper does not say the direction; tolerance 1 mm",
        ),
    ]


#: Seed 002 §5.2 / Table 3: mean MAE along the surface normal of E13-E18 (formed, no
#: compensation) [mm], and about 0.2 mm with the stiffness compensation (E19-E24, like the
#: force-free runs E01-E06: "around 0.2 mm, typical for industrial robots of this size").
SEED002_MAE_NONE_MM, SEED002_MAE_COMP_MM = 0.4277, 0.2
#: The forming-like path on the torque-dependent KR600.
FORMING = "kr600_forming_contour"


@dataclass(frozen=True)
class FormingCheck:
    """Seed 002's metric on the forming-like path: MAE along the surface normal [mm].

    Attributes:
        mae_mm: (scenario, strategy) -> MAE along the normal [mm]; scenarios ``main`` (truth =
            model), ``stiffness_-20%`` and ``noise_x3`` of ``compare`` (no hidden-effect
            scenario: the robot file already has every tilting compliance).
        max_mm: (scenario, strategy) -> max |error along the normal| [mm].
        axial_N: Axial (forming) force of the problem [N].
    """

    mae_mm: dict[tuple[str, str], float]
    max_mm: dict[tuple[str, str], float]
    axial_N: float


def kr600_forming_check() -> FormingCheck:
    """``compare kr600_forming_contour`` with ``none`` and ``realtime_seed002``."""
    # imported here, not at the top: ``--help`` answers without loading the simulator
    from rfsw_plan.realtime.compare import CompareOptions, compare

    problem = load_problem(FORMING)
    res = compare(problem, CompareOptions(strategies=("none", "realtime_seed002")))
    mae, mx = {}, {}
    for sc in (res.main, *res.sensitivity):
        for k, n in sc.normal.items():
            mae[sc.name, k] = n.mae * 1e3
            mx[sc.name, k] = n.max_abs * 1e3
    return FormingCheck(mae, mx, problem.process.forces.axial)


def _seed002_rows() -> list[Check]:
    """Seed 002 (KUKA KR600) rows: Table 3's MAE along the normal on a forming-like path."""
    f = kr600_forming_check()
    none, comp = f.mae_mm["main", "none"], f.mae_mm["main", "realtime_seed002"]
    soft = next(k for k, _ in f.mae_mm if k.startswith("stiffness"))
    err = (none - SEED002_MAE_NONE_MM) / SEED002_MAE_NONE_MM * 100
    return [
        Check(
            "002 Table 3: MAE along the normal 0.43 mm uncompensated (E13-E18)",
            f"{none:.3f} mm ({err:+.0f} %), max {f.max_mm['main', 'none']:.2f} mm "
            f"(compare {FORMING}, strategy none)",
            abs(err) <= 20.0,
            f"forming forces ASSUMED ({f.axial_N:g} N along the tool for 'over 1000 N', 300 N "
            "lateral, 150 N traverse), a flat 120 mm contour for the 50 deg wall, tool and "
            "placement ASSUMED; scaled linearly in the force, the paper's level "
            f"needs about {f.axial_N * SEED002_MAE_NONE_MM / none:.0f} N; tolerance 20 %",
        ),
        Check(
            "002 Table 3: compensation halves the MAE (0.43 -> ~0.2 mm, E19-E24)",
            f"{none:.3f} -> {comp:.3f} mm (truth = model); truth 20 % softer "
            f"{f.mae_mm[soft, 'none']:.3f} -> {f.mae_mm[soft, 'realtime_seed002']:.3f} mm; "
            f"3x sensor noise {f.mae_mm['noise_x3', 'none']:.3f} -> "
            f"{f.mae_mm['noise_x3', 'realtime_seed002']:.3f} mm",
            comp <= 0.5 * none and f.mae_mm[soft, "realtime_seed002"] <= 0.5 * f.mae_mm[
                soft, "none"],
            "the reduction is reproduced; the level is not: the simulation has no error "
            "besides the deflection, while the paper's robot had ~0.2 mm without any force "
            "(E01-E06: controller at its computational limit, stops, LED plate load), which "
            "no compensation of the stiffness removes; the simulated residual is the MAF/PID "
            "lag at the corners and the model error",
        ),
    ]


def checks(n_points: int = 41) -> list[Check]:
    """Every paper number of issue 15 with the project's measured number and honest status."""
    return [*_seed001_rows(), *_seed000_rows(n_points), *_seed002_rows()]


#: Width of the printed report [characters]: it fits a terminal and the manual's page (the
#: rows were once 250 characters wide and ran off the page).
WIDTH = 96


def _wrapped(text: str, indent: str = "  ") -> list[str]:
    return textwrap.wrap(text, WIDTH, initial_indent=indent, subsequent_indent=indent + "  ",
                         break_on_hyphens=False)


def main() -> None:
    rows = checks()
    for r in rows:  # one block per number: the paper's, the project's, the status and why
        status = "reproduced" if r.reproduced else "NOT reproduced"
        print("\n".join(_wrapped(r.paper, "")))
        print("\n".join(_wrapped(f"project: {r.project}")))
        print("\n".join(_wrapped(f"{status}: {r.why}")))
    print("\nSeed 000, 1700 mm weld: lateral deviation at the first / last waypoint [mm], with one "
          "\nassumption changed")
    sens = fanuc_1700_sensitivity()
    print(f"{'y+ start':>8}  {'y+ end':>8}  {'y- start':>8}  {'y- end':>8}  assumption: variant")
    for s in sens:
        head = (f"{s.y_plus_mm[0]:+8.2f}  {s.y_plus_mm[1]:+8.2f}  {s.y_minus_mm[0]:+8.2f}  "
                f"{s.y_minus_mm[1]:+8.2f}  ")
        print("\n".join(textwrap.wrap(f"{s.assumption}: {s.variant}", WIDTH,
                                       initial_indent=head, subsequent_indent=" " * len(head),
                                       break_on_hyphens=False)))


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
