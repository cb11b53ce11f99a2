"""Parametric process forces and the load schedule (issue 3 §2)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rfsw_plan.exceptions import InputError
from rfsw_plan.process.forces import ProcessForces
from rfsw_plan.process.frames import PHASES
from rfsw_plan.process.presets import PROCESS_PRESETS, process_preset
from rfsw_plan.process.seam import Seam

SEAM = Seam(np.array([[0.0, 0.0, 0.0], [0.0, 0.1, 0.0]]), tilt=np.deg2rad(2.0))


@pytest.mark.parametrize(
    ("name", "expected"),
    [("seed001_aa6061_5mm", (-899.80, 1350.87, 4842.58)),
     ("seed000_aa5754_3mm", (-1000.0, 1000.0, 3100.0))],
)
def test_steady_forces_reproduced(name: str, expected: tuple[float, float, float]) -> None:
    proc = process_preset(name)
    np.testing.assert_allclose(proc.steady_force_seam(), expected)
    sch = proc.schedule(SEAM.frames(0.005), dt=0.05)
    weld = sch.mask("weld") & (sch.s > 20 * proc.forces.ramp_length)
    assert weld.sum() > 10
    np.testing.assert_allclose(sch.force_seam[weld], np.tile(expected, (weld.sum(), 1)),
                               rtol=1e-6)
    # And in the base frame: the axial force is along the tilted tool axis.
    W = sch.wrench_base[weld]
    np.testing.assert_allclose(np.einsum("ki,ki->k", W[:, :3], sch.frames.n[weld]), expected[2])


def test_schedule_phases_and_continuity() -> None:
    proc = replace(process_preset("seed001_aa6061_5mm"), approach_height=0.01)
    fr = SEAM.frames(0.005)
    sch = proc.schedule(fr, dt=0.1)
    order = [PHASES.index(p) for p in sch.phase]
    assert np.all(np.diff(order) >= 0)
    assert set(sch.phase) == set(PHASES)
    assert np.all(np.diff(sch.t) > 0)
    pt = proc.phase_times(SEAM.length)
    assert sch.t[-1] == pytest.approx(pt.total)
    assert pt.plunge == pytest.approx(4.8 / 2.0)
    assert pt.weld == pytest.approx(100 / 3.0)
    # Stationary phases at s = 0, weld reaches the end, retract at the end.
    assert np.all(sch.s[sch.mask("dwell")] == 0)
    assert sch.s[sch.mask("weld")][-1] == pytest.approx(SEAM.length)
    np.testing.assert_allclose(sch.depth[sch.mask("weld")], proc.plunge_depth)
    # No force before contact, none after the retract.
    assert np.all(sch.force_seam[sch.mask("approach")] == 0)
    np.testing.assert_allclose(sch.force_seam[-1], 0, atol=1e-9)
    # The force is continuous: evaluate just before and after each boundary.
    for t0 in pt.starts[1:]:
        a = proc.evaluate(fr, np.array([t0 - 1e-7, t0 + 1e-7])).force_seam
        np.testing.assert_allclose(a[0], a[1], atol=1e-2)
    # During the plunge the tool tip is (depth_final - depth) above the seam start.
    m = sch.mask("plunge")
    up = np.einsum("ki,ki->k", sch.frames.p[m] - fr.p[0], sch.frames.n[m])
    np.testing.assert_allclose(up, proc.plunge_depth - sch.depth[m], atol=1e-12)


def test_lateral_force_flips_with_travel_direction_in_base_frame() -> None:
    """Seed 000 Fig. 18: F_z keeps its direction, F_y reverses between y+ and y- paths."""
    proc = process_preset("seed000_aa5754_3mm")
    pts = np.array([[1.7, -0.125, 0.6], [1.7, 0.125, 0.6]])
    w = []
    for rev in (False, True):
        fr = Seam(pts, reverse=rev).frames(0.01)
        sch = proc.schedule(fr, 0.1)
        w.append(sch.wrench_base[sch.mask("weld")][-1])
    assert w[0][2] == pytest.approx(w[1][2])
    assert w[0][1] == pytest.approx(-w[1][1])  # traverse along y flips too
    assert w[0][0] == pytest.approx(-w[1][0])  # lateral along x flips
    assert abs(w[0][0]) == pytest.approx(1000.0)


def test_lateral_sign_option_and_torque() -> None:
    proc = process_preset("seed001_aa6061_5mm")
    neg = replace(proc, forces=replace(proc.forces, lateral_sign=-1.0, spindle_torque=30.0))
    assert neg.steady_force_seam()[1] == pytest.approx(-1350.87)
    for rot, sign in (("cw", 1.0), ("ccw", -1.0)):
        fr = Seam(SEAM.points, rotation=rot).frames(0.01)  # type: ignore[arg-type]
        sch = neg.schedule(fr, 0.1)
        m = sch.mask("weld")
        # Reaction torque opposes the spindle's angular velocity (cw: omega along -n).
        np.testing.assert_allclose(
            np.einsum("ki,ki->k", sch.moment_base[m], sch.frames.n[m]), sign * 30.0)
    assert np.all(proc.schedule(SEAM.frames(0.01), 0.1).moment_base == 0)


def test_presets_have_sources() -> None:
    for p in PROCESS_PRESETS.values():
        assert p.source and p.forces.source


@pytest.mark.parametrize(
    "kw", [{"axial": -1.0}, {"lateral_sign": 0.5}, {"dwell_tau": 0.0}, {"ramp_length": -1e-3}]
)
def test_bad_forces(kw: dict) -> None:
    with pytest.raises(InputError):
        ProcessForces(**({"axial": 1.0, "lateral": 1.0, "traverse": 1.0} | kw))


def test_bad_process() -> None:
    proc = process_preset("seed001_aa6061_5mm")
    with pytest.raises(InputError, match="travel_speed"):
        replace(proc, travel_speed=0.0)
    with pytest.raises(InputError, match="dt"):
        proc.schedule(SEAM.frames(0.01), 0.0)
