"""The static splat page of ``furrow export --web`` in headless Chromium, measured (issue 33).

Serves DIR with a plain ``python -m http.server`` (nothing of furrow), aborts every request that
leaves it (offline), opens the page at W x H (device pixel ratio 1), waits for its first frame,
hides its one-line caption, takes a screenshot, compares it with furrow's own render of the first capture camera
(the ``splat`` method's numpy twin on the exported PLY, blended over the page's background in
display values: furrow.bench._browser.page_scores) and measures the frame rate while orbiting
with the mouse (frames that drew per second of wall time).

usage: python scripts/web_page_check.py WEB_DIR MODEL SPLATS.ply [--size 960x720] [--orbit 5]
       [--shot OUT.jpg] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("web", type=Path)
    ap.add_argument("model", type=Path)
    ap.add_argument("splats", type=Path)
    ap.add_argument("--size", default="960x720")
    ap.add_argument("--orbit", type=float, default=5.0, help="seconds of orbiting for the frame rate")
    ap.add_argument("--settle", type=float, default=5.0, help="seconds after the canvas faded in")
    ap.add_argument("--shot", type=Path, default=None, help="also save the screenshot as JPEG here")
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args(argv)
    from playwright.sync_api import sync_playwright

    from capture.imageio import read_color
    from furrow.bench import _browser as B
    from render.splat import reference as sr
    from volume.export import read_splats
    from volume.model import load_model

    W, H = (int(v) for v in a.size.split("x"))
    server = B.StaticServer(a.web)
    try:
        with sync_playwright() as p:
            browser = B.launch(p)
            t0 = time.monotonic()
            page, blocked = B.open_offline_page(browser, server.url, W, H)
            load_s = time.monotonic() - t0
            time.sleep(a.settle)
            page.add_style_tag(content="#info { visibility: hidden !important; }")
            time.sleep(0.5)
            png = a.web.parent / (a.web.name + "_shot.png")
            page.screenshot(path=str(png))
            if a.shot:
                page.screenshot(path=str(a.shot), quality=85, type="jpeg")
            fps = B.frame_rate(page, a.orbit, W / 2, H / 2)
            browser.close()
    finally:
        server.close()
    model = load_model(a.model)
    splats = read_splats(a.splats)
    cam = model.rgbz.cameras[0].scaled(W / model.rgbz.cameras[0].width)
    pr = sr.project(splats.positions, splats.covariances(), splats.opacities, splats.sh, cam)
    C, A, _ = sr.blend(pr, W, H)
    iou, psnr = B.page_scores(read_color(png)[..., :3], C, A)
    size = sum(f.stat().st_size for f in a.web.rglob("*") if f.is_file())
    out = {"web": str(a.web), "bytes": size, "gaussians": len(splats), "size": [W, H], "load_s": load_s,
           "silhouette_iou": iou, "masked_psnr_db": psnr, "orbit_fps": fps, "blocked_requests": blocked}
    print(json.dumps(out))
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
