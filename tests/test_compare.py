"""Offline vs real-time comparison: acceptance checks of issue 6 (§5, §6) and the CLI."""

from __future__ import annotations

import json
import re
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.exceptions import InputError, UnknownNameError
from rfsw_plan.process.problem import load_problem
from rfsw_plan.realtime.compare import (
    STRATEGIES,
    CompareOptions,
    CompareResult,
    compare,
    parse_effect_arg,
)

PROBLEMS = ("zk500_table6_seam", "fanuc_butt_1700mm")
REALTIME = ("realtime_seed000", "realtime_seed002")


@cache
def result(name: str) -> CompareResult:
    """All strategies, truth = model in the main run, plus the sensitivity reruns."""
    return compare(load_problem(name), CompareOptions())


@pytest.mark.usefixtures("stored_plans")  # the session's plans (conftest)
@pytest.mark.parametrize("name", PROBLEMS)
def test_seed000_shows_the_settling_transient_at_weld_start(name: str) -> None:
    """Seed 000 Fig. 21: several mm at the weld start, then inside the window."""
    res = result(name)
    run = res.main.runs["realtime_seed000"]
    m = res.main.metrics["realtime_seed000"]
    w = run.weld
    s = run.s[w] - run.s[w][0]
    e = run.lateral_error[w]
    first = s < 0.010
    assert np.max(np.abs(e[first])) > 2.0e-3  # several mm in the first 10 mm
    assert 0.0 < m.settling < 0.05 * m.weld_length + 0.010
    # After settling it stays near the seam (the transient is a start effect).
    late = s > 0.2 * s[-1]
    assert np.max(np.abs(e[late])) < 1.0e-3
    # Uncompensated, the pin is (all but) never in the window.
    assert res.main.metrics["none"].inside_window_fraction < 0.01


@pytest.mark.usefixtures("stored_plans")  # the session's plans (conftest)
@pytest.mark.parametrize("name", PROBLEMS)
def test_offline_is_inside_the_window_when_truth_equals_model(name: str) -> None:
    m = result(name).main.metrics["offline"]
    assert m.inside_window_fraction >= 0.99


@pytest.mark.usefixtures("stored_plans")  # the session's plans (conftest)
@pytest.mark.parametrize("name", PROBLEMS)
def test_hybrid_is_at_least_as_good_as_the_best_other_when_truth_differs(name: str) -> None:
    res = result(name)
    others = ("offline", *REALTIME)
    for sc in res.sensitivity:
        if sc.name.startswith("noise"):
            continue  # truth = model there
        hyb = sc.metrics["hybrid"]
        best_rms = min(sc.metrics[k].rms_lateral for k in others)
        assert hyb.rms_lateral <= best_rms * 1.02 + 1e-6, sc.name
        best_max = min(sc.metrics[k].max_abs_lateral for k in others)
        assert hyb.max_abs_lateral <= best_max * 1.05 + 1e-6, sc.name
    hidden = next(sc for sc in res.sensitivity if sc.name.startswith("hidden"))
    best_in = max(hidden.metrics[k].inside_window_fraction for k in others)
    assert hidden.metrics["hybrid"].inside_window_fraction >= best_in - 0.005


@pytest.mark.usefixtures("stored_plans")  # the session's plans (conftest)
@pytest.mark.parametrize("name", PROBLEMS)
def test_simulator_reproduces_the_deviation_command_within_1_percent(name: str) -> None:
    c = result(name).consistency
    assert c is not None
    assert c.relative_difference <= 0.01
    assert c.max_time_difference <= 0.01 * c.deviation_max_abs_lateral


@pytest.mark.usefixtures("stored_plans")  # the session's plans (conftest)
def test_sensitivity_scenarios_are_all_run() -> None:
    names = [sc.name for sc in result(PROBLEMS[0]).sensitivity]
    assert names[0] == "stiffness_-20%"
    assert names[1].startswith("hidden_")
    assert names[2] == "noise_x3"
    soft = result(PROBLEMS[0]).sensitivity[0].metrics["none"]
    assert soft.max_abs_lateral > result(PROBLEMS[0]).main.metrics["none"].max_abs_lateral


# -- options and parsing ----------------------------------------------------------------------
def test_options_reject_unknown_strategy_and_bad_cycle() -> None:
    with pytest.raises(UnknownNameError, match="unknown strategy 'bogus'"):
        CompareOptions(strategies=("none", "bogus"))
    with pytest.raises(InputError, match="cycle"):
        CompareOptions(cycle_s=0.0)


def test_parse_effect_arg() -> None:
    assert parse_effect_arg("tilting_compliance:j3") == ("tilting_compliance:j3", None)
    assert parse_effect_arg("payload_gravity=m=150,m_rz:-37.5") == (
        "payload_gravity", {"m": 150.0, "m_rz": -37.5})
    with pytest.raises(InputError, match="bad parameter"):
        parse_effect_arg("payload_gravity=m")


# -- CLI ---------------------------------------------------------------------------------------
def run_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(["compare", *args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--strategies", "none", "bogus"], "unknown strategy 'bogus'"),
        (["--truth-effect", "no_such_effect"], "unknown effect 'no_such_effect'"),
        (["--cycle-ms", "0"], "cycle"),
        (["--cycle-ms", "-4"], "cycle"),
        (["--maf-samples", "100000000"], "longer than the weld"),
        (["--seed000-update-ms", "1e9"], "longer than the weld"),
        (["--truth-stiffness-scale", "0"], "stiffness-scale"),  # refused by the parser
    ],
)
def test_cli_bad_input_is_one_line_and_nonzero(
    args: list[str], needle: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code, _out, err = run_cli(["zk500_table6_seam", "-o", str(tmp_path), *args], capsys)
    assert code != 0
    lines = err.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], err
    assert "Traceback" not in err


def test_cli_json_and_files_realtime_only(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    code, out, err = run_cli(
        ["zk500_table6_seam", "-o", str(tmp_path), "--json", "--no-sensitivity",
         "--strategies", "none", "realtime_seed000", "realtime_seed002"], capsys)
    assert code == 0, err
    data = json.loads(out)
    assert set(data["strategies"]) == {"none", "realtime_seed000", "realtime_seed002"}
    for m in data["strategies"].values():
        assert {"inside_window_fraction", "max_abs_lateral_mm", "rms_lateral_mm",
                "settling_mm"} <= set(m)
        assert 0.0 <= m["inside_window_fraction"] <= 1.0
    for f in ("compare.json", "compare.md", "compare_lateral.png"):
        assert (tmp_path / f).is_file()
    assert json.loads((tmp_path / "compare.json").read_text())["strategies"] == data["strategies"]


@pytest.mark.usefixtures("stored_plans")  # the session's plans (conftest)
def test_cli_table_all_strategies(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, out, err = run_cli(
        ["fanuc_butt_1700mm", "-o", str(tmp_path), "--no-sensitivity", "--no-plot"], capsys)
    assert code == 0, err
    for s in STRATEGIES:
        assert f"  {s} " in out
    assert "simulator vs deviation" in out


def test_change_of_travel_direction_on_the_curved_seam() -> None:
    """kr600_curved_seam: the 90 deg arc is found and reported for every strategy."""
    opts = CompareOptions(strategies=("none", *REALTIME), cycle_s=0.02, sensitivity=False)
    res = compare(load_problem("kr600_curved_seam"), opts)
    for name in opts.strategies:
        dc = res.main.metrics[name].direction_change
        assert dc is not None, name
        assert dc.turn_angle == pytest.approx(0.5 * np.pi, abs=0.05)
        assert 0.25 < dc.s_start < 0.35  # the arc starts after the 300 mm straight
    none = res.main.metrics["none"].direction_change
    rt = res.main.metrics["realtime_seed002"].direction_change
    assert none is not None and rt is not None
    assert none.inside_window_fraction == 0.0
    assert rt.max_abs_lateral < none.max_abs_lateral


def test_mae_along_the_normal_matches_the_deviation_command(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """Seed 002 Table 3's metric: with no force drift the open-loop error along the surface
    normal is the ``deviation`` command's axial deviation; the CLI's JSON, compare.json and the
    table carry it, and seed 002's compensation removes most of it."""
    from rfsw_plan.process.deviation import problem_deviation

    code, out, err = run_cli(
        ["kr600_forming_contour", "-o", str(tmp_path), "--json", "--no-sensitivity",
         "--no-plot", "--force-drift", "0", "--strategies", "none", "realtime_seed002"], capsys)
    assert code == 0, err
    data = json.loads(out)
    for m in data["strategies"].values():
        assert {"mae_normal_mm", "max_abs_normal_mm", "mean_normal_mm", "std_normal_mm"} <= set(m)
        assert 0.0 <= m["mae_normal_mm"] <= m["max_abs_normal_mm"]
    dev = problem_deviation(load_problem("kr600_forming_contour"))
    weld = dev.schedule.mask("weld")
    axial_mae = float(np.mean(np.abs(dev.axial_t[weld]))) * 1e3
    none = data["strategies"]["none"]
    assert none["mae_normal_mm"] == pytest.approx(axial_mae, rel=0.01)
    assert none["mean_normal_mm"] == pytest.approx(float(np.mean(dev.axial_t[weld])) * 1e3,
                                                   rel=0.01)
    assert data["strategies"]["realtime_seed002"]["mae_normal_mm"] < 0.1 * none["mae_normal_mm"]
    saved = json.loads((tmp_path / "compare.json").read_text())
    assert saved["main"]["strategies"]["none"]["mae_normal_mm"] == none["mae_normal_mm"]
    assert "MAE along the normal" in (tmp_path / "compare.md").read_text()
    code, out, err = run_cli(["kr600_forming_contour", "-o", str(tmp_path / "t"),
                              "--no-sensitivity", "--no-plot", "--strategies", "none"], capsys)
    assert code == 0, err
    assert "MAE_n mm" in out


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def test_the_same_comparison_writes_the_same_bytes_and_prints_its_times(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """``compare.json``, ``compare.md`` and the plot hold no wall time (the plan's and the
    simulations', which differ from run to run): the same comparison run twice into two
    folders writes the same bytes. The times are printed, on the table's last line."""
    args = ["--no-sensitivity", "--strategies", "none", "realtime_seed000", "offline"]
    runs = []
    for name in ("a", "b"):
        code, out, err = run_cli(["fanuc_butt_1700mm", "-o", str(tmp_path / name), *args],
                                 capsys)
        assert code == 0, err
        assert re.search(r"^plan \d+\.\d\d s, simulation \d+\.\d{3} s$", out, re.M), out
        runs.append(_files(tmp_path / name))
    assert sorted(runs[0]) == ["compare.json", "compare.md", "compare_lateral.png"]
    assert [n for n in runs[0] if runs[0][n] != runs[1][n]] == []
    assert b"plan_time_s" not in runs[0]["compare.json"]
    assert b"sim_time_s" not in runs[0]["compare.json"]
    assert b"simulation time" not in runs[0]["compare.md"]
