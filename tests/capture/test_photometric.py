"""Photometric alignment: no harm at fixed exposure, recovery of jittered exposure and white balance."""

from __future__ import annotations

import numpy as np
import pytest

from capture.photometric import PhotometricConfig, apply_gains, estimate_gains, identity
from capture.scan import Scan, to_uint8_srgb
from tests.scenes import render_rgbz, scan_ring

#: The issue's property: an unjittered capture stays this close to identity (EV).
IDENTITY_EV = 0.01
#: Recovery of jittered gains (log2 units, after removing the one global gain nobody can know).
RECOVERY_EV = 0.01
#: Small test images: every pixel is a sample.
CFG = PhotometricConfig(stride=1)


def _views(n=12, glints=0.03, seed=0):
    """(cams, linear colours, depths) of the three-sphere scene, with a fraction ``glints`` of
    pixels made 3x brighter in a view-dependent way (outliers the solver must ignore)."""
    rng = np.random.default_rng(seed)
    cams = scan_ring(n, 128, 96)
    out = []
    for cam in cams:
        rgb, z = render_rgbz(cam)
        rgb = np.where((rng.random(z.shape) < glints)[..., None], np.minimum(rgb * 3, 1.0), rgb)
        out.append((cam, rgb.astype(np.float32), z))
    return out


def _scans(views, camera_gains=None):
    """8-bit sRGB scans of linear colour multiplied by each view's camera gain (clipped)."""
    g = np.ones((len(views), 3)) if camera_gains is None else camera_gains
    return [Scan(to_uint8_srgb(rgb * gi.astype(np.float32)), z, cam, cam.name) for (cam, rgb, z), gi in zip(views, g)]


def _log2_err(result_gains, truth_camera_gains):
    """(V, 3) log2 of recovered correction x true camera gain, global offset removed."""
    e = np.log2(result_gains) + np.log2(truth_camera_gains)
    return e - np.median(e, axis=0)


def test_identity_at_fixed_exposure():
    res = estimate_gains(_scans(_views()), CFG)
    assert res.pairs >= 12 and not res.unaligned
    assert np.abs(np.log2(res.gains)).max() < IDENTITY_EV


def test_recovers_jittered_exposure_and_white_balance():
    rng = np.random.default_rng(3)
    n = 12
    ev = rng.normal(0, 0.35, n)
    wb = np.exp(rng.normal(0, 0.06, (n, 3)))
    cam_gain = np.exp2(ev)[:, None] * wb          # what the "camera" did to linear colour
    views = _views(n)
    res = estimate_gains(_scans(views, cam_gain), CFG)
    err = _log2_err(res.gains, cam_gain)
    assert np.abs(err).max() < RECOVERY_EV
    # corrected colours agree with the truth up to the global gain
    fixed = apply_gains(_scans(views, cam_gain), res.gains)
    assert all(f.rgb.dtype == np.uint8 for f in fixed)


def test_reference_view_and_errors():
    scans = _scans(_views(6, glints=0.0))
    res = estimate_gains(scans, PhotometricConfig(reference=scans[2].name))
    assert np.allclose(res.gains[2], 1.0)
    with pytest.raises(ValueError, match="neither median nor mean nor a view name"):
        estimate_gains(scans, PhotometricConfig(reference="nope"))
    off = identity(scans)
    assert np.all(off.gains == 1) and off.record()["views"][0]["ev"] == 0
    assert apply_gains(scans, off.gains)[0] is scans[0]


def test_view_dependent_appearance_is_not_taken_for_exposure():
    """On a ring of 18 views, a smooth change of colour with the viewpoint (a lit side) stays;
    independent per-view jumps (auto exposure) are recovered."""
    from capture.photometric import exposure_part

    az = np.radians(np.arange(18) * 20.0)
    fwd = np.stack([np.cos(az), np.sin(az), np.zeros(18)], axis=1)
    smooth = 0.4 * np.stack([np.cos(az), np.cos(az + 0.5), np.cos(2 * az)], axis=1)
    e, ratio = exposure_part(smooth - smooth.mean(0), fwd, 30.0)
    assert np.abs(e).max() < 0.02 and ratio > 10
    rms = []
    for seed in range(6):   # 18 draws can look partly smooth by chance (seed 0 here): judged over six
        rng = np.random.default_rng(seed)
        jumps = rng.normal(0, 0.3, (18, 1)) + rng.normal(0, 0.05, (18, 3))
        jumps -= jumps.mean(0)
        e, _ = exposure_part(jumps, fwd, 30.0)
        rms.append(np.sqrt(np.mean((e - jumps) ** 2)) / np.sqrt(np.mean(jumps ** 2)))
    assert np.median(rms) < 0.01 and max(rms) < 0.5


def test_views_without_a_usable_pair_keep_their_colour():
    scans = _scans(_views(4, glints=0.0))
    res = estimate_gains(scans, PhotometricConfig(max_angle_deg=1.0))
    assert res.pairs == 0 and np.all(res.gains == 1.0) and len(res.unaligned) == 4


def _blotches(cam, depth, seed: int, sigma: float, scale: float = 0.004, blobs: int = 600) -> np.ndarray:
    """(H, W, 1) exp(sigma N(x)) of a random field N over the world points of ``depth`` (unit variance;
    ``blobs`` Gaussian blobs of ``scale`` metres with random signs): a fine texture on the surface that each
    view draws anew (``seed``), as strands that do not correspond from view to view."""
    rng = np.random.default_rng(seed)
    c = rng.uniform(-0.12, 0.12, (blobs, 3))
    s = rng.choice([-1.0, 1.0], blobs)
    vv, uu = np.nonzero(depth > 0)
    p = cam.unproject(np.stack([uu, vv], 1).astype(np.float64), depth[vv, uu].astype(np.float64))
    f = (s * np.exp(-((p[:, None] - c[None]) ** 2).sum(-1) / (2 * scale ** 2))).sum(1)
    out = np.ones(depth.shape)
    out[vv, uu] = np.exp(sigma * f / max(f.std(), 1e-9))
    return out[..., None].astype(np.float32)


def _textured(views, sigma: float, seed: int = 100):
    return [(cam, rgb * _blotches(cam, z, seed + k, sigma), z) for k, (cam, rgb, z) in enumerate(views)]


def _patchy_light(views, sigma: float = 0.3, sectors: int = 6, seed: int = 5):
    """Fixed exposure, but in every view each of ``sectors`` wedges of the object (by azimuth about z) is
    lit by its own factor exp(N(0, sigma)): lamps that flicker independently, sheen that moves.  Every
    pair's overlap holds a few wedges that disagree; no gain per view explains them."""
    a = np.random.default_rng(seed).normal(0, sigma, (len(views), sectors))
    a -= a.mean(axis=1, keepdims=True)   # no part common to a whole view: nothing an exposure would explain
    out = []
    for ak, (cam, rgb, z) in zip(a, views):
        vv, uu = np.nonzero(z > 0)
        p = cam.unproject(np.stack([uu, vv], 1).astype(np.float64), z[vv, uu].astype(np.float64))
        wedge = np.floor((np.arctan2(p[:, 1], p[:, 0]) + np.pi) / (2 * np.pi) * sectors).astype(np.int64) % sectors
        f = np.ones(z.shape, np.float32)
        f[vv, uu] = np.exp(ak[wedge])
        out.append((cam, rgb * f[..., None], z))
    return out


def test_alignment_that_does_not_hold_is_not_applied():
    """Captures made to defeat the estimator (:func:`_patchy_light`, eight draws): by itself it finds per-view
    "exposures" (whichever wedges dominate a pair's overlap), 0.3 EV and more off in seven of them (in the
    eighth it takes the wedges' changes for smooth appearance and corrects nothing); the check finds they do not
    hold on held-back cells and keeps every view's colour, and says so -- in five of those seven (measured: in
    the other two the wedges a pair sees do share a brightness change, which the held-back pairs confirm, and
    one exposure per view is aligned)."""
    defeated = kept = 0
    for seed in range(1, 9):
        scans = _scans(_patchy_light(_views(12, glints=0.0), seed=seed))
        raw = estimate_gains(scans, PhotometricConfig(stride=1, check=False))
        if np.abs(np.log2(raw.gains)).max() < 0.3:   # what applying the estimate would have done
            continue
        defeated += 1
        res = estimate_gains(scans, CFG)
        if res.meta["check"]["chosen"] == "none":
            kept += 1
            assert np.all(res.gains == 1.0) and res.meta["check"]["reason"].startswith("kept the views as they are")
    assert defeated >= 7 and kept >= 5


def test_alignment_that_holds_is_applied_through_texture():
    """A strong fine texture that each view draws anew (strands that do not correspond, sigma 0.5 in log) on
    top of a jittered exposure: the check keeps the alignment and the gains are recovered within 0.05 EV (the
    texture averages out over the cells)."""
    rng = np.random.default_rng(8)
    cam_gain = np.exp2(rng.normal(0, 0.35, 12))[:, None] * np.exp(rng.normal(0, 0.06, (12, 3)))
    res = estimate_gains(_scans(_textured(_views(12), sigma=0.5), cam_gain), CFG)
    assert res.meta["check"]["chosen"] in ("ev", "full")
    assert np.abs(_log2_err(res.gains, cam_gain)).mean(1).max() < 0.05


def test_appearance_that_changes_the_colour_is_not_taken_for_exposure():
    """At fixed exposure, a sheen that brightens and whitens (adds to blue more than to red) views on one side
    of the ring: the solve alone takes it for exposure; predicted from its colour by the other views, it is
    left in place.  With a jittered exposure on top (its EV spread twice the sheen's), the colour cannot show
    the sheen through the jitter and the views are aligned as the solve says: off by no more than the sheen."""
    n = 18
    views = _views(n, glints=0.0)
    az = np.radians(np.arange(n) * 20.0)
    sheen = 0.25 * (1 + np.cos(az))                       # strongest at view 0, none opposite
    white = np.array([0.1, 0.2, 0.4], np.float32)         # a white sheen on a warm colour: blue gains most
    lit = [(cam, rgb + (sh * white * (z > 0)[..., None]).astype(np.float32), z)
           for (cam, rgb, z), sh in zip(views, sheen)]
    none = np.log2(estimate_gains(_scans(lit), PhotometricConfig(stride=1, check=False, appearance="none")).gains)
    res = estimate_gains(_scans(lit), PhotometricConfig(stride=1, check=False))
    assert np.abs(none.mean(1)).max() > 0.15 and res.meta["appearance_share"] > 0.9
    assert np.abs(np.log2(res.gains).mean(1)).max() < 0.2 * np.abs(none.mean(1)).max()
    rng = np.random.default_rng(4)
    cam_gain = np.exp2(rng.normal(0, 0.35, n))[:, None] * np.exp(rng.normal(0, 0.06, (n, 3)))
    err = _log2_err(estimate_gains(_scans(lit, cam_gain), PhotometricConfig(stride=1)).gains, cam_gain).mean(1)
    sheen_ev = none.mean(1) - np.median(none.mean(1))
    assert np.sqrt(np.mean(err ** 2)) < np.sqrt(np.mean(sheen_ev ** 2)) + 0.03


def test_partial_matte_pixels_are_samples():
    """A matte of alpha 0.7 over the whole object (a conifer's needles: no pixel opaque in two views)
    over black (C = a F, times the camera's gain): PhotometricConfig.min_alpha 0.5 finds pairs and the
    jitter; 0.999 (the rule before) found none and kept every view's colour."""
    rng = np.random.default_rng(3)   # seed 5's jitter happens to vary smoothly round the ring: taken for appearance
    n = 12
    cam_gain = np.exp2(rng.normal(0, 0.35, n))[:, None] * np.ones(3)
    views = _views(n)
    scans = [Scan(to_uint8_srgb(0.7 * rgb * gi.astype(np.float32)), z, cam, cam.name,
                  np.where(z > 0, 0.7, 0.0).astype(np.float32))
             for (cam, rgb, z), gi in zip(views, cam_gain)]
    res = estimate_gains(scans, CFG)
    assert res.pairs >= 12 and not res.unaligned
    assert np.abs(_log2_err(res.gains, cam_gain)).max() < 0.02
    before = estimate_gains(scans, PhotometricConfig(stride=1, min_alpha=0.999))
    assert before.pairs == 0 and len(before.unaligned) == n and np.all(before.gains == 1)
    with pytest.raises(ValueError, match="min_alpha"):
        PhotometricConfig(min_alpha=0.0)
