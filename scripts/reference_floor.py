"""How far a lens + auto-exposure capture's own held-out references lie from its black twin's (docs/matting.md,
"That miss is the capture's own noise"): each held-out reference (frames 1::2) undistorted with the capture's
OPENCV coefficients (cv2.undistort, in linear light), its true gain (gt/exposure.json) taken out, scored against
the twin's reference of the same view as `furrow eval` scores (masked PSNR / SSIM).  A floor under any render
scored against these references.

    PYTHONPATH=. .venv/bin/python scripts/reference_floor.py CAPTURE TWIN
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import cv2
import imageio.v3 as iio
import numpy as np

from capture.scan import srgb_to_linear, to_uint8_srgb
from render import metrics


def main(argv=None) -> int:
    cap, twin = (Path(a) for a in (argv or sys.argv[1:])[:2])
    d = json.loads((cap / "transforms.json").read_text())
    gains = {v["name"]: np.array(v["gain"]) for v in json.loads((cap / "gt/exposure.json").read_text())["views"]}
    f0 = d["frames"][0]
    K = np.array([[f0["fl_x"], 0, f0["cx"]], [0, f0["fl_y"], f0["cy"]], [0, 0, 1.0]])
    D = np.array([d.get(k, 0.0) for k in ("k1", "k2", "p1", "p2", "k3")])
    scores = []
    for f in d["frames"][1::2]:
        photo = srgb_to_linear(iio.imread(cap / f["file_path"])[..., :3].astype(np.float32) / 255.0)
        ref = iio.imread(twin / f["file_path"])[..., :3]
        flat = cv2.undistort(np.ascontiguousarray(photo, np.float32), K, D) / gains[Path(f["file_path"]).name]
        scores.append(metrics.compare(ref, to_uint8_srgb(np.clip(flat, 0, 1)), metrics.foreground(ref)))
    print(f"{cap}: its references against {twin}'s: masked PSNR {np.mean([s['psnr_masked'] for s in scores]):.2f}, "
          f"SSIM {np.mean([s['ssim_masked'] for s in scores]):.3f} ({len(scores)} views)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
