"""The trial-weld loop on a virtual cell: plan, weld, validate against the weld, re-plan, weld.

For each truth difference (the real robot differs from the model the plan uses):

1. ``rfsw-plan plan PROBLEM`` with the model;
2. a virtual trial weld on the truth robot (process drift +-10 %, sensor noise 30 N, a
   track with 0.05 mm noise and gaps) writes ``weld1/trial_forces.csv`` and
   ``weld1/trial_track.csv`` (:func:`rfsw_plan.realtime.trial_weld.simulate_trial_weld`);
3. ``rfsw-plan validate-weld plan1 --track ... --forces ...`` names the difference;
4. ``validate-weld ... --add BEST --save-robot robot_weld.toml``, then
   ``rfsw-plan plan PROBLEM --forces weld1/trial_forces.csv --robot robot_weld.toml``;
5. a second virtual weld of the new plan on the same truth.

Prints the share of the weld length inside the window for both welds (measured on the truth
pin, every 4 ms cycle), and what validate-weld said. Run:
``PYTHONPATH=. .venv/bin/python examples/trial_weld_loop.py [OUT_DIR]`` (default OUT_DIR:
``out/examples/trial_weld_loop``).
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rfsw_plan.cli.main import main
from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.exceptions import RfswError
from rfsw_plan.planfiles.folder import PlanFolder
from rfsw_plan.process.problem import load_problem
from rfsw_plan.robot.kinematics import load_robot

PROBLEM = "zk500_table6_seam"
#: Truth differences: (name, joint made 20 % softer or None, hidden effect label or None).
DIFFERENCES = (
    ("joint 1 20 % softer", 0, None),
    ("hidden tilting compliance of joint 3", None, "tilting_compliance:j3"),
)


@dataclass(frozen=True)
class LoopResult:
    """One pass of the loop.

    Attributes:
        difference: What the truth has that the model lacks.
        truth_label: The candidate label of that difference.
        inside_first / inside_second: Share of the weld length inside the window, truth pin.
        max_first / max_second: Max |lateral error| over the weld [mm].
        verdict, best, ties: validate-weld's verdict, best candidate and the candidates it
            cannot tell from the best.
        stiffness_scale: Fitted stiffness scale of the best candidate (joint candidates).
        rms_before / rms_after: Lateral+normal residual RMS before / after --add [mm].
        holds_measured_box: The second plan holds under the measured force uncertainty.
    """

    difference: str
    truth_label: str
    inside_first: float
    inside_second: float
    max_first: float
    max_second: float
    verdict: str
    best: str
    ties: tuple[str, ...]
    stiffness_scale: float | None
    rms_before: float
    rms_after: float
    holds_measured_box: bool

    @property
    def named(self) -> bool:
        """The truth's difference is the best candidate or one the weld cannot tell from it."""
        return self.truth_label == self.best or self.truth_label in self.ties


class LoopError(Exception):
    """A step of the loop (an rfsw-plan command) failed; its own error line went to stderr."""


def _cli(args: list[str]) -> None:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["-q", *args])
    if code != 0:
        raise LoopError(f"rfsw-plan {' '.join(args)} exited {code}")


def run_loop(folder: Path, name: str, joint: int | None, hidden: str | None,
             problem: str = PROBLEM) -> LoopResult:
    """Run the loop of the module docstring in ``folder`` for one truth difference."""
    # imported here, not at the top: ``--help`` answers without loading the simulator
    from rfsw_plan.realtime.trial_weld import simulate_trial_weld

    pb = load_problem(problem)
    model = ElastostaticModel(load_robot(pb.robot))
    truth = model.copy()
    if joint is not None:
        c = np.array(truth.joint_compliance.params, dtype=float)
        c[joint] /= 0.8
        truth.joint_compliance.params = c
        label = f"joint_compliance:j{joint + 1}"
    else:
        assert hidden is not None
        truth = truth.with_effect(hidden)
        label = hidden
    plan1, plan2 = folder / "plan1", folder / "plan2"
    _cli(["plan", problem, "-o", str(plan1)])
    weld1 = simulate_trial_weld(pb, PlanFolder.open(plan1).rebuild().waypoints, model, truth,
                                seed=1)
    forces, track = weld1.write(folder / "weld1")
    _cli(["validate-weld", str(plan1), "--track", str(track), "--forces", str(forces),
          "-o", str(folder / "validate1")])
    v1 = json.loads((folder / "validate1" / "validate_weld.json").read_text())
    dg1 = v1["diagnosis"]
    best = next(c for c in dg1["candidates"] if c["label"] == dg1["best"])
    robot = folder / "robot_weld.toml"
    _cli(["validate-weld", str(plan1), "--track", str(track), "--forces", str(forces),
          "--add", best["label"], "--save-robot", str(robot), "-o", str(folder / "validate1_add")])
    v1a = json.loads((folder / "validate1_add" / "validate_weld.json").read_text())
    _cli(["plan", problem, "--forces", str(forces), "--robot", str(robot), "-o", str(plan2)])
    p2 = json.loads((plan2 / "plan.json").read_text())
    weld2 = simulate_trial_weld(pb, PlanFolder.open(plan2).rebuild().waypoints, model, truth,
                                seed=2)
    return LoopResult(
        difference=name, truth_label=label,
        inside_first=weld1.metrics.inside_window_fraction,
        inside_second=weld2.metrics.inside_window_fraction,
        max_first=weld1.metrics.max_abs_lateral * 1e3,
        max_second=weld2.metrics.max_abs_lateral * 1e3,
        verdict=v1["diagnosis"]["verdict"], best=best["label"],
        ties=tuple(v1["diagnosis"]["indistinguishable_from_best"]),
        stiffness_scale=best["stiffness_scale"],
        rms_before=v1a["add"]["rms_before_mm"], rms_after=v1a["add"]["rms_after_mm"],
        holds_measured_box=bool(p2["force_log"]["plan_under_measured_uncertainty"]["holds"]),
    )


def report(r: LoopResult) -> str:
    """A few lines per loop."""
    k = f" (stiffness x{r.stiffness_scale:.3f})" if r.stiffness_scale is not None else ""
    return "\n".join([
        f"truth: {r.difference} ({r.truth_label})",
        f"  weld 1 (plan from the model):        {100 * r.inside_first:6.1f} % of the length "
        f"inside the window, max |e| {r.max_first:.3f} mm",
        f"  validate-weld: {r.verdict}, best {r.best}{k}; the truth is "
        f"{'named' if r.named else 'NOT named'} ({len(r.ties)} candidates explain it as well)",
        f"  --add {r.best}: residual RMS {r.rms_before:.4f} -> {r.rms_after:.4f} mm",
        f"  weld 2 (re-identified robot, logged forces): {100 * r.inside_second:6.1f} % inside, "
        f"max |e| {r.max_second:.3f} mm; plan holds under the measured force uncertainty: "
        f"{'yes' if r.holds_measured_box else 'no'}",
    ])


def run_all(folder: Path) -> list[LoopResult]:
    """Every difference of :data:`DIFFERENCES`, each in a subfolder."""
    return [run_loop(folder / f"truth{i + 1}", name, joint, hidden)
            for i, (name, joint, hidden) in enumerate(DIFFERENCES)]


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out_dir", nargs="?", type=Path,
                    default=Path("out") / "examples" / "trial_weld_loop",
                    help="folder for both loops (default: out/examples/trial_weld_loop)")
    out = ap.parse_args().out_dir
    try:
        results = run_all(out)
    except (RfswError, LoopError) as exc:  # one line, as the CLI says it
        print(f"trial_weld_loop: error: {exc}", file=sys.stderr)
        sys.exit(getattr(exc, "exit_code", 2))
    print(f"problem {PROBLEM}, window [-1.25, +0.7] mm, track noise 0.05 mm, force drift "
          "+-10 %, sensor noise 30 N")
    for r in results:
        print(report(r))
