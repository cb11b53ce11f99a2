"""Plan your own seam: a seam CSV, your own process forces, a verified plan folder.

Copy this script, replace the seam points and force values with yours, and run::

    PYTHONPATH=. .venv/bin/python examples/plan_my_seam.py [OUT_DIR]

(default OUT_DIR: ``out/examples/plan_my_seam``, under the git-ignored ``out/``)

It writes ``my_seam.csv`` and ``my_weld.toml`` (a problem file: robot, seam, process, window)
into OUT_DIR, plans it with :func:`rfsw_plan.plan` and writes the plan folder
``OUT_DIR/plan`` exactly as ``rfsw-plan plan OUT_DIR/my_weld.toml -o OUT_DIR/plan`` would:
``waypoints.csv``, ``lateral_error.png``, ``lateral_error_time.png`` and ``plan.json``.
Units are in the names (mm, N, s); vectors are in the robot base frame.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import rfsw_plan
from rfsw_plan.files import prepare_output_dir

# Your taught seam: points in travel order, robot base frame [mm]. Here a 60 mm straight seam
# in front of the bundled ZK-500 (the seed 001 cell). Add nx,ny,nz columns for a per-point
# surface normal.
SEAM_MM = [(269.52, -2070.91, 663.15), (274.00, -2011.00, 663.60)]

# Your process forces at steady welding [N] (measured on a trial weld or from your process
# sheet): axial (plunge) force, lateral force and traverse (travel) force.
AXIAL_N, LATERAL_N, TRAVERSE_N = 4500.0, 1200.0, 850.0

PROBLEM = """\
name = "my_weld"
robot = "zk500"                 # a bundled robot or the path of your robot file

[seam]
csv = "my_seam.csv"             # relative to this file
spacing_mm = 10.0
tilt_deg = 2.0
rotation = "cw"                 # spindle rotation seen from above: decides the advancing side
surface_normal = [0, 0, 1]

[process]
preset = "seed001_aa6061_5mm"   # speeds, plunge and dwell; the forces below override it

[process.forces]
axial_N = {axial}
lateral_N = {lateral}
traverse_N = {traverse}
lateral_sign = 1                # +1: the lateral force points toward the advancing side

[window]                        # where the pin may be, relative to the joint line
lower_mm = -1.25
upper_mm = 0.7

[planning]
q_seed_deg = [-96.24, 3.91, 25.45, -2.10, 57.17, 2.90]   # a pose near the seam
tool_rotation_deg = 180.0
force_uncertainty = 0.2         # keep the pin in the window for +-20 % on every force
"""


def write_problem(out: Path) -> Path:
    """Write ``my_seam.csv`` and the problem file ``my_weld.toml`` into ``out``."""
    out = prepare_output_dir(out, "OUT_DIR")  # a file or unwritable folder: one line, exit 2
    rows = ["x_mm,y_mm,z_mm"] + [f"{x},{y},{z}" for x, y, z in SEAM_MM]
    (out / "my_seam.csv").write_text("\n".join(rows) + "\n")
    problem_file = out / "my_weld.toml"
    problem_file.write_text(PROBLEM.format(axial=AXIAL_N, lateral=LATERAL_N,
                                           traverse=TRAVERSE_N))
    return problem_file


def main(out: Path) -> rfsw_plan.PlanResult:
    problem_file = write_problem(out)

    problem = rfsw_plan.load_problem(problem_file)   # strict: a wrong key is a one-line error
    result = rfsw_plan.plan(problem)                 # raises InfeasibleError if it cannot hold
    plan_json = rfsw_plan.write_plan(out / "plan", result, robot_file=problem.robot.path)

    print(f"{result.status}: max |lateral error| "
          f"{result.summary()['samples']['max_abs_lateral_mm']:.3f} mm in the material "
          f"(uncompensated {abs(result.e_none).max() * 1e3:.3f} mm), tolerates "
          f"+-{result.tolerated_force_uncertainty * 100:.3g} % force")
    print(f"files: {plan_json.parent}")
    return result


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out_dir", nargs="?", type=Path,
                    default=Path("out") / "examples" / "plan_my_seam",
                    help="folder for my_seam.csv, my_weld.toml and the plan folder "
                         "(default: out/examples/plan_my_seam)")
    args = ap.parse_args()
    try:
        main(args.out_dir)
    except rfsw_plan.RfswError as exc:
        print(f"plan_my_seam: error: {exc}", file=sys.stderr)
        sys.exit(getattr(exc, "exit_code", 2))
