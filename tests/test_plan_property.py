"""Property test: random seams for all three bundled robots; what is written re-verifies
sample by sample, and what cannot hold is refused with exit 3 (issue 9 §5); every written plan
tolerates at least its mirror baseline's force uncertainty at +-20 % and +-10 % (issue 24).

Seams: straight lines and arcs (spline through points on a circle) through the bundled seam's
midpoint, 30-800 mm long, turned up to +-30 deg in the surface plane, tilt 0-5 deg, both
spindle rotation senses and travel directions, window widths down to 1 mm. Coarse waypoint
spacing and 20 ms samples keep it fast. The default run tries 3 seams, one per robot (a seeded
NumPy draw); ``-m slow`` tries 60 (Hypothesis, derandomised). A seam out of reach is counted
apart (exit 2, the unreachable message).
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import rfsw_plan.planning.api as api
from rfsw_plan.cli.commands.plan import _print_table
from rfsw_plan.cli.main import main
from rfsw_plan.planfiles.folder import PlanFolder
from rfsw_plan.planfiles.waypoints import Q_RESOLUTION
from rfsw_plan.planning.baselines import metrics
from rfsw_plan.planning.robustness import DOMINANCE_TOL
from rfsw_plan.planning.verify import CONTACT_PHASES, verify_samples
from rfsw_plan.process.problem import resolve_problem_path

PROBLEMS = ("zk500_table6_seam", "fanuc_butt_1700mm", "kr600_curved_seam")


def _seam_points(base: dict[str, Any], kind: str, length: float, turn: float, bend: float
                 ) -> list[list[float]]:
    """Points [mm] of a line or arc of ``length`` through the bundled seam's midpoint, its
    direction turned by ``turn`` [deg] about z; an arc bends by ``bend`` [deg] in total."""
    pts = np.asarray(base["seam"]["points_mm"], float)
    mid = 0.5 * (pts[0] + pts[-1])
    d = pts[-1] - pts[0]
    d[2] = 0.0
    d /= np.linalg.norm(d)
    c, s = np.cos(np.deg2rad(turn)), np.sin(np.deg2rad(turn))
    d = np.array([c * d[0] - s * d[1], s * d[0] + c * d[1], 0.0])
    if kind == "line":
        return [list(mid - 0.5 * length * d), list(mid + 0.5 * length * d)]
    ang = np.deg2rad(bend)
    r = length / abs(ang)
    side = np.sign(ang) * np.array([-d[1], d[0], 0.0])
    centre = mid + r * side
    a = np.linspace(-0.5 * abs(ang), 0.5 * abs(ang), 7)
    out = [centre - r * side * np.cos(x) + r * d * np.sin(x) for x in a]
    return [list(p) for p in out]


def _problem(tmp: Path, name: str, kind: str, length: float, turn: float, bend: float,
             tilt: float, rotation: str, reverse: bool, width: float) -> Path:
    base = tomllib.loads(resolve_problem_path(name).read_text())
    seam = base["seam"]
    seam["points_mm"] = _seam_points(base, kind, length, turn, bend)
    seam["interpolation"] = "linear" if kind == "line" else "spline"
    seam["spacing_mm"] = float(max(length / 10.0, 5.0))
    seam["tilt_deg"] = tilt
    seam["rotation"] = rotation
    seam["reverse"] = reverse
    base["window"] = {**base.get("window", {}), "lower_mm": -0.64 * width,
                      "upper_mm": 0.36 * width}
    base["window"].pop("target_mm", None)
    pl = base.setdefault("planning", {})
    pl["sample_dt_s"] = 0.02
    pl["rotation_starts"] = 2
    base["name"] = f"prop_{name}"
    path = tmp / f"{name}.toml"
    path.write_text(tomli_w.dumps(base))
    return path


class Tally:
    def __init__(self) -> None:
        self.written = 0
        self.refused = 0
        self.outside = 0
        self.unreachable = 0

    def line(self) -> str:
        return (f"written {self.written} / refused {self.refused} / written but outside "
                f"{self.outside} (out of reach, not planned: {self.unreachable})")


def _check_one(tmp: Path, tally: Tally, monkeypatch: pytest.MonkeyPatch, capsys: Any,
               case: tuple[Any, ...]) -> None:
    path = _problem(tmp, *case)
    out = tmp / f"out_{case[0]}"
    seen: list[Any] = []
    real_plan = api.plan

    def spy(*a: Any, **k: Any) -> Any:
        res = real_plan(*a, **k)
        seen.append(res)
        return res

    monkeypatch.setattr(api, "plan", spy)
    code = main(["-q", "plan", str(path), "-o", str(out)])
    err = capsys.readouterr().err
    monkeypatch.setattr(api, "plan", real_plan)
    assert "Traceback" not in err
    rec = json.loads((out / "plan.json").read_text()) if (out / "plan.json").exists() else {}
    if code == 2:
        assert "reach" in err or "IK" in err or "workspace" in err, err
        tally.unreachable += 1
        return
    assert code in (0, 3), err
    if code == 3:
        tally.refused += 1
        assert rec.get("status") == "infeasible"
        assert not (out / "waypoints.csv").exists()
        return
    tally.written += 1
    res = seen[-1]
    written = PlanFolder.open(out).samples
    sv = verify_samples(res.model, res.task, res.window, written, res.options.margin, res.q,
                        Q_RESOLUTION)
    c = np.isin(written.phase, CONTACT_PHASES)
    inside = bool(np.all((sv.e_lat[c] >= res.window.lower) & (sv.e_lat[c] <= res.window.upper)))
    if not (sv.ok and inside):
        tally.outside += 1
    assert rec["status"] in ("optimal", "verified", "optimal_nominal", "verified_nominal")
    held = rec["tolerated_force_uncertainty"] is None or (
        rec["tolerated_force_uncertainty"] >= rec["force_uncertainty_requested"] * (1 - 1e-9))
    assert rec["status"].endswith("_nominal") != held
    assert rec["verdict"] == ("GO" if held else "HOLDS NOMINALLY")
    # Issue 24: the plan is never beaten by its mirror baseline, at the problem's request (the
    # CLI run above: +-20 %, +-10 % on kr600_curved_seam) and at the other of +-10 % and
    # +-20 % (planned again through the API, no files); asking for less is never less robust.
    by = rec["tolerated_force_uncertainty_by_strategy"]
    assert by["nlp"] >= by["mirror"] - DOMINANCE_TOL, (case, by)
    u = rec["force_uncertainty_requested"]
    assert u in (0.1, 0.2)
    other = real_plan(path, replace(res.options, force_uncertainty=0.3 - u))
    t2 = other.tolerated_by_strategy
    assert t2["nlp"] >= t2["mirror"] - DOMINANCE_TOL, (case, t2)
    low, high = (t2["nlp"], by["nlp"]) if u > 0.15 else (by["nlp"], t2["nlp"])
    assert low >= high - 1e-6


CASES = st.tuples(
    st.sampled_from(PROBLEMS),
    st.sampled_from(["line", "arc"]),
    st.floats(30.0, 800.0),
    st.floats(-30.0, 30.0),
    st.sampled_from([-60.0, -30.0, 30.0, 60.0]),
    st.floats(0.0, 5.0),
    st.sampled_from(["cw", "ccw"]),
    st.booleans(),
    st.floats(1.0, 1.95),
)


def _run(n: int, tmp_path_factory: Any, monkeypatch: Any, capsys: Any) -> None:
    tally = Tally()

    @settings(max_examples=n, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(CASES)
    def prop(case: tuple[Any, ...]) -> None:
        tmp = tmp_path_factory.mktemp("seam")
        _check_one(tmp, tally, monkeypatch, capsys, case)

    prop()
    with capsys.disabled():
        print("\n" + tally.line())
    assert tally.written + tally.refused >= n // 2  # most seams are reachable
    assert tally.outside == 0, tally.line()


def _default_cases(n: int = 3, seed: int = 0) -> list[tuple[Any, ...]]:
    """The default run's seams: CASES' ranges drawn by a seeded NumPy generator, one per
    robot (``-m slow`` tries 60 with Hypothesis). (Hypothesis mixes number constants of the
    modules already imported into its draws, derandomised or not, so its six seams depended
    on which tests ran before on the same worker: a seam below its mirror came up alone and
    not in the suite.)"""
    rng = np.random.default_rng(seed)
    return [(PROBLEMS[k % len(PROBLEMS)], str(rng.choice(["line", "arc"])),
             float(rng.uniform(30.0, 800.0)), float(rng.uniform(-30.0, 30.0)),
             float(rng.choice([-60.0, -30.0, 30.0, 60.0])), float(rng.uniform(0.0, 5.0)),
             str(rng.choice(["cw", "ccw"])), bool(rng.integers(2)),
             float(rng.uniform(1.0, 1.95))) for k in range(n)]


def test_random_seams_written_or_refused(tmp_path_factory, monkeypatch, capsys) -> None:
    tally = Tally()
    cases = _default_cases()
    for case in cases:
        _check_one(tmp_path_factory.mktemp("seam"), tally, monkeypatch, capsys, case)
    with capsys.disabled():
        print("\n" + tally.line())
    assert tally.written + tally.refused >= len(cases) // 2  # most seams are reachable
    assert tally.outside == 0, tally.line()


#: A seam whose plan holds less force uncertainty than its mirror baseline's waypoints (+-3.54 %
#: against +-5.38 %), found by the property search (a reversed zk500 arc of 410 mm, waypoints
#: 41 mm apart; shrinking finds arcs of 333-410 mm). The mirror's written samples leave the
#: window with the margin between its waypoints, so it cannot be written: judged as written,
#: as the plan is, it holds nothing, and the plan says so instead of claiming it below a floor.
BELOW_MIRROR = ("zk500_table6_seam", "arc", 409.8, 0.0002, 30.0, 3.54, "cw", True, 1.0)


def test_a_mirror_that_cannot_be_written_holds_nothing(tmp_path, monkeypatch, capsys) -> None:
    # The refusal is the planner's own check of a plan, run on the mirror: written, timed and
    # sample-checked, one of its samples leaves the window with the margin.
    refused: list[str] = []
    real = api.written_plan

    def spy(*a: Any, **k: Any) -> Any:
        try:
            return real(*a, **k)
        except api.InfeasibleError as exc:
            if a[7:8] == ("mirror",):
                refused.append(str(exc))
            raise

    monkeypatch.setattr(api, "written_plan", spy)
    res = api.plan(_problem(tmp_path, *BELOW_MIRROR))
    assert len(refused) == 1 and "outside the window with the margin" in refused[0], refused
    mirror = next(b for b in res.baselines if b.name == "mirror")
    d = mirror.to_dict()
    # The case that matters: at its waypoints alone the mirror holds more than the plan.
    assert d["tolerated_at_waypoints_pct"] > 100 * res.plan_metrics.tolerated + 1.0, d
    assert d["tolerated_force_uncertainty_pct"] == 0.0
    assert d["tolerated_force_uncertainty_by_quantity_pct"] is None
    assert refused[0].startswith(d["cannot_be_written"]), d
    assert res.source == "nlp" and res.plan_metrics.tolerated > 0.03
    # Judged on the same basis the plan dominates either way: at the waypoints alone it holds
    # more than the mirror's waypoints (+-7.37 % against +-5.38 %), at the written samples
    # the mirror holds nothing.
    at_waypoints = metrics("nlp", res.model, res.task, res.q, res.window,
                           res.options.force_uncertainty)
    assert 100 * at_waypoints.tolerated >= d["tolerated_at_waypoints_pct"] + 1.0
    by = res.tolerated_by_strategy
    assert by["nlp"] >= by["mirror"] - DOMINANCE_TOL and by["mirror"] == 0.0, by
    capsys.readouterr()
    _print_table(res)  # the plan command's table
    lines = capsys.readouterr().out.splitlines()
    assert any(line.startswith("mirror ") and line.rstrip().endswith(
        "holds none: cannot be written") for line in lines), lines
    assert any(line.startswith("mirror: holds up to +-5.38 % at its waypoints alone, but "
                               "cannot be written: lateral fails first: sample ")
               for line in lines), lines


@pytest.mark.slow
def test_random_seams_written_or_refused_many(tmp_path_factory, monkeypatch, capsys) -> None:
    _run(60, tmp_path_factory, monkeypatch, capsys)
