"""Weld window and seam-frame contracts."""

from __future__ import annotations

import numpy as np
import pytest

from rfsw_plan.exceptions import InputError
from rfsw_plan.process.frames import SeamFrames, tcp_orientation
from rfsw_plan.process.window import WeldWindow


def test_default_window_is_seed_000() -> None:
    w = WeldWindow()
    assert w.lower == pytest.approx(-1.25e-3)
    assert w.upper == pytest.approx(0.7e-3)
    assert w.contains(0.0) and not w.contains(0.8e-3) and not w.contains(-1.3e-3)
    assert w.margin(0.0) == pytest.approx(0.7e-3)
    assert w.margin(1.0e-3) == pytest.approx(-0.3e-3)


def test_window_rejects_inverted_bounds() -> None:
    with pytest.raises(InputError, match="lower"):
        WeldWindow(lower=1e-3, upper=-1e-3)


def _frames(k: int = 5) -> SeamFrames:
    rng = np.random.default_rng(3)
    t = rng.normal(size=(k, 3))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    n = np.cross(t, rng.normal(size=(k, 3)))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    l = np.cross(n, t)
    return SeamFrames(np.arange(k) * 0.01, rng.normal(size=(k, 3)), t, l, n)


def test_seam_base_round_trip() -> None:
    f = _frames()
    v = np.random.default_rng(0).normal(size=(5, 3))
    np.testing.assert_allclose(f.to_base(f.to_seam(v)), v, atol=1e-12)


@pytest.mark.parametrize("rot", [0.0, 0.7, -2.0])
def test_tcp_orientation_points_into_workpiece(rot: float) -> None:
    f = _frames()
    R = tcp_orientation(f, rot)
    for k in range(len(f)):
        np.testing.assert_allclose(R[k].T @ R[k], np.eye(3), atol=1e-12)
        assert np.linalg.det(R[k]) == pytest.approx(1.0)
        np.testing.assert_allclose(R[k][:, 2], -f.n[k], atol=1e-12)
    # the rotation about the tool axis is the requested angle
    R0 = tcp_orientation(f, 0.0)
    cos = np.einsum("ki,ki->k", R0[:, :, 0], R[:, :, 0])
    np.testing.assert_allclose(cos, np.cos(rot), atol=1e-12)
