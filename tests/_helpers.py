"""Test helpers shared by several test modules (no test imports another test module):
the ZK-500 seed 001 seam, its seed pose and its steady process force, and a simulated trial
weld of the default problem."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.process.frames import SeamFrames

#: Seed pose of the ZK-500 on the seed 001 seam [rad].
Q_SEED = np.deg2rad([-82.6, 41.73, 18.5, 0.18, 30.22, 11.57])
#: Seed 001 steady forces (f_t, f_l, f_n) [N].
F_SEAM = np.array([-899.80, 1350.87, 4842.58])


def zk500_frames(k: int) -> SeamFrames:
    """``k`` frames along the straight seed 001 seam of the ZK-500 (base frame, [m])."""
    a = np.array([269.52, -2070.91, 663.15]) * 1e-3
    b = np.array([278.10, -1957.60, 664.05]) * 1e-3
    L = float(np.linalg.norm(b - a))
    t = np.tile((b - a) / L, (k, 1))
    n = np.tile([0.0, 0.0, 1.0], (k, 1))
    n -= np.einsum("ki,ki->k", n, t)[:, None] * t
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    s = np.linspace(0.0, L, k)
    return SeamFrames(s, a + s[:, None] * t[0], t, np.cross(n, t), n)


def softer_joint1_weld(root: Path, problem: str = "zk500_table6_seam",
                       plan_folder: Any = None) -> tuple[Path, Path, Path]:
    """Plan ``problem`` with its robot's model into ``root/plan`` (a copy of the session's plan
    with the ``plan_folder`` fixture, else ``rfsw-plan plan``), then weld it (simulated) on a
    truth whose joint 1 is 20 % softer; returns (plan folder, forces CSV, track CSV)."""
    from rfsw_plan.cli.main import main
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.planfiles.folder import PlanFolder
    from rfsw_plan.process.problem import load_problem
    from rfsw_plan.realtime.trial_weld import simulate_trial_weld
    from rfsw_plan.robot.kinematics import load_robot

    pb = load_problem(problem)
    model = ElastostaticModel(load_robot(pb.robot))
    truth = model.copy()
    c = np.array(truth.joint_compliance.params)
    c[0] /= 0.8
    truth.joint_compliance.params = c
    if plan_folder is not None:
        plan_folder(problem, root / "plan")
    else:
        assert main(["-q", "plan", problem, "-o", str(root / "plan")]) == 0
    planned = PlanFolder.open(root / "plan").rebuild().waypoints
    forces, track = simulate_trial_weld(pb, planned, model, truth).write(root / "weld")
    return root / "plan", forces, track
