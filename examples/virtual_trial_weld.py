"""Stand in for a real trial weld: weld a written plan on a virtual robot and bring back its logs.

A real trial weld gives a force log of the spindle or wrist sensor and a measured weld track.
Without a cell, this script runs the plan of ``PLAN_DIR`` open loop on a *truth* robot that
differs from the model the plan was made with (joint ``--softer-joint`` 20 % softer, by
default joint 1), on the virtual weld of ``rfsw-plan compare`` (process drift +-10 % along the
seam, 30 N force sensor noise, 4 ms cycle), and writes what the cell would bring back:

* ``OUT_DIR/trial_forces.csv``: the logged force, base frame (``t_s, fx_N, ...``);
* ``OUT_DIR/trial_track.csv``: the measured weld centreline (``s_mm, e_lat_mm, e_norm_mm``,
  0.05 mm noise, 3 % gaps).

Both are the formats ``rfsw-plan validate-weld`` and ``plan --forces`` read. Run::

    PYTHONPATH=. .venv/bin/python examples/virtual_trial_weld.py PLAN_DIR OUT_DIR [--softer-joint N]

(:func:`rfsw_plan.realtime.trial_weld.simulate_trial_weld`; ``examples/trial_weld_loop.py``
runs the whole loop with it.)
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import RfswError
from rfsw_plan.planfiles.folder import PlanFolder
from rfsw_plan.robot.kinematics import load_robot


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], allow_abbrev=False)
    ap.add_argument("plan_dir", help="folder written by rfsw-plan plan")
    ap.add_argument("out_dir", help="folder for trial_forces.csv and trial_track.csv")
    ap.add_argument("--softer-joint", type=int, default=1, metavar="N",
                    help="1-based joint of the truth robot made 20 %% softer (default 1)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the noise and gaps")
    args = ap.parse_args(argv)
    try:
        record = PlanFolder.open(args.plan_dir).rebuild()
        model = ElastostaticModel(load_robot(record.robot))
        n = len(model.joint_compliance.params)
        if not 1 <= args.softer_joint <= n:
            print(f"--softer-joint: {args.softer_joint} is not a joint of the robot (1..{n})",
                  file=sys.stderr)
            return 2
        truth = model.copy()
        c = np.array(truth.joint_compliance.params, dtype=float)
        c[args.softer_joint - 1] /= 0.8
        truth.joint_compliance.params = c
        # imported here, not at the top: ``--help`` answers without loading the simulator
        from rfsw_plan.realtime.trial_weld import simulate_trial_weld

        weld = simulate_trial_weld(record.problem, record.waypoints, model, truth, seed=args.seed)
        forces, track = weld.write(args.out_dir)
    except RfswError as exc:
        print(f"virtual_trial_weld: error: {exc}", file=sys.stderr)
        return exc.exit_code
    m = weld.metrics
    print(f"virtual trial weld of {args.plan_dir} on a truth with joint {args.softer_joint} "
          f"20 % softer: {100 * m.inside_window_fraction:.1f} % of the weld inside the window, "
          f"max |e| {1e3 * m.max_abs_lateral:.2f} mm")
    print(f"wrote {forces} and {track}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
