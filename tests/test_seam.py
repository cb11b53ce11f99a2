"""Seam geometry and frames (issue 3 §1)."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.exceptions import InputError
from rfsw_plan.process.seam import Seam, interpolate_frames


def _orthonormal(fr) -> None:
    R = fr.rotation()
    I = np.einsum("kji,kjl->kil", R, R)
    np.testing.assert_allclose(I, np.broadcast_to(np.eye(3), I.shape), atol=1e-12)


@pytest.mark.parametrize("interp", ["linear", "spline"])
@pytest.mark.parametrize("tilt", [0.0, 2.0, -15.0])
@pytest.mark.parametrize("rotation", ["cw", "ccw"])
def test_frames_orthonormal(interp: str, tilt: float, rotation: str) -> None:
    rng = np.random.default_rng(3)
    pts = np.cumsum(rng.uniform(0.02, 0.1, size=(6, 3)) * [1, 1, 0.1], axis=0)
    seam = Seam(pts, interpolation=interp, tilt=np.deg2rad(tilt), rotation=rotation)  # type: ignore[arg-type]
    fr = seam.frames(0.01)
    _orthonormal(fr)
    assert np.all(np.diff(fr.s) > 0)
    np.testing.assert_allclose(fr.p[0], pts[0], atol=1e-12)
    np.testing.assert_allclose(fr.p[-1], pts[-1], atol=1e-9)
    # det [t l n] = +1 for cw, -1 for ccw (sigma).
    np.testing.assert_allclose(np.linalg.det(fr.rotation()), 1.0 if rotation == "cw" else -1.0)


def test_cw_advancing_side_and_tilt() -> None:
    """Travel +x, surface +z, clockwise from above: omega = -w z, the surface velocity at +y is
    +x (along travel), so +y is the advancing side. The tilted tool top leans back (-x)."""
    th = np.deg2rad(2.0)
    fr = Seam(np.array([[0, 0, 0], [0.1, 0, 0]]), tilt=th, rotation="cw").frames(0.05)
    np.testing.assert_allclose(fr.l, np.tile([0, 1, 0], (len(fr), 1)), atol=1e-15)
    np.testing.assert_allclose(fr.n[0], [-np.sin(th), 0, np.cos(th)], atol=1e-15)
    w = np.array([0, 0, -1.0])  # clockwise seen from above
    assert np.cross(w, fr.l[0]) @ np.array([1.0, 0, 0]) > 0


@pytest.mark.parametrize("interp", ["linear", "spline"])
def test_advancing_side_flips(interp: str) -> None:
    pts = np.array([[0, 0, 0], [0.1, 0.02, 0], [0.2, 0.0, 0.0]])
    base = Seam(pts, interpolation=interp).frames_at(np.array([0.0, 0.05, 0.1]))  # type: ignore[arg-type]
    ccw = Seam(pts, interpolation=interp, rotation="ccw").frames_at(base.s)  # type: ignore[arg-type]
    np.testing.assert_allclose(ccw.l, -base.l, atol=1e-12)
    rev = Seam(pts, interpolation=interp, reverse=True)  # type: ignore[arg-type]
    # The same physical point: s on the reversed seam = L - s.
    back = rev.frames_at(rev.length - base.s)
    np.testing.assert_allclose(back.p, base.p, atol=1e-9)
    np.testing.assert_allclose(back.t, -base.t, atol=1e-9)
    np.testing.assert_allclose(back.l, -base.l, atol=1e-9)
    # Both flips together restore the side.
    both = Seam(pts, interpolation=interp, rotation="ccw", reverse=True)  # type: ignore[arg-type]
    np.testing.assert_allclose(both.frames_at(rev.length - base.s).l, base.l, atol=1e-9)


def test_spline_smooth_and_arc_length() -> None:
    ang = np.deg2rad(np.arange(0, 91, 10))
    R = 0.2
    pts = np.stack([R * np.cos(ang), R * np.sin(ang), np.zeros_like(ang)], axis=1)
    seam = Seam(pts, interpolation="spline")
    assert seam.length == pytest.approx(R * np.pi / 2, rel=1e-4)
    fr = seam.frames(0.005)
    # Tangent perpendicular to the radius on a circle.
    assert np.max(np.abs(np.einsum("ki,ki->k", fr.t, fr.p))) < 2e-3 * R
    # Waypoint spacing uniform in arc length.
    d = np.linalg.norm(np.diff(fr.p, axis=0), axis=1)
    assert np.ptp(d) < 1e-5


def test_per_point_normals() -> None:
    pts = np.array([[0, 0, 0], [0.1, 0, 0]])
    nrm = np.array([[0, 0, 1.0], [0, np.sin(0.2), np.cos(0.2)]])
    fr = Seam(pts, surface_normal=nrm).frames(0.05)
    _orthonormal(fr)
    np.testing.assert_allclose(fr.n[-1], nrm[-1], atol=1e-12)


def test_interpolate_frames_exact_at_waypoints() -> None:
    seam = Seam(np.array([[0, 0, 0], [0.1, 0.05, 0], [0.2, 0, 0.01]]), interpolation="spline",
                tilt=0.03)
    fr = seam.frames(0.02)
    again = interpolate_frames(fr, fr.s)
    for a in ("p", "t", "l", "n"):
        np.testing.assert_allclose(getattr(again, a), getattr(fr, a), atol=1e-12)
    mid = interpolate_frames(fr, 0.5 * (fr.s[1:] + fr.s[:-1]))
    _orthonormal(mid)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"points": np.array([[0, 0, 0.0]])}, "at least 2 points"),
        ({"points": np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0, 0]])}, "duplicate"),
        ({"points": np.array([[0.1, 0, 0], [0.1, 0, 0]])}, "zero-length"),
        ({"tilt": np.deg2rad(15.5)}, "tilt"),
        ({"rotation": "left"}, "rotation"),
        ({"interpolation": "bezier"}, "interpolation"),
        ({"surface_normal": np.array([1.0, 0, 0])}, "parallel"),
    ],
)
def test_bad_seam(kw: dict, match: str) -> None:
    args = {"points": np.array([[0, 0, 0], [0.1, 0, 0]])} | kw
    with pytest.raises(InputError, match=match):
        Seam(**args)


def test_bad_spacing() -> None:
    with pytest.raises(InputError, match="spacing"):
        Seam(np.array([[0, 0, 0], [0.1, 0, 0]])).frames(0.0)
