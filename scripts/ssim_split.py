"""Which of alpha, colour or neither carries a room capture's held-out SSIM / PSNR gap to its black twin
(issue 30, tenth round)?

Renders the held-out views with gather's numpy twin (render/gather/reference.py, the GL path's digits) from
the kept views' RGBz of a model, with the kept views' alpha and / or straight colour swapped for the truth:
the true matte (the room capture's ``mask_path``) and the true colour F = C_black / a_true from the black twin's
photo (where a_true >= TRUE_COLOUR_ALPHA; the model's colour elsewhere).  Scores as ``furrow eval``: masked PSNR /
SSIM / sharpness, over white and the alpha MSE (render.evaluate.composite_scores), and the SSIM's three terms
(luminance, contrast, structure; grey, 7 x 7 box) inside the scored region split by the held-out true alpha.

    furrow model CAP --frames 0::2 -o MODEL            (CAP: scripts/hide_mattes.py of ROOM)
    furrow model ROOM --frames 0::2 -o TRUE_MODEL      (the kept views' true mattes given)
    PYTHONPATH=. python scripts/ssim_split.py ROOM BLACK MODEL [TRUE_MODEL] [--black-model M] [--pictures DIR]

``--pictures DIR`` writes, for the first held-out view, the reference, the renders and their SSIM maps.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter

from capture.io import read_scanset
from render import metrics
from render.evaluate import COMPOSITE_BACKDROPS, reference_foreground
from render.gather import reference as g

#: The true colour C_black / a_true is used where the true matte is at least this (the photo's 8 bits and
#: noise divided by a smaller alpha are worse than the model's colour).
TRUE_COLOUR_ALPHA = 0.1

#: The held-out true alpha's classes for the SSIM split: (name, low, high).
ALPHA_CLASSES = (("a<0.1", -1.0, 0.1), ("0.1-0.5", 0.1, 0.5), ("0.5-0.85", 0.5, 0.85), (">=0.85", 0.85, 2.0))


def _arrays(model_dir):
    from volume.model import load_model

    r = load_model(model_dir).rgbz
    return (list(r.cameras), np.asarray(r.rgb, np.float32), np.asarray(r.depth, np.float32),
            np.asarray(r.alpha, np.float32), r.measured)


def ssim_terms(a8: np.ndarray, b8: np.ndarray) -> np.ndarray:
    """(3, H, W) luminance, contrast and structure terms of SSIM on the grey images (7 x 7 box window)."""
    x, y = metrics.grey(a8), metrics.grey(b8)
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    mx, my = uniform_filter(x, 7), uniform_filter(y, 7)
    vx = np.maximum(uniform_filter(x * x, 7) - mx * mx, 0)
    vy = np.maximum(uniform_filter(y * y, 7) - my * my, 0)
    cxy = uniform_filter(x * y, 7) - mx * my
    sx, sy = np.sqrt(vx), np.sqrt(vy)
    lum = (2 * mx * my + c1) / (mx * mx + my * my + c1)
    con = (2 * sx * sy + c2) / (vx + vy + c2)
    st = (cxy + c2 / 2) / (sx * sy + c2 / 2)
    return np.stack([lum, con, st])


def score(scan, col, a) -> dict:
    """furrow eval's scores of one premultiplied frame (col, a) against the held-out scan, plus the split."""
    ref = scan.srgb8
    out8 = metrics.as_srgb8(col)
    fg = metrics.foreground(ref, reference_foreground(scan))
    s = metrics.compare(ref, out8, fg)
    union = fg | metrics.foreground(out8)
    true_a = np.asarray(scan.alpha, np.float64)
    region = (true_a > 0) | fg | (a > 0)
    from capture.scan import srgb_to_linear

    B = float(srgb_to_linear(np.float64(COMPOSITE_BACKDROPS["white"] / 255.0)))
    want = scan.linear_rgb.astype(np.float64) + (1.0 - true_a)[..., None] * B
    got = col.astype(np.float64) + (1.0 - a)[..., None] * B
    s["psnr_white"] = metrics.psnr(np.clip(want, 0, None), np.clip(got, 0, None), region)
    s["alpha_mse"] = float(np.mean((a - true_a)[region] ** 2))
    terms = ssim_terms(ref, out8)
    n = union.sum()
    for name, lo, hi in ALPHA_CLASSES:
        m = union & (true_a >= lo) & (true_a < hi)
        s[f"share {name}"] = m.sum() / n
        for t, tn in zip(terms, ("lum", "con", "str"), strict=True):
            s[f"{tn} {name}"] = float(t[m].mean()) if m.any() else np.nan
    return s


def render_all(scans, held, cams, rgb, depth, alpha, measured):
    centre = np.concatenate([c.depth_to_points(d)[0] for c, d in zip(cams, depth)]).mean(0)
    for h in held:
        col, a, _, _ = g.gather_frame(scans[h].camera, None, cams, rgb, depth, centre, g.GatherConfig(), alpha,
                                      measured)
        yield h, col, a


def true_colour_alpha(room, black, kept, rgb):
    """The kept views' true matte (V, H, W) and true straight colour (model's where a_true is small)."""
    at = np.stack([np.asarray(room[i].alpha, np.float32) for i in kept])
    cb = np.stack([black[i].linear_rgb.astype(np.float32) for i in kept])
    ok = at >= TRUE_COLOUR_ALPHA
    ft = np.where(ok[..., None], cb / np.maximum(at, 1e-6)[..., None], rgb)
    return at, np.clip(ft, 0, 1).astype(np.float32)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("room")
    ap.add_argument("black")
    ap.add_argument("model")
    ap.add_argument("true_model", nargs="?")
    ap.add_argument("--black-model")
    ap.add_argument("--pictures", type=Path)
    ap.add_argument("--classes", action="store_true", help="the truth (alpha and colour) in one true-alpha class "
                                                              "of the kept views at a time")
    a = ap.parse_args()
    room, black = read_scanset(a.room).scans, read_scanset(a.black).scans
    held = [i for i in range(len(room)) if i % 2]
    kept = [i for i in range(len(room)) if i % 2 == 0]
    cams, rgb, dep, al, meas = _arrays(a.model)
    at, ft = true_colour_alpha(room, black, kept, rgb)
    runs = [("default", (cams, rgb, dep, al, meas)), ("true alpha", (cams, rgb, dep, at, meas)),
            ("true colour", (cams, ft, dep, al, meas)), ("true colour + alpha", (cams, ft, dep, at, meas))]
    if a.true_model:
        c2, rgb2, dep2, al2, meas2 = _arrays(a.true_model)
        runs += [("pipeline given true matte", (c2, rgb2, dep2, al2, meas2)),
                 ("  + true colour", (c2, true_colour_alpha(room, black, kept, rgb2)[1], dep2, al2, meas2))]
    if a.classes:
        runs = runs[:1] + list(_class_runs(room, black, kept, (cams, rgb, dep, al, meas)))
    if a.black_model:
        runs.append(("black twin model", _arrays(a.black_model)))
    keys = ("psnr_masked", "ssim_masked", "sharpness", "psnr_white", "alpha_mse")
    for name, arr in runs:
        recs = []
        for h, col, alpha in render_all(room, held, *arr):
            recs.append(score(room[h], col, alpha))
            if a.pictures and h == held[0]:
                _pictures(a.pictures, name, room[h], col)
        m = {k: float(np.nanmean([r[k] for r in recs])) for k in recs[0]}
        print(f"{name:28s} " + " / ".join(f"{m[k]:.4f}" for k in keys), flush=True)
        print("    " + "  ".join(f"{c[0]} {m['share ' + c[0]]:.2f}: l {m['lum ' + c[0]]:.3f} c {m['con ' + c[0]]:.3f} "
                                 f"s {m['str ' + c[0]]:.3f}" for c in ALPHA_CLASSES), flush=True)


def _class_runs(room, black, kept, arr):
    """The model ``arr`` with the truth, a_true and C_black / a_true, in one ALPHA_CLASSES class at a time."""
    cams, rgb, dep, al, meas = arr
    at = np.stack([np.asarray(room[i].alpha, np.float32) for i in kept])
    cb = np.stack([black[i].linear_rgb.astype(np.float32) for i in kept])
    ft = cb / np.maximum(at, 1e-3)[..., None]
    for name, lo, hi in ALPHA_CLASSES:
        m = (at >= lo) & (at < hi)
        yield (f"truth at a_true {name}", (cams, np.where(m[..., None], ft, rgb), dep, np.where(m, at, al), meas))


def _pictures(out: Path, name: str, scan, col) -> None:
    import imageio.v3 as iio
    from skimage.metrics import structural_similarity

    out.mkdir(parents=True, exist_ok=True)
    ref, r8 = scan.srgb8, metrics.as_srgb8(col)
    _, smap = structural_similarity(ref, r8, channel_axis=-1, data_range=255, win_size=7, full=True)
    tag = name.strip().replace(" ", "_").replace("+", "and")
    iio.imwrite(out / "reference.png", ref)
    iio.imwrite(out / f"{tag}.png", r8)
    iio.imwrite(out / f"{tag}_ssim.png", (np.clip(smap.mean(-1), 0, 1) * 255).astype(np.uint8))


if __name__ == "__main__":
    main()
