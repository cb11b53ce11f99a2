"""Problem files: loading, validation, bundled problems (issue 3 §3, §6)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.exceptions import InputError, UnknownNameError
from rfsw_plan.process.problem import BUNDLED_PROBLEMS_DIR, bundled_problem_names, load_problem

GOOD = """
robot = "zk500"
[seam]
points_mm = [[269.52, -2070.91, 663.15], [278.10, -1957.60, 664.05]]
tilt_deg = 2.0
rotation = "cw"
spacing_mm = 10.0
[process]
preset = "seed001_aa6061_5mm"
[window]
lower_mm = -1.25
upper_mm = 0.7
[planning]
q_seed_deg = [-96.24, 3.91, 25.45, -2.10, 57.17, 2.90]
tool_rotation_deg = 180
w_stiffness = 3.0
margin_mm = 0.2
"""


def _write(tmp_path: Path, text: str, name: str = "p.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_bundled_problems_load() -> None:
    names = bundled_problem_names()
    for n in ("zk500_table6_seam", "fanuc_butt_1700mm", "kr600_curved_seam"):
        assert n in names
        p = load_problem(n)
        assert p.name == n
        assert p.planning.q_seed is not None
        fr = p.frames()
        assert len(fr) >= 2
    kr = load_problem("kr600_curved_seam")
    assert kr.seam.length >= 0.6
    ts = kr.seam.seam_tangent(np.array([0.0, kr.seam.length]))
    # The travel direction turns by 90 deg along the seam (+y, then +x).
    np.testing.assert_allclose(ts, [[0, 1, 0], [1, 0, 0]], atol=0.02)
    zk = load_problem("zk500_table6_seam")
    np.testing.assert_allclose(zk.process.steady_force_seam(), [-899.80, 1350.87, 4842.58])
    assert zk.coupling is not None and zk.coupling.commanded_depth == pytest.approx(8e-3)


def test_units_and_planning_options(tmp_path: Path) -> None:
    p = load_problem(_write(tmp_path, GOOD))
    assert p.spacing == pytest.approx(0.01)
    assert p.seam.tilt == pytest.approx(np.deg2rad(2.0))
    assert p.process.travel_speed == pytest.approx(3e-3)
    assert p.planning.tool_rotation == pytest.approx(np.pi)
    assert p.planning.w_stiffness == 3.0  # [planning] is parsed once, into PlanOptions
    assert p.planning.margin == pytest.approx(0.2e-3)
    with pytest.raises(InputError, match=r"planning\.w_stifness: unknown key; did you mean "
                       r"'w_stiffness'\?"):
        load_problem(_write(tmp_path, GOOD.replace("w_stiffness", "w_stifness"), "q.toml"))
    assert p.window.lower == pytest.approx(-1.25e-3)


def test_seam_csv(tmp_path: Path) -> None:
    (tmp_path / "s.csv").write_text("x_mm,y_mm,z_mm\n0,0,0\n100,0,0\n200,50,0\n")
    text = GOOD.replace(
        'points_mm = [[269.52, -2070.91, 663.15], [278.10, -1957.60, 664.05]]', 'csv = "s.csv"')
    p = load_problem(_write(tmp_path, text))
    np.testing.assert_allclose(p.seam.points[-1], [0.2, 0.05, 0.0])


def test_unknown_names(tmp_path: Path) -> None:
    with pytest.raises(UnknownNameError, match="zk500_table6_seam"):
        load_problem("no_such_problem")
    with pytest.raises(UnknownNameError, match=r"unknown robot.*'nobot'.*zk500"):
        load_problem(_write(tmp_path, GOOD.replace('"zk500"', '"nobot"')))
    with pytest.raises(UnknownNameError, match="process preset"):
        load_problem(_write(tmp_path, GOOD.replace('"seed001_aa6061_5mm"', '"x"')))


def test_typo_key_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"seam\.tilt_dg: unknown key; did you mean 'tilt_deg'"):
        load_problem(_write(tmp_path, GOOD.replace("tilt_deg", "tilt_dg")))


BAD = [
    ("points_mm = [[269.52, -2070.91, 663.15], [278.10, -1957.60, 664.05]]",
     "points_mm = [[269.52, -2070.91, 663.15]]", "at least 2 rows"),
    ("points_mm = [[269.52, -2070.91, 663.15], [278.10, -1957.60, 664.05]]",
     "points_mm = [[0, 0, 0], [100, 0, 0], [100, 0, 0]]", "duplicate consecutive"),
    ("points_mm = [[269.52, -2070.91, 663.15], [278.10, -1957.60, 664.05]]",
     "points_mm = [[5, 5, 5], [5, 5, 5]]", "zero-length"),
    ("tilt_deg = 2.0", "tilt_deg = 20.0", "tilt_deg: got 20 (expected a number in [-15, 15])"),
    ('rotation = "cw"', 'rotation = "clockwise"', "rotation: got 'clockwise'"),
    ("upper_mm = 0.7", "upper_mm = -1.5", "not below upper"),
    ('robot = "zk500"', 'robot = "abb_irb_99"', "unknown robot"),
    ("q_seed_deg = [-96.24, 3.91, 25.45, -2.10, 57.17, 2.90]", "q_seed_deg = [0, 0]",
     "q_seed_deg"),
    ("spacing_mm = 10.0", "spacing_mm = -1", "spacing_mm"),
]


@pytest.mark.parametrize(("old", "new", "match"), BAD)
def test_bad_problem_one_line_error_via_cli(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], old: str, new: str, match: str
) -> None:
    assert old in GOOD
    p = _write(tmp_path, GOOD.replace(old, new))
    code = main(["deviation", str(p), "-o", str(tmp_path / "out"), "--no-plot"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert match in err
    assert str(p) in err or "unknown robot" in err


def test_every_plan_option_has_one_file_key() -> None:
    """[planning] and --set cover every PlanOptions field, each by exactly one key."""
    from dataclasses import fields

    from rfsw_plan.process.plan_options import OPTION_KEYS, PlanOptions

    by_field = [spec.field for spec in OPTION_KEYS.values()]
    assert sorted(by_field) == sorted(f.name for f in fields(PlanOptions))


def test_set_unknown_option_did_you_mean(capsys: pytest.CaptureFixture[str],
                                         tmp_path: Path) -> None:
    code = main(["plan", "zk500_table6_seam", "-o", str(tmp_path / "o"),
                 "--set", "w_stifness=2"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "--set: unknown option 'w_stifness'; did you mean 'w_stiffness'?" in err
    code = main(["plan", "zk500_table6_seam", "-o", str(tmp_path / "o"), "--set", "margin_mm=nan"])
    err = capsys.readouterr().err
    assert code == 2 and "--set: margin_mm: got nan" in err, err


def test_coupling_calibration_and_plunge_cases(tmp_path: Path) -> None:
    """The three seed 001 Fig. 10 cases are bundled; a calibration names observed plunges."""
    for name, depth in (("zk500_plunge7mm", 7e-3), ("zk500_table6_seam", 8e-3),
                        ("zk500_plunge9mm", 9e-3)):
        p = load_problem(name)
        assert p.coupling is not None and p.coupling.law is None
        assert p.coupling.calibration_name == "seed001_fig10"
        assert p.coupling.commanded_depth == pytest.approx(depth)
        assert [o.commanded_depth for o in p.coupling.calibration] == [7e-3, 8e-3, 9e-3]
    text = (BUNDLED_PROBLEMS_DIR / "zk500_table6_seam.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('calibration = "seed001_fig10"', 'calibration = "fig11"'))
    with pytest.raises(InputError, match=r"unknown calibration 'fig11'.*seed001_fig10"):
        load_problem(bad)
    bad.write_text(text.replace('calibration = "seed001_fig10"', 'calibration = "seed001_fig10"'
                                "\npenetration_stiffness_N_per_mm = 1000"))
    with pytest.raises(InputError, match="together with 'calibration'"):
        load_problem(bad)


#: Every key of a problem file that is a relative amount (a fraction), with the table it is in.
FRACTION_KEYS = [("planning", "force_uncertainty"), ("planning", "det_fraction"),
                 ("planning", "min_stiffness_share"), ("process.forces", "dwell_lateral_fraction")]


def _with(table: str, line: str) -> str:
    if table == "planning":
        return GOOD + line + "\n"
    return GOOD.replace('preset = "seed001_aa6061_5mm"\n',
                        f'preset = "seed001_aa6061_5mm"\n[process.forces]\n{line}\n')


@pytest.mark.parametrize(("table", "key"), FRACTION_KEYS)
def test_a_percent_written_as_a_number_is_refused_with_the_fix(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], table: str, key: str) -> None:
    """``force_uncertainty = 10`` means 10 %, never +-1000 %: one line naming the key, with the
    fix, as ``--force-uncertainty 10`` says on the command line (issue 33, wall 6)."""
    path = _write(tmp_path, _with(table, f"{key} = 10"))
    with pytest.raises(InputError, match=rf"{table}\.{key}: got 10, a fraction above .*did you "
                                         r"mean 10 %\?.*the fraction 0\.1 or the string \"10 %\""):
        load_problem(path)
    assert main(["-q", "plan", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "did you mean 10 %?" in err
    # The percentage as a string, and the fraction, both mean 10 %.
    for text in (f'{key} = "10 %"', f'{key} = "10%"', f"{key} = 0.1"):
        pb = load_problem(_write(tmp_path, _with(table, text), "ok.toml"))
        field = {"force_uncertainty": pb.planning.force_uncertainty,
                 "det_fraction": pb.planning.det_fraction,
                 "min_stiffness_share": pb.planning.min_stiffness_share,
                 "dwell_lateral_fraction": pb.process.forces.dwell_lateral_fraction}[key]
        assert field == pytest.approx(0.1), text


def test_force_uncertainty_above_100_percent_only_as_a_percentage(tmp_path: Path) -> None:
    pb = load_problem(_write(tmp_path, GOOD + 'force_uncertainty = "150 %"\n'))
    assert pb.planning.force_uncertainty == pytest.approx(1.5)
    with pytest.raises(InputError, match=r"force_uncertainty: got 1\.5, a fraction above 1"):
        load_problem(_write(tmp_path, GOOD + "force_uncertainty = 1.5\n", "b.toml"))
    with pytest.raises(InputError, match="force_uncertainty: got 2000 %"):
        load_problem(_write(tmp_path, GOOD + 'force_uncertainty = "2000 %"\n', "c.toml"))
