"""Seed 001's cable campaign (Table 2 -> Table 3): simulation and identifiability."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from rfsw_plan.exceptions import InputError

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples" / "seed001"))
from seed001_campaign import (
    OFF_AXIS_ATTACHMENT_MM,
    TABLE2_DEG,
    TABLE3_K,
    CableCampaign,
    identify_cable_campaign,
    seed001_cases,
    simulate_cable_campaign,
)

NOISE_FREE = {"force_noise_N": 0.0, "moment_noise_Nm": 0.0, "position_noise_mm": 0.0,
              "rotation_noise_deg": 0.0}


def test_campaign_is_the_papers_five_poses_with_table3_truth() -> None:
    sim = simulate_cable_campaign(CableCampaign(orientation=True))
    d = sim.data
    np.testing.assert_allclose(sim.truth.stiffness, TABLE3_K)
    assert len(d) == 5 * 5  # slack reading + 4 tensions per pose
    np.testing.assert_allclose(np.degrees(d.q[::5]), TABLE2_DEG, atol=1e-12)
    # The logged force is the tension along the cable towards the anchor (50-sample mean).
    tension = np.linalg.norm(d.wrench[:, :3], axis=1).reshape(5, 5)
    np.testing.assert_allclose(tension[:, 1:], [[1000, 2000, 3000, 4000]] * 5, atol=15.0)
    assert np.all(tension[:, 0] < 15.0)
    f = d.wrench[4, :3]
    assert f @ sim.cable_direction[0] == pytest.approx(np.linalg.norm(f), rel=1e-4)
    assert d.rotation is not None and d.rotation.shape == (25, 3)


def test_noise_free_campaign_returns_the_truth_where_identifiable() -> None:
    """Off the tool axis and with orientation data all six joints come back exactly; with
    positions only joint 6 keeps the prior, named as invisible."""
    six = identify_cable_campaign(
        "6-D", CableCampaign(attachment_mm=OFF_AXIS_ATTACHMENT_MM, orientation=True,
                             **NOISE_FREE))
    assert six.identified.all()
    np.testing.assert_allclose(six.result.stiffness, TABLE3_K, rtol=1e-6)
    three = identify_cable_campaign(
        "3-D", CableCampaign(attachment_mm=OFF_AXIS_ATTACHMENT_MM, **NOISE_FREE))
    assert three.identified.tolist() == [True] * 5 + [False]
    np.testing.assert_allclose(three.result.stiffness[:5], TABLE3_K[:5], rtol=1e-6)
    assert three.result.stiffness[5] == pytest.approx(three.prior_k[5])
    assert "does not move the measured TCP" in three.notes()[0]


def test_cable_at_the_tcp_never_identifies_k6() -> None:
    cases = seed001_cases(seed=0)
    tcp3, tcp6, vertical, off3, off6, fine = cases[:6]
    # No torque on j6 from a force at a TCP on the j6 axis, whatever the data.
    assert np.max(np.abs(tcp3.simulation.j6_torque_per_kN)) < 1e-9
    for c in (tcp3, tcp6):
        assert c.identified.tolist() == [True] * 5 + [False], c.label
        err, std = c.relative_error[:5], c.relative_std[:5]
        assert np.all(np.abs(err) <= 3.0 * std), (c.label, err, std)
    # A vertical cable puts no torque on the vertical j1 axis either.
    assert not vertical.identified[0] and not vertical.identified[5]
    # Off the axis: j6 is loaded, only orientation data see it, a finer device pins it down.
    assert np.min(np.abs(off6.simulation.j6_torque_per_kN)) > 50.0
    assert not off3.identified[5] and off6.identified[5] and fine.identified[5]
    assert fine.relative_std[5] < 0.2 < off6.relative_std[5]
    assert abs(fine.relative_error[5]) <= 3.0 * fine.relative_std[5]


def test_averaging_50_samples_shrinks_the_standard_errors() -> None:
    one = identify_cable_campaign("1", CableCampaign(samples=1), seed=3)
    fifty = identify_cable_campaign("50", CableCampaign(), seed=3)
    ratio = one.relative_std[:5] / fifty.relative_std[:5]
    assert np.all((ratio > 3.0) & (ratio < 15.0)), ratio  # sqrt(50) = 7.1


def test_commanded_reading_sees_only_the_deflection_along_the_cable() -> None:
    """The paper's reading: the move is the deflection along the cable plus the stretch, the
    rest is zero; identifying from it misses Table 3 far beyond its standard errors."""
    setup = CableCampaign(measurement="commanded", cable_compliance_mm_per_kN=0.5,
                          **NOISE_FREE)
    sim = simulate_cable_campaign(setup)
    d = sim.data
    u = np.repeat(sim.cable_direction, 5, axis=0)
    tension = np.linalg.norm(d.wrench[:, :3], axis=1)
    moved = d.position - sim.truth.batch(d.q).T[:, :3, 3]
    true = sim.truth.deflection(d.q, d.wrench)[:, :3]
    along = np.einsum("mi,mi->m", true, u) + tension * 0.5e-6
    np.testing.assert_allclose(moved, along[:, None] * u, atol=1e-12)
    assert np.max(np.linalg.norm(true - np.einsum("mi,mi->m", true, u)[:, None] * u,
                                 axis=1)) > 1e-3  # the cable lets the TCP move across it
    paper_reading = seed001_cases(seed=0)[6]
    err = np.abs(paper_reading.relative_error[:5])
    assert np.nanmax(err) > 0.5
    assert paper_reading.result.rms_after > 50 * seed001_cases(seed=0)[0].result.rms_after


@pytest.mark.parametrize("kwargs, match", [
    ({"tensions_N": (1000.0, -5.0)}, "tensions_N"),
    ({"samples": 0}, "samples"),
    ({"position_noise_mm": float("nan")}, "position_noise_mm"),
    ({"poses_deg": ((0.0, 0.0, 0.0),)}, "poses_deg"),
    ({"measurement": "laser"}, "measurement"),
    ({"cable_compliance_mm_per_kN": -1.0}, "cable_compliance"),
])
def test_bad_setup_is_a_one_line_input_error(kwargs: dict[str, object], match: str) -> None:
    with pytest.raises(InputError, match=match):
        simulate_cable_campaign(CableCampaign(**kwargs))  # type: ignore[arg-type]
