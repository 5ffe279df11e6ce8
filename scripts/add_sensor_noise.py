"""A copy of a transforms.json capture whose frames carry a camera's sensor noise: independent in every
frame, Gaussian in 8-bit sRGB steps (issue 30; docs/matting.md "Sensor noise behind the object").

The path-traced rooms of scripts/hardcases.py have none behind the object: the room is a visible
environment map, which a camera ray reads without Monte Carlo noise, so the room's pixels differ between
frames only by the auto exposure's rounding (0.4 sRGB steps).  A real camera's frames differ by their
noise everywhere, and the room path (plate, matte, the colour across the views) reads the background in
every frame.

    PYTHONPATH=. .venv/bin/python scripts/add_sensor_noise.py CAPTURE OUT --sigma 1.5 [--frames 0::2] [--seed 0]

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


def main(argv=None) -> Path:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("capture", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--sigma", type=float, required=True, help="noise in 8-bit sRGB steps (e.g. 1.5)")
    p.add_argument("--frames", default="0::2",
                   help="the frames given noise, as furrow's --frames (default 0::2: the kept)")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
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
        write_png(d, noisy(rgb, a.sigma, np.random.default_rng(a.seed * 100_003 + i)))
    print(a.out)
    return a.out


if __name__ == "__main__":
    main()
