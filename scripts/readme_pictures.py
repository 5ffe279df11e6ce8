"""The README's pictures, made from furrow's own outputs.

``heldout``: held-out photographs beside what furrow draws there (gather, the default method), one
row per capture, cut from the side-by-side sheets of ``furrow eval`` (top row: reference | gather |
...; the first two columns are taken)::

    furrow eval CAPTURE --holdout 2 --methods gather --save-model M -o EVAL      # once per capture
    python scripts/readme_pictures.py heldout --eval EVAL1 EVAL2 --labels "fur ball" conifer \
        --view 5 -o docs/images/heldout.jpg

``viewer``: ``furrow view MODEL`` in headless Chromium (Debian's ``chromium`` through Playwright),
the page's camera placed on the direction of capture camera ``--camera`` so that the object fills
the view, the panel open, the capture frustums hidden::

    python scripts/readme_pictures.py viewer M --camera 1 -o docs/images/viewer.jpg

The README names the captures and the commands that made its pictures.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

#: Page size of the viewer screenshot (CSS pixels) and its JPEG quality.
VIEW_W, VIEW_H = 960, 640
JPEG_QUALITY = 82
#: Page pixels per photograph pixel at the object: 1 draws the object as large as capture camera
#: ``--camera`` saw it (gather splats the photographs' pixels, so much more shows their grain).
ZOOM = 1.15
#: Label band height (pixels) above each held-out row.
LABEL_H = 18


def _sheet_columns(sheet: Path, columns: int = 2) -> Image.Image:
    """The first ``columns`` images of the top row of a side-by-side sheet (top: reference | methods;
    bottom: their error maps, so the sheet is two images high)."""
    img = Image.open(sheet).convert("RGB")
    w, h = img.size
    methods = json.loads((sheet.parent.parent / "eval.json").read_text())["methods"]
    cw, ch = w // (len(methods) + 1), h // 2
    return img.crop((0, 0, columns * cw, ch))


def heldout(evals: list[Path], labels: list[str], view: str, out: Path, height: int) -> None:
    rows = []
    for ev, label in zip(evals, labels, strict=True):
        sheets = sorted((ev / "side_by_side").glob("*.png"))
        if not sheets:
            sys.exit(f"{ev}/side_by_side: no sheets (run furrow eval ... -o {ev})")
        pick = [s for s in sheets if view in s.stem] or sheets
        row = _sheet_columns(pick[0])
        row = row.resize((round(row.width * height / row.height), height), Image.LANCZOS)
        band = Image.new("RGB", (row.width, LABEL_H), (255, 255, 255))
        ImageDraw.Draw(band).text((4, 3), f"{label}: held-out photograph | furrow (gather)", fill=(0, 0, 0))
        canvas = Image.new("RGB", (row.width, row.height + LABEL_H))
        canvas.paste(band, (0, 0))
        canvas.paste(row, (0, LABEL_H))
        rows.append(canvas)
    w = max(r.width for r in rows)
    sheet = Image.new("RGB", (w, sum(r.height for r in rows)), (255, 255, 255))
    y = 0
    for r in rows:
        sheet.paste(r, (0, y))
        y += r.height
    tmp = out.with_suffix(".tmp" + out.suffix)
    sheet.save(tmp, quality=JPEG_QUALITY)
    tmp.replace(out)
    print(f"wrote {out} ({sheet.width}x{sheet.height})")


def _page_camera(model_dir: Path, camera: int):
    from capture.orbit import estimate_up
    from furrow.bench import _browser as B
    from volume.model import load_model

    model = load_model(model_dir)
    b = np.asarray(model.bounds, float)
    target = 0.5 * (b[0] + b[1])
    cams = model.rgbz.cameras
    cam = cams[camera]
    direction = cam.center - target
    dist_capture = float(np.linalg.norm(direction))
    f_page = 0.5 * VIEW_H / np.tan(0.5 * B.VISER_DEFAULT_FOV)
    dist = f_page * dist_capture / (ZOOM * float(cam.K[1, 1]))
    return target + dist * direction / dist_capture, target, estimate_up(cams)


def viewer(model_dir: Path, camera: int, out: Path) -> None:
    from playwright.sync_api import sync_playwright

    from furrow.bench import _browser as B
    from render.methods import DEFAULT_METHOD, samples_per_pixel_side

    eye, target, up = _page_camera(model_dir, camera)
    vp = B.ViewProcess(model_dir)
    try:
        with sync_playwright() as p:
            browser = B.launch(p)
            page = browser.new_page(viewport={"width": VIEW_W, "height": VIEW_H})
            page.goto(B.view_url(vp.url, eye, target, up))
            B.wait_still(page, VIEW_W, VIEW_H, samples_per_pixel_side(DEFAULT_METHOD))
            B.wait_opaque(page)
            page.get_by_text("show capture cameras").click()
            page.add_style_tag(content="[class*='Notification'] { visibility: hidden !important; }")
            time.sleep(1.0)
            tmp = out.with_suffix(".tmp" + out.suffix)
            page.screenshot(path=str(tmp), quality=JPEG_QUALITY, type="jpeg")
            tmp.replace(out)
            browser.close()
    finally:
        code, _ = vp.interrupt()
    print(f"wrote {out} (furrow view exited {code})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    h = sub.add_parser("heldout", help="held-out photographs beside gather, from furrow eval's sheets")
    h.add_argument("--eval", nargs="+", type=Path, required=True, help="furrow eval -o folders")
    h.add_argument("--labels", nargs="+", required=True, help="one label per --eval folder")
    h.add_argument("--view", default="", help="a held-out view's name (part of its sheet's file name)")
    h.add_argument("--height", type=int, default=240, help="row height in pixels")
    h.add_argument("-o", type=Path, required=True)
    v = sub.add_parser("viewer", help="furrow view in headless Chromium, the object filling the view")
    v.add_argument("model", type=Path)
    v.add_argument("--camera", type=int, default=1, help="capture camera whose direction the page looks from")
    v.add_argument("-o", type=Path, required=True)
    a = ap.parse_args(argv)
    if a.what == "heldout":
        heldout(a.eval, a.labels, a.view, a.o, a.height)
    else:
        viewer(a.model, a.camera, a.o)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
