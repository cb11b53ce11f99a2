"""Virtual trial weld: the log and the track are what the weld did, with the stated noise; and
a weld by a robot equal to the model validates as adequate."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rfsw_plan.elastostatics.model import ElastostaticModel
from rfsw_plan.io.force_series import read_force_series
from rfsw_plan.io.weld_track import read_weld_track
from rfsw_plan.planfiles.folder import PlanFolder
from rfsw_plan.process.problem import load_problem
from rfsw_plan.realtime.trial_weld import simulate_trial_weld
from rfsw_plan.robot.kinematics import load_robot
from rfsw_plan.validation.weld.workbench import validate_weld


def test_truth_equal_to_model_is_adequate(tmp_path: Path, plan_folder: Any) -> None:
    name = "zk500_table6_seam"
    plan_folder(name, tmp_path / "plan")  # rfsw-plan -q plan NAME -o plan, the session's
    pb = load_problem(name)
    model = ElastostaticModel(load_robot(pb.robot))
    rec = PlanFolder.open(tmp_path / "plan").rebuild()
    tw = simulate_trial_weld(pb, rec.waypoints, model, None, seed=3)
    # The track: 0.05 mm white noise on the true offset, ~3 % gaps, every 0.5 mm.
    assert tw.track.e_lat is not None and tw.track.s is not None
    ok = np.isfinite(tw.track.e_lat)
    noise = tw.track.e_lat[ok] - tw.truth_e_lat[ok]
    assert abs(float(np.std(noise)) - 0.05e-3) < 0.01e-3
    assert 0.02 < 1 - ok.mean() < 0.05
    np.testing.assert_allclose(np.diff(tw.track.s), 0.5e-3, rtol=1e-6)
    assert tw.metrics.inside_window_fraction >= 0.99
    forces, track = tw.write(tmp_path / "weld")
    series = read_force_series(forces)
    assert series.frame == "base" and len(series) == len(tw.run.t)
    res = validate_weld(rec, read_weld_track(track), series, model)
    dg = res.diagnosis
    assert dg.verdict == "adequate", dg.message
    assert abs(dg.sigma - 0.05e-3) < 0.01e-3  # the noise floor finds the track noise
    assert float(np.sqrt(np.mean(res.residual_lat**2))) < 0.08e-3
