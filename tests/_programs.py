"""A fixed synthetic joint path on the ZK-500 for the program tests (golden files, the toy
format, long programs): no planner run, so these tests take milliseconds."""

from __future__ import annotations

import numpy as np

from rfsw_plan.export.program import ProgramHeader, Samples
from rfsw_plan.robot.kinematics import Robot, load_robot


def synthetic(n_weld: int = 20, wiggle: float = 0.0) -> tuple[Robot, Samples, ProgramHeader]:
    """Approach, plunge, dwell (held still), a curved weld of ``n_weld`` samples, retract.

    ``wiggle`` [rad] adds a joint-1 oscillation along the weld, so a long seam keeps many
    points after the Douglas-Peucker selection.
    """
    robot = load_robot("zk500")
    q0 = np.radians([-96.24, 3.91, 25.45, -2.10, 57.17, 2.90])
    phases = ["approach"] * 6 + ["plunge"] * 6 + ["dwell"] * 6 + ["accelerate"] * 3 + \
        ["weld"] * n_weld + ["decelerate"] * 3 + ["retract"] * 6
    n = len(phases)
    t = np.arange(n) * 0.1
    q = np.repeat(q0[None], n, axis=0)
    ramp = np.concatenate([np.linspace(0, 1, 6), np.ones(n - 6)])
    q[:, 1] += np.radians(2.0) * ramp
    w = np.array([p in ("accelerate", "weld", "decelerate") for p in phases])
    c = np.cumsum(w) * (20 / n_weld)  # the same weld, sampled more finely
    q[:, 0] += np.radians(0.2) * c / 10
    q[:, 2] += np.radians(0.05) * c ** 2 / 100
    q[:, 0] += wiggle * np.sin(np.cumsum(w) * 0.7) * w
    back = np.array([p == "retract" for p in phases])
    q[:, 1] -= np.radians(0.5) * np.cumsum(back) / 6  # the retract lifts the tool
    T = robot.batch_fk_jacobian(q)[0]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1))])
    s = np.where(w | (np.cumsum(w) > 0), s - s[np.argmax(w)], 0.0)
    s = np.maximum.accumulate(np.maximum(s, 0.0))
    seam = T[:, :3, 3] - 0.002 * T[:, :3, 2]  # the pin tip is 2 mm below the surface
    samples = Samples(t, np.array(phases), s, q, np.zeros((n, 6)), seam)
    header = ProgramHeader("rfsw_golden", "golden-000000000000", "golden", "zk500",
                           "zk500.toml", "0123456789abcdef" * 4, "0.1.0", 0.2, 0.2,
                           (-1.25, 0.7), 1e-5, 5e-3)
    return robot, samples, header
