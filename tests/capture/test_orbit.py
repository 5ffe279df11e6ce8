"""Orbit cameras and the rig's up estimate, for rigs with any up axis."""

import numpy as np
import pytest

from capture.camera import Camera, look_at, make_K
from capture.orbit import closest_point_to_axes, estimate_up, orbit_cameras


def ring(up, center, n=8, r=0.6, h=0.2):
    up = np.asarray(up, float) / np.linalg.norm(up)
    e1 = np.cross(up, [0.3, 0.5, 0.8])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(up, e1)
    out = []
    for i in range(n):
        a = 2 * np.pi * i / n + 0.3
        eye = center + h * up + r * (np.cos(a) * e1 + np.sin(a) * e2)
        out.append(Camera(make_K(100, 100, 63.5, 47.5), look_at(eye, center, up=up), 128, 96))
    return out


@pytest.mark.parametrize("up", [(0, 0, 1), (0, 1, 0), (0.3, -0.2, 0.9)])
def test_orbit_recovers_rig(up):
    center = np.array([0.1, -0.2, 0.05])
    cams = ring(up, center)
    u = np.asarray(up, float) / np.linalg.norm(up)
    assert np.allclose(estimate_up(cams), u, atol=1e-9)
    assert np.allclose(closest_point_to_axes(cams), center, atol=1e-9)
    orbit = orbit_cameras(cams, 5)
    assert len(orbit) == 5
    for c in orbit:
        uv, z = c.project(center[None])
        assert np.allclose(uv, [[63.5, 47.5]], atol=1e-6)                 # looks at the centre
        assert np.linalg.norm(c.center - center) == pytest.approx(np.hypot(0.6, 0.2), rel=1e-9)
        assert np.dot(c.center - center, u) == pytest.approx(0.2, abs=1e-9)
    assert np.allclose(orbit[0].center, cams[0].center, atol=1e-9)       # starts at the first camera
