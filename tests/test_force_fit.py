"""Least-squares fit of the force model to a measured series (seed 001 eq. 15 loss)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rfsw_plan.io.force_series import ForceSeries
from rfsw_plan.process.force_fit import fit_process_forces
from rfsw_plan.process.frames import tcp_orientation
from rfsw_plan.process.presets import process_preset
from rfsw_plan.process.seam import Seam

SEAM = Seam(np.array([[0.27, -2.07, 0.66], [0.278, -1.958, 0.661]]), tilt=np.deg2rad(2.0))
FRAMES = SEAM.frames(0.005)
PRIOR = process_preset("seed001_aa6061_5mm")
TRUTH = replace(PRIOR, forces=replace(
    PRIOR.forces, axial=5200.0, lateral=1100.0, lateral_sign=-1.0, traverse=750.0,
    plunge_peak_axial=6500.0, dwell_lateral_fraction=0.3, dwell_tau=3.0, ramp_length=2.5e-3,
    spindle_torque=35.0))


def _series(frame: str, noise: float, seed: int = 7, tool_rotation: float = 0.0) -> ForceSeries:
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, TRUTH.phase_times(SEAM.length).total, 0.05)
    sch = TRUTH.evaluate(FRAMES, t)
    f = sch.force_seam + rng.normal(0.0, noise, sch.force_seam.shape)
    m_base = sch.moment_base + rng.normal(0.0, 1.0, (len(t), 3))
    if frame == "seam":
        return ForceSeries(t, f, sch.frames.to_seam(m_base), "seam")
    fb = sch.frames.to_base(f)
    if frame == "base":
        return ForceSeries(t, fb, m_base, "base")
    R = tcp_orientation(sch.frames, tool_rotation)
    return ForceSeries(t, np.einsum("kji,kj->ki", R, fb), np.einsum("kji,kj->ki", R, m_base),
                       "tool")


@pytest.mark.parametrize("frame", ["seam", "base", "tool"])
def test_fit_recovers_parameters_from_noisy_series(frame: str) -> None:
    rot = np.deg2rad(180.0)
    fit = fit_process_forces(PRIOR, FRAMES, _series(frame, 50.0, tool_rotation=rot),
                             tool_rotation=rot)
    p = fit.params
    assert p["axial"] == pytest.approx(5200.0, abs=15.0)
    assert p["lateral"] == pytest.approx(-1100.0, abs=15.0)  # signed: retreating side found
    assert p["traverse"] == pytest.approx(750.0, abs=15.0)
    assert p["plunge_peak_axial"] == pytest.approx(6500.0, abs=60.0)
    assert p["dwell_tau"] == pytest.approx(3.0, rel=0.05)
    assert p["dwell_lateral_fraction"] == pytest.approx(0.3, abs=0.03)
    assert p["ramp_length"] == pytest.approx(2.5e-3, rel=0.15)
    assert p["spindle_torque"] == pytest.approx(35.0, abs=0.5)
    assert fit.process.forces.lateral_sign == -1.0
    # Fit quality: residual at the noise level, high R^2; std errors cover the truth.
    assert fit.rms_total == pytest.approx(50.0, rel=0.1)
    assert np.all(fit.r2 > 0.9)
    assert abs(p["axial"] - 5200.0) < 5 * fit.std["axial"]
    assert "R^2" in fit.summary()


def test_fit_noise_free_is_exact_and_keeps_uninformed_priors() -> None:
    s = _series("seam", 0.0)
    weld_only = ForceSeries(s.t[s.t > 20.0], s.force[s.t > 20.0], None, "seam")
    fit = fit_process_forces(PRIOR, FRAMES, weld_only)
    assert fit.params["axial"] == pytest.approx(5200.0, rel=1e-6)
    assert fit.params["traverse"] == pytest.approx(750.0, rel=1e-6)
    assert "plunge_peak_axial" in fit.fixed and "spindle_torque" in fit.fixed
    assert fit.params["plunge_peak_axial"] == PRIOR.forces.peak_axial
    assert any("plunge_peak_axial" in n for n in fit.notes)
