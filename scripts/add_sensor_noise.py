"""A copy of a transforms.json capture whose frames carry a camera's sensor noise: independent in every
frame, Gaussian in 8-bit sRGB steps (issue 30; docs/matting.md "Sensor noise behind the object").

The path-traced rooms of scripts/hardcases.py have none behind the object: the room is a visible
environment map, which a camera ray reads without Monte Carlo noise, so the room's pixels differ between
frames only by the auto exposure's rounding (0.4 sRGB steps).  A real camera's frames differ by their
noise everywhere, and the room path (plate, matte, the colour across the views) reads the background in
every frame.

    PYTHONPATH=. .venv/bin/python scripts/add_sensor_noise.py CAPTURE OUT --sigma 1.5 [--frames 0::2] [--seed 0]
    PYTHONPATH=. .venv/bin/python scripts/add_sensor_noise.py CAPTURE OUT --sigma 3 --camera [--jpeg-quality 90]

``--camera``: the noise a camera leaves instead (docs/matting.md, "Camera-like noise"): the frame to linear, an RGGB
mosaic, shot and read noise in linear (read CAMERA_READ; the shot noise's gain set so that linear CAMERA_GREY has
``--sigma`` 8-bit steps), OpenCV's bilinear demosaicing, 8-bit sRGB, JPEG at ``--jpeg-quality``, decoded and written
back as the frame's PNG (the file names stay).  Its noise is correlated between neighbours: capture.noise's finest
level reads sigma 3 as 0.56, the next level 2.06.

OUT gets the noisy colour images of the frames ``--frames`` selects (default: the frames `furrow eval
--holdout 2` keeps, so that the held-out references stay as rendered), a copy of the other frames' images,
and a symbolic link to every other entry of CAPTURE (transforms.json, depth, masks, gt).  Frame i's noise
is drawn from the seed ``--seed`` * 100,003 + i: the same copy every time.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np

from capture.imageio import read_color, write_png
from capture.scan import select_indices


def noisy(rgb: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """(H, W, 3) uint8 sRGB ``rgb`` plus Gaussian noise of ``sigma`` 8-bit steps, rounded and clipped."""
    return np.clip(np.rint(rgb.astype(np.float64) + rng.normal(0.0, sigma, rgb.shape)), 0, 255).astype(np.uint8)


#: --camera: the read noise (linear) and the grey (linear, about sRGB 124) at which the noise is --sigma steps.
CAMERA_READ = 0.002
CAMERA_GREY = 0.2


def camera_noisy(rgb: np.ndarray, sigma: float, quality: int, rng: np.random.Generator) -> np.ndarray:
    """(H, W, 3) uint8 sRGB ``rgb`` through a camera-like pipeline (module docstring): mosaic, shot + read noise of
    ``sigma`` steps at CAMERA_GREY, bilinear demosaicing, JPEG ``quality``."""
    import cv2

    from capture.scan import linear_to_srgb, srgb8_to_linear

    lin = srgb8_to_linear(rgb).astype(np.float64)
    mosaic = np.empty(lin.shape[:2])
    for (dy, dx), c in (((0, 0), 0), ((0, 1), 1), ((1, 0), 1), ((1, 1), 2)):  # RGGB
        mosaic[dy::2, dx::2] = lin[dy::2, dx::2, c]
    slope = 255.0 * (linear_to_srgb(np.array(CAMERA_GREY + 1e-4)) - linear_to_srgb(np.array(CAMERA_GREY))) / 1e-4
    var = max((sigma / float(slope)) ** 2 - CAMERA_READ ** 2, 1e-12)  # the shot noise's share at CAMERA_GREY
    noisy = mosaic + rng.normal(0.0, 1.0, mosaic.shape) * np.sqrt(np.maximum(mosaic, 0) * var / CAMERA_GREY
                                                                   + CAMERA_READ ** 2)
    raw = np.clip(np.rint(noisy * 65535), 0, 65535).astype(np.uint16)
    dem = cv2.cvtColor(raw, cv2.COLOR_BayerBG2RGB).astype(np.float64) / 65535  # OpenCV names RGGB data "BG"
    s8 = np.clip(np.rint(linear_to_srgb(np.clip(dem, 0, 1)) * 255), 0, 255).astype(np.uint8)
    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(s8[..., ::-1]), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise SystemExit("JPEG encoding failed")
    return np.ascontiguousarray(cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1])


def main(argv=None) -> Path:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("capture", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--sigma", type=float, required=True, help="noise in 8-bit sRGB steps (e.g. 1.5)")
    p.add_argument("--frames", default="0::2",
                   help="the frames given noise, as furrow's --frames (default 0::2: the kept)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--camera", action="store_true",
                   help="a camera's noise instead: mosaic, shot + read noise (--sigma steps at mid grey), bilinear "
                        "demosaicing, JPEG (module docstring)")
    p.add_argument("--jpeg-quality", type=int, default=90, help="--camera: the JPEG quality (1-100, default 90)")
    a = p.parse_args(argv)
    if not 1 <= a.jpeg_quality <= 100:
        raise SystemExit(f"--jpeg-quality must be 1-100, got {a.jpeg_quality}")
    src = a.capture / "transforms.json"
    if not src.is_file():
        raise SystemExit(f"{src}: no transforms.json")
    if not a.sigma > 0:
        raise SystemExit(f"--sigma must be > 0, got {a.sigma}")
    frames = json.loads(src.read_text())["frames"]
    try:
        chosen = set(select_indices(a.frames, len(frames)))  # furrow's --frames syntax
    except (ValueError, IndexError) as e:
        raise SystemExit(f"--frames: {e}") from None
    a.out.mkdir(parents=True, exist_ok=True)
    for entry in a.capture.iterdir():
        link = a.out / entry.name
        if entry.name != "images" and not link.exists():
            link.symlink_to(entry.resolve())
    for i, fr in enumerate(frames):
        s, d = a.capture / fr["file_path"], a.out / fr["file_path"]
        d.parent.mkdir(parents=True, exist_ok=True)
        if i not in chosen:
            shutil.copyfile(s, d)
            continue
        rgb = read_color(s)
        if rgb.dtype != np.uint8:
            raise SystemExit(f"{s}: 8-bit colour images only (got {rgb.dtype})")
        rng = np.random.default_rng(a.seed * 100_003 + i)
        write_png(d, camera_noisy(rgb, a.sigma, a.jpeg_quality, rng) if a.camera else noisy(rgb, a.sigma, rng))
    print(a.out)
    return a.out


if __name__ == "__main__":
    main()
