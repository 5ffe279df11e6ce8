"""``furrow export --web``: the static page in a real headless browser (Debian's chromium driven by
Playwright), served by a plain ``python -m http.server`` with nothing of furrow running and every
request that leaves that server aborted (offline):

* the object is visible at the first capture camera: against furrow's own render of that camera
  (the ``splat`` method's numpy twin, the same Gaussians, blended over the page's black) the
  silhouette agrees (SILHOUETTE_IOU) and the object's colours too (MASKED_PSNR_DB: the page runs
  the same image formation), and the same comparison fails for a camera with another field of
  view (the check can tell);
* orbiting with the mouse redraws the page (its frame rate is measured and printed: software
  WebGL on a shared machine says little about a GPU).

The docs/images/splats_web.jpg screenshot is written by this test when FURROW_SPLATS_SHOT names a file.
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from capture.imageio import read_color
from furrow.bench import _browser as B
from furrow.cli import main
from render.splat import reference as sr
from tests import scenes as scene
from volume.model import load_model, save_model

pytestmark = [pytest.mark.browser, pytest.mark.gl]

#: Viewport (CSS pixels = canvas pixels: device scale 1).
W, H = 960, 720
#: The capture: 12 ring cameras at half the viewport (the page shows them 2x larger).
CAPTURE = (480, 360)
#: Silhouette agreement (IoU of |pixel - background| > MASK_LEVEL, furrow.bench._browser.page_scores):
#: measured 1.00 here (0.98 on the path-traced conifer at 960 x 720, scripts/web_page_check.py).
SILHOUETTE_IOU = 0.9
MASK_LEVEL = 24
#: PSNR (8-bit) inside the union of both silhouettes: float16 covariances and SH, float32 GPU
#: arithmetic against the float64 twin; measured 47.3 dB here, 45.9 dB on the conifer.
MASKED_PSNR_DB = 35.0
#: Seconds the page is given after its first frame.
SETTLE_S = 2.0
#: Orbit duration for the frame rate (wall seconds).
ORBIT_S = 4.0



def reference_view(model, splats, fov_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """furrow's render (the numpy twin) of the first capture camera at the page's size: (C display
    colour premultiplied, A alpha); ``fov_scale`` != 1 makes a deliberately wrong camera."""
    cam = model.rgbz.cameras[0].scaled(W / CAPTURE[0])
    if fov_scale != 1.0:
        K = cam.K.copy()
        K[0, 0] *= fov_scale
        K[1, 1] *= fov_scale
        from capture.camera import Camera

        cam = Camera(K, cam.cam_from_world, cam.width, cam.height)
    pr = sr.project(splats.positions, splats.covariances(), splats.opacities, splats.sh, cam)
    C, A, _ = sr.blend(pr, W, H)
    return C, A


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    d = tmp_path_factory.mktemp("web")
    save_model(scene.compact(scene.build_model(scene.ring_cameras(12, *CAPTURE))), d / "model")
    assert main(["export", str(d / "model"), "--splats", str(d / "s.ply"), "--web", str(d / "web")]) == 0
    return d


def test_static_page_in_a_real_browser(exported):
    reason = B.skip_reason()
    if reason:
        pytest.skip(reason)
    from playwright.sync_api import sync_playwright

    from volume.export import read_splats

    web = exported / "web"
    assert sorted(p.name for p in web.iterdir()) == ["index.html", "splats.bin"]
    server = B.StaticServer(web)
    try:
        with sync_playwright() as p:
            browser = B.launch(p)
            page, blocked = B.open_offline_page(browser, server.url, W, H)
            time.sleep(SETTLE_S)
            page.add_style_tag(content="#info { visibility: hidden !important; }")
            time.sleep(0.5)
            page.screenshot(path=str(exported / "shot.png"))
            shot_path = os.environ.get("FURROW_SPLATS_SHOT")
            if shot_path:
                page.screenshot(path=shot_path, quality=80, type="jpeg")
            fps = B.frame_rate(page, ORBIT_S, W / 2, H / 2)
            browser.close()
    finally:
        server.close()
    assert not blocked, blocked
    shot = read_color(exported / "shot.png")[..., :3]
    model = load_model(exported / "model")
    splats = read_splats(exported / "s.ply")
    iou, psnr = B.page_scores(shot, *reference_view(model, splats), MASK_LEVEL)
    print(f"static page: silhouette IoU {iou:.3f}, masked PSNR {psnr:.2f} dB against furrow's render; "
          f"{fps:.2f} frames/s while orbiting at {W}x{H} (software WebGL)")
    assert iou >= SILHOUETTE_IOU and psnr >= MASKED_PSNR_DB, (iou, psnr)
    wrong_iou, wrong_psnr = B.page_scores(shot, *reference_view(model, splats, fov_scale=1.25), MASK_LEVEL)
    assert wrong_iou < SILHOUETTE_IOU or wrong_psnr < MASKED_PSNR_DB, (wrong_iou, wrong_psnr)
    assert fps > 0.0  # orbiting redraws the page
