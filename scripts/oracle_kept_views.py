"""Which part of the kept views' matte limits held-out quality (docs/matting.md "Where the rest of the gap lies"):
a model's RGBz with its kept views' alpha and / or colour replaced by the truth (the capture's true mattes, the
black twin's colour), rendered with gather at the held-out cameras (`furrow render --frames 1::2`) and scored as
`furrow eval` scores (masked PSNR / SSIM / sharpness over black; through the 8-bit PNGs `furrow render` writes).

    furrow model CAP_WITH_HIDDEN_MATTES --frames 0::2 -o M
    PYTHONPATH=. .venv/bin/python scripts/oracle_kept_views.py M ROOM_CAPTURE BLACK_TWIN OUT

ROOM_CAPTURE holds the true mattes (mask_path) and the held-out references (frames 1::2, over black); BLACK_TWIN
the same views over black (its colour is the true premultiplied colour).  A measurement, not a method.
"""
from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np
from scipy.ndimage import gaussian_filter

from render import metrics
from volume.model import load_model, save_model
from volume.rgbz_store import RgbzImages

#: The partial pixels: true alpha in (PARTIAL_LO, OPAQUE); opaque: at least OPAQUE.
PARTIAL_LO, OPAQUE = 0.02, 0.9
#: Scale (pixels) of the low-passed error.
LOW_SIGMA = 4.0
#: Bands of the model's alpha for the per-band true gain (docs/matting.md "Other rooms behind the conifer").
ALPHA_BANDS = (0.02, 0.1, 0.2, 0.3, 0.5, 0.7, 0.85, 0.999)


def _lin(x: np.ndarray) -> np.ndarray:
    x = x.astype(np.float64) / (65535 if x.dtype == np.uint16 else 255)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _matte(path: str) -> np.ndarray:
    t = iio.imread(path)
    t = t.astype(np.float64) / (65535 if t.dtype == np.uint16 else 255)
    return t[..., 0] if t.ndim == 3 else t


def _straight(p: np.ndarray, a: np.ndarray) -> np.ndarray:
    return np.where(a[..., None] > 1e-3, np.clip(p / np.maximum(a[..., None], 1e-3), 0, 1), 0).astype(np.float32)


def variants(rgb, al, ta, tp) -> dict:
    """The RGBz colour and alpha of each variant (module docstring)."""
    pm = rgb * al[..., None]
    part = ((ta > PARTIAL_LO) & (ta < OPAQUE))[..., None]
    opq = (ta >= OPAQUE)[..., None]
    err = np.where(part, tp - pm, 0).astype(np.float32)
    w = gaussian_filter(part[..., 0].astype(np.float32), (0, LOW_SIGMA, LOW_SIGMA))
    low = np.stack([gaussian_filter(err[..., j], (0, LOW_SIGMA, LOW_SIGMA)) for j in range(3)], -1)
    low /= np.maximum(w, 1e-3)[..., None]
    pb = part[..., 0]
    gain = np.array([tp[..., j][pb].sum() / max(pm[..., j][pb].sum(), 1e-12) for j in range(3)])
    band_gain = np.ones_like(pm)
    for lo, hi in zip(ALPHA_BANDS[:-1], ALPHA_BANDS[1:]):
        b = (al >= lo) & (al < hi)
        band_gain[b] = [tp[..., j][b].sum() / max(pm[..., j][b].sum(), 1e-12) for j in range(3)]
    return {"as built": (rgb, al), "true alpha and colour": (_straight(tp, ta), ta),
            "true alpha, its premultiplied colour": (_straight(pm, ta), ta),
            "its alpha, the true premultiplied colour": (_straight(tp, al), al),
            "true colour at the partial pixels": (_straight(np.where(part, tp, pm), al), al),
            "true colour at the opaque pixels": (_straight(np.where(opq, tp, pm), al), al),
            "partial pixels' low-passed error taken out": (_straight(np.where(part, pm + low, pm), al), al),
            f"partial pixels times {np.round(gain, 3).tolist()}": (_straight(np.where(part, pm * gain, pm), al), al),
            "a true gain per band of the model's alpha": (_straight(pm * band_gain, al), al),
            "its alpha and colour, none where the true alpha is 0": (rgb, np.where(ta > 0, al, 0).astype(np.float32))}


def main(argv=None) -> int:
    model_dir, room, black, out = (Path(a) for a in (argv or sys.argv[1:])[:4])
    m = load_model(model_dir)
    frames = json.loads((room / "transforms.json").read_text())["frames"]
    kept, held = frames[0::2], frames[1::2]
    views = [m.rgbz.view(n) for n in range(len(m.rgbz))]
    rgb, dep, al = (np.stack([np.asarray(v[i], np.float32) for v in views]) for i in range(3))
    ta = np.stack([_matte(str(room / f["mask_path"])) for f in kept]).astype(np.float32)
    tp = np.stack([_lin(iio.imread(black / f["file_path"]))[..., :3] for f in kept]).astype(np.float32)
    out.mkdir(parents=True, exist_ok=True)
    for k, (name, (c, a)) in enumerate(variants(rgb, al, ta, tp).items()):
        md, rdir = out / f"m{k}", out / f"r{k}"
        subprocess.run(["rm", "-rf", str(md)], check=True)
        save_model(dataclasses.replace(m, rgbz=RgbzImages(c, dep, m.rgbz.cameras, a)), md)
        subprocess.run([sys.executable, "-m", "furrow", "render", str(md), "--cameras", str(room / "transforms.json"),
                        "--frames", "1::2", "-o", str(rdir)], check=True, capture_output=True)
        sc = []
        for f in held:
            ref = iio.imread(room / f["file_path"])[..., :3]
            r = iio.imread(rdir / Path(f["file_path"]).name)
            prem = (_lin(r[..., :3]) * (r[..., 3:4].astype(np.float64) / 255)).astype(np.float32)
            sc.append(metrics.compare(ref, metrics.as_srgb8(prem), metrics.foreground(ref)))
        print(f"{name}: " + " / ".join(f"{np.mean([s[x] for s in sc]):.4f}"
                                       for x in ("psnr_masked", "ssim_masked", "sharpness")), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
