"""An environment map with a room's texture at the pixel scale: a bundled map (or an .exr) upsampled and multiplied
by a per-texel grain, for `scripts/hardcases.py --room-map NAME --env-dir DIR` (issue 30; docs/matting.md, "A
room's texture is not noise").

The bundled maps are 1024 x 512: a texel covers about 5.6 pixels of a 640 x 480 frame at the hard cases' field of
view, so their rooms are smooth at the pixel scale and the frames' noise measures 0.00.  At --width 4096 a texel is
about 1.4 pixels, and --grain 0.4 (a normal of that standard deviation, the factor clipped to 0.2-2) gives the frames
about 2.1 8-bit steps of fine detail with no noise at all (stop 61's grainyard40).

    PYTHONPATH=. .venv/bin/python scripts/grainy_map.py courtyard DIR/grainyard40.exr --grain 0.4
    scripts/hardcases.py conifer_room_orbit --room-map grainyard40 --env-dir DIR --seed 13 --room-rotation 180 -o OUT
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

#: The grain's factor is clipped to this range (no negative or blown-out texels).
GRAIN_CLIP = (0.2, 2.0)


def grainy(data: np.ndarray, width: int, grain: float, seed: int) -> np.ndarray:
    """(width / 2, width, 3) float32: ``data`` (H, 2H, 3) linear, bilinearly resized, times a per-texel grey grain."""
    import cv2

    big = cv2.resize(np.asarray(data, np.float32), (width, width // 2), interpolation=cv2.INTER_LINEAR)
    g = np.random.default_rng(seed).standard_normal(big.shape[:2]).astype(np.float32)
    return np.maximum(big * np.clip(1 + grain * g, *GRAIN_CLIP)[..., None], 0).astype(np.float32)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("map", help="a bundled map name (courtyard, forest, studio, sunset) or an equirect .exr / .hdr")
    ap.add_argument("out", type=Path, help="the .exr to write (its stem is the --room-map name)")
    ap.add_argument("--width", type=int, default=4096, help="width of the map written (default 4096)")
    ap.add_argument("--grain", type=float, default=0.4, help="the grain's standard deviation (default 0.4)")
    ap.add_argument("--seed", type=int, default=11, help="seed of the grain (default 11)")
    a = ap.parse_args()
    from capture.imageio import write_exr
    from render.shading.envmap import named_envmap

    if a.width < 2 or a.width % 2:
        ap.error(f"--width must be an even number of texels, got {a.width}")
    data = grainy(named_envmap(a.map).data, a.width, a.grain, a.seed)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = a.out.with_name(a.out.stem + ".tmp.exr")
    write_exr(tmp, data)
    os.replace(tmp, a.out)  # written whole, then renamed
    print(f"wrote {a.out} ({a.width}x{a.width // 2}, grain {a.grain})")


if __name__ == "__main__":
    main()
