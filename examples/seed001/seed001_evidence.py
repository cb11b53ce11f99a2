"""Seed 001's numbers as one measurement set the workbench reads (issue 28).

Seed 001 (Chen et al., Sensors 2024, 24, 1001) gives no raw data, but it gives numbers that a
model of its ZK-500 must reproduce together:

* §2.2.2, Table 2 and Table 3: the joint stiffness identified by a steel-cable campaign in five
  poses. The raw readings are not published; the rows here are what the Table 3 model predicts
  for the campaign of ``seed001_campaign.py`` beside this file (ASSUMED anchor, tensions
  and device noise). They carry Table 3, nothing more.
* §2.1 and §3: the real weld. Commanded plunge about 8 mm after surface contact, the actual
  plunge "suitable for the length of the stirring tool" (pin 4.8 mm, §2.3.1), steady forces
  Fl0 = 1350.87 N, Fd0 = 4842.58 N, Fr0 = 899.80 N, and a lateral displacement of the seam of
  about 4.9 mm (Fig. 3b, §4).

Each weld row is one seam waypoint under the steady weld wrench (seam frame -> base frame as
the process model does). Its commanded TCP is the waypoint 8 mm down the base z axis (the
paper plunges "in the negative direction of the z-axis", §4; joint values by IK); what was
measured is how deep the pin really went::

    z_measured = z_k - 4.8 mm          (x, y blank: not measured)

so the robot gave way 3.2 mm up under the steady weld wrench.

The 4.9 mm lateral displacement is *not* a row. The workbench compares positions axis by axis
in the base frame; the seam's lateral axis is 4.3 deg off the base x axis and the along-track
position was not measured, so no base-frame axis holds the lateral alone (a held device-frame
registration turns a row with one blank axis into a row with three blank axes). It is checked
by the co-simulation instead (``deviation --cosim``: ``cosim.lateral_mm``).

ASSUMED (the paper does not say): the 4.8 mm depth holds at the start, middle and end of the
seam; it is read along the surface normal (base z; the plate is level to 0.5 deg, Table 6);
it is read to about 0.1 mm (``sigma_mm``).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rfsw_plan.elastostatics.measurement_set import FloatArray, MeasurementSet
from rfsw_plan.elastostatics.model import ElastostaticModel, load_model
from rfsw_plan.exceptions import RfswError
from rfsw_plan.files import atomic_path
from rfsw_plan.io.measurements import write_measurements
from rfsw_plan.process.cosim import PenetrationObservation
from rfsw_plan.process.presets import SEED001_FIG10
from rfsw_plan.process.problem import Problem, load_problem
from rfsw_plan.process.taught import taught_path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # seed001_campaign beside this file
from seed001_campaign import CableCampaign, simulate_cable_campaign

#: Seed 001 §2.1: "the motion command of the robot end-effector was about 8 mm" [mm].
COMMANDED_PLUNGE_MM = 8.0
#: Seed 001 §2.1 / §2.3.1: actual plunge "suitable for the length of the stirring tool", whose
#: pin is 4.8 mm long [mm].
PENETRATION_MM = 4.8
#: Seed 001 §4 / Fig. 3b: "the actual displacement of the weld seam was approximately 4.9 mm"
#: [mm] (the virtual weld's 5.24 mm is the paper's model, not a measurement).
LATERAL_MM = 4.9
#: Seed 001 §3: steady forces of the real weld [N].
FL0_N, FD0_N, FR0_N = 1350.87, 4842.58, 899.80
#: ASSUMED reading precision of "about 4.8 mm" and "about 4.9 mm", 1 sigma [mm].
WELD_SIGMA_MM = 0.1
#: ASSUMED precision of the reconstructed cable readings, 1 sigma [mm]: the campaign's
#: tracker-class 0.02 mm per sample averaged over 50 samples.
CABLE_SIGMA_MM = 0.02 / math.sqrt(50)
#: Base-frame up: the paper plunges along -z (§4).
_UP = np.array([0.0, 0.0, 1.0])
#: Waypoints of zk500_table6_seam that become weld rows: start, middle, end.
WELD_WAYPOINTS = (0, 12, 23)
#: The problem whose seam, process and IK branch the weld rows use.
PROBLEM = "zk500_table6_seam"


@dataclass(frozen=True)
class Seed001Evidence:
    """The measurement set and the plunges.

    Attributes:
        data: Cable rows then weld rows, positions in the base frame.
        plunges: Seed 001 Fig. 10's commanded plunges and penetrations.
        n_cable: Number of cable rows (the first rows of ``data``).
    """

    data: MeasurementSet
    plunges: tuple[PenetrationObservation, ...]
    n_cable: int


def _weld_rows(problem: Problem, model: ElastostaticModel) -> tuple[FloatArray, FloatArray,
                                                                     FloatArray]:
    """Joint values (k, n) [rad], base-frame wrench (k, 6) [N, N m] and measured pin position
    (k, 3) [m] base frame, at the weld waypoints."""
    frames = problem.frames()
    idx = np.asarray(WELD_WAYPOINTS)
    down = replace(frames, p=frames.p - COMMANDED_PLUNGE_MM * 1e-3 * _UP)
    Q = taught_path(model.robot, down, problem.q_seed(), problem.planning.tool_rotation)[idx]
    process = problem.process
    F = np.tile(process.steady_force_seam(), (len(idx), 1))
    sub = replace(frames, s=frames.s[idx], p=frames.p[idx], t=frames.t[idx], l=frames.l[idx],
                  n=frames.n[idx])
    sigma = np.sign(np.linalg.det(sub.rotation()))
    M = (sigma * process.forces.spindle_torque)[:, None] * sub.n
    W = np.hstack([sub.to_base(F), M]) + 0.0  # + 0.0: no -0 in the file
    measured = np.full_like(sub.p, np.nan)
    measured[:, 2] = sub.p[:, 2] - PENETRATION_MM * 1e-3
    return Q, W, measured


def seed001_evidence(model: ElastostaticModel | None = None) -> Seed001Evidence:
    """Build the seed 001 evidence set (deterministic: the cable noise has a fixed seed).

    Args:
        model: The model whose Table 3 stiffness reconstructs the cable rows (default the
            bundled zk500).
    """
    model = model or load_model("zk500")
    problem = load_problem(PROBLEM)
    cable = simulate_cable_campaign(CableCampaign(), truth=model, seed=0).data
    Q, W, measured = _weld_rows(problem, model)
    k = len(Q)
    pose_id = np.concatenate([cable.pose_id if cable.pose_id is not None else [],
                              [f"weld-wp{i}" for i in WELD_WAYPOINTS]]).astype(np.str_)
    load_step = np.concatenate([cable.load_step if cable.load_step is not None else [],
                                np.ones(k, dtype=int)]).astype(int)
    sigma = np.concatenate([np.full(len(cable), CABLE_SIGMA_MM), np.full(k, WELD_SIGMA_MM)])
    data = MeasurementSet(
        q=np.vstack([cable.q, Q]), wrench=np.vstack([cable.wrench, W]),
        position=np.vstack([cable.position, measured]),
        pose_id=pose_id, load_step=load_step, sigma=sigma * 1e-3,
        source="<seed 001 evidence>",
    )
    return Seed001Evidence(data, SEED001_FIG10, len(cable))


def write_seed001_evidence(folder: str | Path, evidence: Seed001Evidence | None = None) -> list[
        Path]:
    """Write ``measurements.csv`` and ``plunges.csv`` into ``folder``.

    Returns:
        The written paths.
    """
    ev = evidence or seed001_evidence()
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = [write_measurements(out / "measurements.csv", ev.data)]
    rows = ["commanded_mm,penetration_mm,lower_bound,source"]
    for o in ev.plunges:
        src = ("seed 001 §2.1 (real weld) and Fig. 10b" if o.commanded_depth == 8e-3
               else "seed 001 Fig. 10" + ("c: exceeded the 5 mm plate" if o.at_least else "a"))
        rows.append(f"{o.commanded_depth * 1e3:g},{o.penetration * 1e3:g},"
                    f"{int(o.at_least)},{src}")
    with atomic_path(out / "plunges.csv") as tmp:
        tmp.write_text("\n".join(rows) + "\n")
    paths.append(out / "plunges.csv")
    return paths


if __name__ == "__main__":
    ap = argparse.ArgumentParser(
        description="Write seed 001's evidence set (measurements.csv, plunges.csv) into FOLDER; "
                    "examples/seed001/ holds the written set (see its README).")
    ap.add_argument("folder", help="folder to write into (created if missing)")
    args = ap.parse_args()
    try:
        for path in write_seed001_evidence(args.folder):
            print(path)
    except RfswError as exc:  # a folder that cannot be written: one line, as the CLI says it
        print(f"seed001_evidence: error: {exc}", file=sys.stderr)
        sys.exit(getattr(exc, "exit_code", 2))
