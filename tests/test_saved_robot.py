"""Saved robots (validate --save-robot, identify -o): compact TOML, new name, provenance,
loadable by the strict reader; plans print the robot file they used."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.files import sha256_file
from rfsw_plan.io.measurements import write_measurements
from rfsw_plan.robot.description import (
    bundled_robot_names,
    load_robot_description,
    save_robot_description,
)
from rfsw_plan.validation.campaign.simulation import run_campaign


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    c = run_campaign("zk500", hidden=["payload_gravity=m:150"], poses=12, loads_per_pose=4,
                     noise_mm=0.01, seed=1)
    return write_measurements(tmp_path_factory.mktemp("c") / "campaign.csv", c.data)


def _compact(text: str, n: int = 6) -> None:
    lines = text.splitlines()
    # Every line is a key, a table header, a coupling row or a bracket: never a lone number.
    assert not [ln for ln in lines if re.fullmatch(r"\s*-?[0-9.e+-]+,?\s*", ln)]
    i = lines.index("coupling = [")
    assert lines[i + n + 1] == "]"
    assert all(ln.startswith("    [") for ln in lines[i + 1:i + n + 1])


@pytest.mark.parametrize("name", bundled_robot_names())
def test_bundled_robots_round_trip_through_the_compact_writer(name: str, tmp_path: Path) -> None:
    d = load_robot_description(name)
    p = save_robot_description(d, tmp_path / "r.toml")
    _compact(p.read_text(), d.n_joints)
    d2 = load_robot_description(p)  # the strict reader
    assert d2.name == d.name
    for a in ("stiffness", "coupling", "lower", "upper", "velocity", "tool"):
        np.testing.assert_allclose(getattr(d2, a), getattr(d, a), rtol=1e-9, atol=1e-12)
    assert tomllib.loads(p.read_text()) == tomllib.loads(save_robot_description(
        d2, tmp_path / "r2.toml").read_text())


def test_validate_save_robot_names_the_model_and_records_where_it_came_from(
        campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "v2.toml"
    assert main(["-q", "validate", "--robot", "zk500", "--data", str(campaign), "--add",
                 "payload_gravity", "--save-robot", str(out), "--no-report",
                 "--folds", "3"]) == 0
    text = out.read_text()
    _compact(text)
    assert len(text.splitlines()) < 70
    d = load_robot_description(out)
    assert d.name == "zk500+payload_gravity"
    assert [e.name for e in d.effects] == ["payload_gravity"]
    assert abs(d.effects[0].params["m"] - 150) < 5
    prov = d.provenance
    assert prov["parent"].endswith("robots/zk500.toml")
    assert prov["data"] == str(campaign) and prov["data_sha256"] == sha256_file(campaign)
    assert re.fullmatch(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d UTC", prov["created"])
    assert prov["command"] == "rfsw-plan validate"
    # The saved file is a robot like any other: a plan on it prints the file it used.
    capsys.readouterr()
    again = tmp_path / "v3.toml"
    assert main(["-q", "validate", "--robot", str(out), "--data", str(campaign), "--no-report",
                 "--save-robot", str(again), "--name", "cell7_zk500", "--folds", "3"]) == 0
    d3 = load_robot_description(again)
    assert d3.name == "cell7_zk500" and d3.provenance["parent"] == str(out)


def test_identify_output_is_named_and_numbers_have_one_format(
        campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "id.toml"
    assert main(["identify", "--robot", "zk500", "--data", str(campaign), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    rows = [ln.split() for ln in text.splitlines() if re.match(r"\s+[1-6]\s", ln)]
    assert len(rows) == 6
    assert all(re.fullmatch(r"\d\.\d{4}e[+-]\d\d", r[1]) for r in rows)  # 1.1684e+06, never 739226
    d = load_robot_description(out)
    assert d.name == "zk500+identified" and d.provenance["command"] == "rfsw-plan identify"
    assert d.provenance["data_sha256"] == sha256_file(campaign)


@pytest.mark.usefixtures("stored_plans")  # the session's plans (conftest)
def test_plan_prints_the_robot_file_it_used(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["plan", "zk500_table6_seam", "-o", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^robot zk500_seed001 from .*robots/zk500_seed001\.toml$", out, re.M)


def test_a_robot_the_reader_would_refuse_is_never_written(tmp_path: Path) -> None:
    """--save-robot could write an identified parameter outside its effect's physical range
    (a negative tilting compliance), a file that reading then refused. The writer checks what
    the reader will, before the file exists: one line naming the effect parameter, no file."""
    from rfsw_plan.elastostatics.model import ElastostaticModel
    from rfsw_plan.exceptions import InputError
    from rfsw_plan.robot.kinematics import load_robot
    from rfsw_plan.validation.derived_robot import save_derived_robot

    parent = load_robot_description("zk500")
    model = ElastostaticModel(load_robot("zk500")).with_effect(
        "tilting_compliance:j2", {"c_t1": -1e-7, "c_t2": 1e-8})
    target = tmp_path / "refit.toml"
    with pytest.raises(InputError, match=r"refit.toml: tilting_compliance:j2.c_t1: not "
                                         r"written: got -1e-07, and a robot file with it"):
        save_derived_robot(model, target, parent=parent, note="test", data="campaign.csv",
                           command="rfsw-plan validate")
    assert list(tmp_path.iterdir()) == []
    ok = ElastostaticModel(load_robot("zk500")).with_effect("tilting_compliance:j2")
    save_derived_robot(ok, target, parent=parent, note="test", data="campaign.csv",
                       command="rfsw-plan validate")
    assert load_robot_description(target).effects[-1].name == "tilting_compliance:j2"


def test_the_robot_writer_reads_its_text_with_the_strict_reader_first(tmp_path: Path) -> None:
    """save_robot_description parses its own text with the strict reader before the file
    exists: a description the reader refuses (here a negative joint stiffness) is not
    written."""
    from dataclasses import replace

    from rfsw_plan.exceptions import InputError

    d = load_robot_description("zk500")
    k = d.stiffness.copy()
    k[1] = -k[1]
    target = tmp_path / "bad.toml"
    with pytest.raises(InputError, match=r"bad.toml: .*not written: the robot file would not "
                                         r"load"):
        save_robot_description(replace(d, stiffness=k), target)
    assert list(tmp_path.iterdir()) == []
