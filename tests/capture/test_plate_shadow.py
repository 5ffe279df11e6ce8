"""The object's own shadow put into a fixed camera's plate (capture.plate_shadow).

A seeded scene with exact ground truth: an opaque disc with a soft fringe on a textured table, the table darkened
to 0.55 in a crescent beside it (the shadow the plate, the frames' median, does not hold); the support mask against a
ray-by-ray reference; the relit plate against the shadowed table; the matte's false alpha in the shadow with and
without it; and a frame without a shadow (or with noise only) leaving the plate as it was.  Measured: 20 % of the
ring in the shadow; the relit plate 0.0063 off the shadowed table there against the plain plate's 0.174; the matte's
mean alpha on the shadowed table inside the band (true alpha 0) 0.140 against 0.543.
"""

from __future__ import annotations

import numpy as np
import pytest

import capture.plate_shadow as ps
from capture.camera import Camera, make_K
from capture.matting import BG, FG, UNKNOWN
from capture.matting_known import known_background_matte
from capture.plate_shadow import lines_off_shadow, shadow_relit, support_pixels

H, W = 96, 128
#: The relit plate's mean error against the shadowed table in the shadow, as a share of the plate's own.
RELIT_SHARE = 0.3
#: The matte's mean alpha in the shadow (true alpha 0) with the relit plate, as a share of the plain plate's.
ALPHA_SHARE = 0.3
#: The matte's mean alpha on the shadowed table where the frames' lines had estimated the plate, with those pixels
#: unknown, as a share of its alpha with them kept (measured 0.028 against 0.091).
LINES_ALPHA_SHARE = 0.5


def _scene(shadow=0.55, seed=0):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float64)
    table = 0.35 + 0.1 * np.sin(xx / 5.0)[..., None] * np.array([1.0, 0.8, 0.6]) + rng.uniform(0, 0.05, (H, W, 3))
    r = np.hypot(yy - 48, xx - 64)
    alpha = np.clip((22.0 - r) / 3.0, 0.0, 1.0)  # opaque inside 19 px, a 3-px fringe
    shade = np.ones((H, W))
    crescent = (np.hypot(yy - 56, xx - 52) < 30) & (r > 20)
    shade[crescent] = shadow
    F = np.broadcast_to(np.array([0.25, 0.18, 0.12]), (H, W, 3))
    C = alpha[..., None] * F + (1 - alpha[..., None]) * table * shade[..., None]
    tri = np.full((H, W), BG)
    tri[r < 26] = UNKNOWN
    tri[r < 15] = FG
    return C, table, tri, alpha, crescent, shade


def test_the_support_is_where_the_ray_meets_the_plane_near_the_object():
    K = make_K(30.0, 30.0, 15.5, 11.5)
    pose = np.eye(4)
    pose[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]  # looking along +y, image down = world -z
    pose[:3, 3] = -pose[:3, :3] @ np.array([0.0, -0.6, 0.3])  # camera at (0, -0.6, 0.3)
    cam = Camera(K, pose, 32, 24)
    plane, centre, radius = np.array([0.0, 0.0, 1.0, 0.0]), np.array([0.0, 0.0, 0.0]), 0.3
    got = support_pixels(cam, plane, centre, radius, (24, 32))
    want = np.zeros((24, 32), bool)
    for v in range(24):
        for u in range(32):
            d = np.linalg.inv(K) @ np.array([u, v, 1.0])
            d = pose[:3, :3].T @ d
            o = np.array([0.0, -0.6, 0.3])
            t = -o[2] / d[2] if d[2] != 0 else -1.0
            want[v, u] = t > 0 and np.linalg.norm(o + t * d - centre) < 1.5 * radius
    assert np.array_equal(got, want) and 0 < got.sum() < got.size


def test_the_shadow_goes_into_the_plate_and_out_of_the_alpha():
    C, table, tri, alpha, shadowed, shade = _scene()
    known, support = np.ones((H, W), bool), np.ones((H, W), bool)
    lit, rec = shadow_relit(C, table, known, tri, support)
    assert rec is not None and rec["dark_share"] >= 0.1, rec
    truth = table * shade[..., None]
    band = shadowed & (alpha == 0)  # the shadowed table, inside the band and beside it
    err_lit = np.abs(lit - truth)[band].mean()
    err_plain = np.abs(table - truth)[band].mean()
    assert err_lit <= RELIT_SHARE * err_plain, (err_lit, err_plain)
    a_plain = known_background_matte(C, tri, table, known, 0.004)[0]
    a_lit = known_background_matte(C, tri, lit, known, 0.004)[0]
    in_band_shadow = shadowed & (tri == UNKNOWN) & (alpha == 0)
    assert in_band_shadow.sum() > 50
    assert a_lit[in_band_shadow].mean() <= ALPHA_SHARE * a_plain[in_band_shadow].mean()


@pytest.mark.parametrize("noise", [0.0, 0.03])
def test_no_shadow_leaves_the_plate_as_it_was(noise):
    C, table, tri, *_ = _scene(shadow=1.0)
    C = C * (1 + np.random.default_rng(1).uniform(-noise, noise, C.shape))
    lit, rec = shadow_relit(C, table, np.ones((H, W), bool), tri, np.ones((H, W), bool))
    assert rec is None and lit is table
    # off the support nothing is measured either
    C2, table2, tri2, *_ = _scene()
    lit2, rec2 = shadow_relit(C2, table2, np.ones((H, W), bool), tri2, np.zeros((H, W), bool))
    assert rec2 is None and lit2 is table2


def test_the_lines_estimates_on_a_shadowed_support_count_as_unknown(monkeypatch):
    """lines_off_shadow: with a shadow record the estimated pixels on the support leave both masks (the record counts
    them); off the support, without a record or with SHADOW_DROPS_LINES off, the masks stay as they were."""
    rng = np.random.default_rng(3)
    known = rng.random((H, W)) < 0.9
    est = known & (rng.random((H, W)) < 0.4)
    support = np.zeros((H, W), bool)
    support[H // 2:] = True
    rec = {}
    k2, e2 = lines_off_shadow(known, est, support, rec)
    assert np.array_equal(k2, known & ~(est & support)) and np.array_equal(e2, est & ~support)
    assert rec["lines_dropped"] == int((est & support).sum()) > 0
    assert lines_off_shadow(known, est, support, None) == (known, est)
    monkeypatch.setattr(ps, "SHADOW_DROPS_LINES", False)
    assert lines_off_shadow(known, est, support, {}) == (known, est)


def test_lines_that_mixed_the_shadow_in_give_no_false_alpha_once_unknown():
    """The frames' lines solve one background per pixel across the frames; where the object's shadow fell in some of
    them, the estimate mixes lit and shadowed table (here 0.8 of the table under the crescent).  Relit by the ring and
    kept, it leaves false alpha on the shadowed table (true alpha 0: 0.091); unknown, the matte fills it from its
    neighbours (0.028).  Over every estimated pixel the alpha's mean error 0.039 -> 0.023 (the estimates off the
    shadow, which were right: 0.015 -> 0.017, the price)."""
    C, table, tri, alpha, shadowed, _ = _scene()
    known, support = np.ones((H, W), bool), np.ones((H, W), bool)
    yy, xx = np.mgrid[0:H, 0:W]
    r = np.hypot(yy - 48, xx - 64)
    est = (r < 26) & (r > 12)
    plate = np.where((est & shadowed)[..., None], 0.8 * table, table)
    lit, rec = shadow_relit(C, plate, known, tri, support)
    assert rec is not None
    k2, _ = lines_off_shadow(known, est, support, rec)
    a_keep = known_background_matte(C, tri, lit, known, 0.004)[0]
    a_drop = known_background_matte(C, tri, lit, k2, 0.004)[0]
    table_under = shadowed & est & (alpha == 0)
    assert table_under.sum() > 100
    assert a_drop[table_under].mean() <= LINES_ALPHA_SHARE * a_keep[table_under].mean()
    assert np.abs(a_drop - alpha)[est].mean() < np.abs(a_keep - alpha)[est].mean()
