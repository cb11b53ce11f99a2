"""Deflection under a *modelled* process wrench: sensor-only effects and the seam reference."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.cli.main import main
from rfsw_plan.elastostatics.model import load_model
from rfsw_plan.exceptions import InputError
from rfsw_plan.process.problem import load_problem, resolve_problem_path

Q = np.radians([[-82.58, 41.65, 18.67, 0.0, 29.68, 15.42], [-90.0, 30.0, 20.0, 5.0, 40.0, 0.0]])
F = np.array([[-1415.0, -795.2, 4835.5, 0.0, 0.0, 0.0], [800.0, -1200.0, 3000.0, 10.0, 0, 0]])


def test_linear_model_references_agree_with_eq_11() -> None:
    m = load_model("zk500")
    for ref in ("taught", "absolute"):
        np.testing.assert_allclose(m.process_deflection(Q, F, ref), m.deflection(Q, F), atol=1e-15)


def test_taught_seam_removes_the_zero_load_sag() -> None:
    m = load_model("zk500").with_effect("payload_gravity")
    sag = m.process_deflection(Q, np.zeros_like(F), "absolute")
    assert np.min(np.linalg.norm(sag[:, :3], axis=1)) > 1e-4  # 150 kg spindle sags > 0.1 mm
    np.testing.assert_allclose(m.process_deflection(Q, np.zeros_like(F), "taught"), 0.0,
                               atol=1e-15)
    # payload gravity is a wrench: with linear compliance the process part equals eq. 11
    base = load_model("zk500").deflection(Q, F)
    np.testing.assert_allclose(m.process_deflection(Q, F, "taught"), base, atol=1e-12)


def test_sensor_only_effects_do_not_move_a_modelled_wrench() -> None:
    base = load_model("zk500")
    m = base.with_effect("sensor_misalignment", {"phi_x": 0.05, "phi_z": -0.03})
    m = m.with_effect("force_sensor_bias", {"b_fx": 200.0})
    assert not np.allclose(m.deflection(Q, F), base.deflection(Q, F))  # logged: corrected
    for ref in ("taught", "absolute"):
        np.testing.assert_allclose(m.process_deflection(Q, F, ref), base.deflection(Q, F),
                                   atol=1e-15)
    assert [e.label for e in m.physical().effects] == ["joint_compliance"]


def test_batch_and_pose_forms_agree() -> None:
    m = load_model("zk500").with_effect("kinematic_offsets", {"dq2": 1e-3, "dt_x": 1e-3})
    batch = m.batch(Q)
    np.testing.assert_allclose(m.process_deflection_batch(batch, F, "absolute"),
                               m.process_deflection(Q, F, "absolute"), atol=1e-15)
    # the kinematic offset is load independent: a taught seam never sees it
    np.testing.assert_allclose(m.process_deflection(Q, F, "taught"),
                               load_model("zk500").deflection(Q, F), atol=1e-12)


def _problem_with(tmp_path: Path, line: str) -> Path:
    text = resolve_problem_path("zk500_table6_seam").read_text()
    out = tmp_path / "p.toml"
    out.write_text(text.replace("[seam]\n", f"[seam]\n{line}\n", 1))
    return out


def test_problem_reads_the_seam_reference(tmp_path: Path) -> None:
    assert load_problem("zk500_table6_seam").seam_reference == "taught"
    assert load_problem(_problem_with(tmp_path, 'reference = "absolute"')).seam_reference == (
        "absolute")
    with pytest.raises(InputError, match="reference"):
        load_problem(_problem_with(tmp_path, 'reference = "jogged"'))


def test_bad_reference_is_a_one_line_cli_error(tmp_path: Path, capsys) -> None:
    code = main(["deviation", str(_problem_with(tmp_path, 'reference = "cad"')), "--no-plot",
                 "-o", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and "reference" in err
