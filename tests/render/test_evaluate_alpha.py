"""Composite scores of the held-out evaluation (render.evaluate.composite_scores) on scenes with a
known matte: exact numbers on a hand-made frame, and gather with and without the matte."""

from __future__ import annotations

import numpy as np

from capture.scan import Scan
from render import evaluate as ev
from render.frame import Frame, FrameStats
from tests import scenes as scene

STATS = FrameStats(0.0, 0.0, supersample=1)


def _held(cam, ramp_px=3.0):
    """A held-out scan of the spheres scene with a soft true matte: photo over black = colour x matte."""
    rgb, depth = scene.render_rgbz(cam)
    a = scene.soft_matte(depth[None], ramp_px, seed=None)[0]
    return Scan((rgb * a[..., None]).astype(np.float32), depth, cam, name=cam.name, alpha=a), rgb, a


def test_composite_scores_by_hand():
    cam = scene.ring_cameras(4)[1]
    scan, rgb, a = _held(cam)
    exact = Frame(rgb * a[..., None], a, scan.depth, STATS)
    s = ev.composite_scores(scan, exact)
    assert s["psnr_white"] == s["psnr_dark"] == 100.0 and s["alpha_mse"] == 0.0 and s["alpha_sad"] == 0.0
    binary = Frame(rgb * (a > 0)[..., None], (a > 0).astype(np.float32), scan.depth, STATS)
    s = ev.composite_scores(scan, binary)
    region = a > 0
    assert np.isclose(s["alpha_mse"], np.mean((1 - a[region]) ** 2))
    assert np.isclose(s["alpha_sad"], np.sum(1 - a[region]) / 1000)
    assert s["psnr_white"] < 40.0 and s["psnr_dark"] < 100.0
    no_matte = Scan(scan.rgb, scan.depth, cam, name=cam.name)
    assert ev.composite_scores(no_matte, exact) == {}
    assert np.isnan(ev.summarise([{**ev.score_view(no_matte, exact)}])["alpha_mse"])


def test_gather_with_the_matte_scores_the_composite(gl_ctx):
    """Kept views with their true matte in the model: gather's alpha follows the held-out matte and
    its composite over white beats the matte-less model's; over black the scores hardly move."""
    cams = scene.ring_cameras(12)
    kept, held = cams[0::2], cams[1::2]
    base = scene.build_model(kept)
    with_a = scene.with_alpha(base, scene.soft_matte(base.rgbz.depth, seed=None))
    scans = [_held(c)[0] for c in held]
    res = {name: ev.evaluate(gl_ctx, m, scans, methods=("gather",))["gather"]
           for name, m in (("binary", base), ("alpha", with_a))}
    b, s = res["binary"], res["alpha"]
    assert s["alpha_mse"] < 0.5 * b["alpha_mse"], (s["alpha_mse"], b["alpha_mse"])
    assert s["psnr_white"] > b["psnr_white"] + 3.0, (s["psnr_white"], b["psnr_white"])
    assert s["psnr_masked"] > b["psnr_masked"] - 0.5


def test_gt_model_takes_the_matte_of_over_black_photos_only():
    """render.gt_model.rgb_and_matte: straight colour = photo / alpha for photos over black; a photo
    with something behind the object gives no matte (the model stage estimates that foreground)."""
    from render.gt_model import rgb_and_matte

    cams = scene.ring_cameras(4)
    scans = [_held(c)[0] for c in cams]
    rgb, a = rgb_and_matte(scans)
    straight = [scene.render_rgbz(c)[0] for c in cams]
    inner = a > 0.2
    np.testing.assert_allclose(rgb[inner], np.stack(straight)[inner], atol=1e-5)
    room = [Scan(s.rgb + (1 - s.alpha[..., None]) * 0.3, s.depth, s.camera, name=s.name, alpha=s.alpha) for s in scans]
    assert rgb_and_matte(room)[1] is None
    assert rgb_and_matte([Scan(s.rgb, s.depth, s.camera, name=s.name) for s in scans])[1] is None
