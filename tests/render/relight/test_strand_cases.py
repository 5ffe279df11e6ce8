"""Hard relighting cases for strands (issue 23 item 3), end to end in numpy: a slab of fibres along a known
direction, its colour from the strand transfer (render.shading.hair_transfer) with a striped fibre colour
and a white specular weight, captured from 8 views under map A; tangents and fibre colours estimated from
those views (render.relight.strands), then a held-out view relit to map B and scored against the same
model's truth under B.  This checks the estimation and the inversion (not the model's fidelity to real
fur, which ``furrow bench relight`` measures).  The cases: B differs from A mostly in direction (same
power), B strongly coloured, B one sun on black."""

from __future__ import annotations

import numpy as np
import pytest

from capture.camera import Camera, look_at, make_K
from render.relight.reference import volume_sample
from render.relight.strands import field_sample, strand_colour, strand_field
from render.shading.envmap import EnvMap
from render.shading.hair_transfer import hair_diffuse, hair_gain, hair_specular
from render.shading.transfer import global_gain, relight_lighting

W, H = 96, 72
UP = (0.0, 0.0, 1.0)
FIBRE_DIR = np.array([np.cos(np.radians(35)), np.sin(np.radians(35)), 0.0])
BASE_RHO = np.array([0.6, 0.4, 0.25])
SIGMA = 0.08
#: Required: relit PSNR at least this far above the single gain's (dB), and at least this absolute per case
#: (measured 29.4 / 34.5 / 33.2 dB against the gain's 11.7 / 13.3 / 11.7).
MIN_MARGIN_DB = 6.0
MIN_PSNR_DB = {"direction": 27.0, "coloured": 32.0, "one-sun": 30.0}


def _sky(sun, tint=(1.0, 1.0, 1.0), sky=0.3, sun_power=40.0, h=32) -> EnvMap:
    d = EnvMap(np.zeros((h, 2 * h, 3), np.float32)).pixel_directions()
    s = np.asarray(sun, float) / np.linalg.norm(sun)
    base = sky * (0.5 + 0.5 * np.maximum(d[..., 2:3], 0)) * np.array([0.6, 0.8, 1.0])
    disc = sun_power * np.exp(60 * (d @ s - 1))[..., None]
    return EnvMap(((base + disc) * np.asarray(tint)).astype(np.float32), "sky")


def _sun_dir(az_deg, el_deg=30.0):
    a, e = np.radians(az_deg), np.radians(el_deg)
    return (np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e))


A_MAP = _sky(_sun_dir(20))
CASES = {
    "direction": _sky(_sun_dir(140)),  # the same sky and sun, turned 120 degrees: same power
    "coloured": _sky(_sun_dir(-70, 45), tint=(1.0, 0.35, 0.1)),
    "one-sun": _sky(_sun_dir(200, 15), sky=0.0, sun_power=60.0),
}


def _fur(env):
    return relight_lighting(env, UP, "wrap", 16)


def _camera(az_deg: float) -> Camera:
    a = np.radians(az_deg)
    eye = np.array([0.9 * np.cos(a), 0.9 * np.sin(a), 0.8])
    return Camera(make_K(90.0, 90.0, (W - 1) / 2, (H - 1) / 2), look_at(eye, (0, 0, 0)), W, H)


def _shoot(cam: Camera, fur):
    """(colour (H, W, 3), depth (H, W)) of the fibre slab |x|, |y| < 0.3, z = 0 under ``fur``."""
    uv = cam.pixel_grid().reshape(-1, 2)
    d = cam.pixel_rays(uv) @ cam.cam_from_world[:3, :3]
    c = cam.center
    t = -c[2] / d[:, 2]
    p = c + t[:, None] * d
    inside = (t > 0) & (np.abs(p[:, 0]) < 0.3) & (np.abs(p[:, 1]) < 0.3)
    across = np.cross(UP, FIBRE_DIR)
    rho = BASE_RHO * (0.55 + 0.45 * np.sin(2 * np.pi * (p[inside] @ across) / 0.05))[:, None]
    v = c - p[inside]
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    tan = np.tile(FIBRE_DIR, (len(v), 1))
    nrm = np.tile(UP, (len(v), 1))
    col = np.zeros((len(uv), 3))
    col[inside] = rho * hair_diffuse(fur, tan, nrm, v) + SIGMA * hair_specular(fur, tan, nrm, v)
    z = np.where(inside, (p - c) @ cam.forward, 0.0)
    return col.reshape(H, W, 3), z.reshape(H, W)


@pytest.fixture(scope="module")
def captured():
    fur_a = _fur(A_MAP)
    cams = [_camera(360 * i / 8) for i in range(8)]
    shots = [_shoot(c, fur_a) for c in cams]
    rgb = np.stack([s[0] for s in shots]).astype(np.float32)
    dep = np.stack([s[1] for s in shots]).astype(np.float32)
    field = strand_field(rgb, dep, cams, np.full(3, -0.32), 0.64 / 16, res=16, stride=1)
    normals = lambda x: np.tile(UP, (len(x), 1))
    return fur_a, strand_colour(field, rgb, dep, cams, fur_a, normals, stride=1)


def _psnr(a, b, m):
    peak = float(b[m].max())
    return float(10 * np.log10(peak ** 2 / np.mean((a[m] - b[m]) ** 2)))


@pytest.mark.parametrize("case", sorted(CASES))
def test_strands_relit_to_a_hard_map(captured, case):
    fur_a, sc = captured
    fur_b = _fur(CASES[case])
    cam = _camera(22.5 + 45)  # between two capture views
    col_a, dep = _shoot(cam, fur_a)
    col_b, _ = _shoot(cam, fur_b)
    m = dep > 0
    x = cam.unproject(cam.pixel_grid()[m], dep[m])
    v = cam.center - x
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    t, w = field_sample(sc.field, x)
    fit = volume_sample(sc.fit, sc.field.origin, sc.field.voxel, x)
    g = global_gain(fur_a, fur_b)
    gain = hair_gain(t, np.tile(UP, (len(t), 1)), v, fit[:, :3], fit[:, 3], fur_a, fur_b, g)
    relit = np.zeros_like(col_a)
    relit[m] = col_a[m] * gain
    single = col_a * g
    p_relit, p_gain = _psnr(relit, col_b, m), _psnr(single, col_b, m)
    assert np.median(w) > 0.5  # the slab reads as strands
    assert p_relit >= MIN_PSNR_DB[case] and p_relit >= p_gain + MIN_MARGIN_DB, (case, p_relit, p_gain)
