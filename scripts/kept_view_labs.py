"""Three render-side measurements of a room capture's kept views (issue 30, stop 63; docs/matting.md "Three ways
to use the kept views' errors, measured"): none became a method.

Renders the held-out views with gather's numpy twin (render/gather/reference.py; the GL path's digits) from a model of
the kept views, changed one way at a time, and scores them as ``furrow eval`` does (scripts/ssim_split.py: masked PSNR
/ SSIM / sharpness, over white, alpha MSE):

* ``confidence``: gather's blend weight of each kept view times a per-pixel confidence (resampled as its colour):
  ``oracle-alpha`` 1 / (1 + (a - a_true)^2 / 0.05^2), ``oracle-premult`` 1 / (1 + |a F - C_black|^2 / 0.01^2) (both
  read the truth), ``photo-clipped`` EPS where the photo is clipped in every channel and alpha < 1, ``blown`` EPS where
  the photo or plate is clipped (the class map of scripts/matte_error_classes.py), ``blown-unknown`` also where B is
  unknown; 1 elsewhere.
* ``shift D``: where B is known (classes seen / lines) alpha lowered by D (ramped in from alpha 0.3 to 0.5), the
  premultiplied colour by D B with it (a F = C - (1 - a) B): the kept views' alpha is biased high there.
* ``decorrelate R``: the premultiplied colour made uncorrelated with B in windows of radius R (REG regularises the
  slope): a F = t + d B with t the object's own colour, d the alpha error.

    furrow model CAP --frames 0::2 -o MODEL                                      (CAP: scripts/hide_mattes.py of ROOM)
    PYTHONPATH=. python scripts/matte_error_classes.py ROOM BLACK CLASSES       (the class maps and plates)
    PYTHONPATH=. python scripts/kept_view_labs.py ROOM BLACK MODEL CLASSES confidence|shift|decorrelate [ARG ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter

sys.path.insert(0, str(Path(__file__).parent))
from ssim_split import _arrays, score

from capture.io import read_scanset
from render.gather import reference as g
from render.points import reference as pr

KEYS = ("psnr_masked", "ssim_masked", "sharpness", "psnr_white", "alpha_mse")
#: The clip level of capture.matting_known (linear, 8-bit sRGB 252).
CLIP = 0.975


def confident_frame(eye, model, centre, conf, cfg):
    """gather_frame (measured depth first) with each blend view's weight times its resampled ``conf`` (V, H, W)."""
    cams, rgb, depth, alpha, measured = model
    idx, ang = pr.nearest_views(eye, cams, centre, max(cfg.k_depth, cfg.k_blend))
    dv = idx[: cfg.k_depth]
    m, d = np.asarray(measured, bool)[dv], np.asarray(depth)[dv]
    cs = [cams[i] for i in dv]
    z, _ = g.measured_first_depth(eye, pr.back_project(cs, rgb[dv], np.where(m, d, 0)),
                                  pr.back_project(cs, rgb[dv], np.where(m, 0, d)), cfg.splat_px)
    px = z > 0
    X = eye.unproject(eye.pixel_grid()[px], z[px])
    acc, wsum = np.zeros((len(X), 4)), np.zeros(len(X))
    for i, w in zip(idx[: cfg.k_blend], 1.0 / np.maximum(ang[: cfg.k_blend], pr.ANGLE_EPS)):
        tex = np.concatenate([g.premultiply(rgb[i], alpha[i]), conf[i][..., None]], -1)
        col, dd, zz, inside = g.sample_view(cams[i], tex, depth[i], X, cfg.resample)
        v = w * g.visibility(dd, zz, inside, cfg.vis_sigma_m, cfg.vis_floor) * col[:, 4]
        acc += v[:, None] * col[:, :4]
        wsum += v
    blend = np.where((wsum > 0)[:, None], acc / np.where(wsum > 0, wsum, 1.0)[:, None], 0.0)
    out, a = np.zeros(z.shape + (3,)), np.zeros(z.shape)
    out[px], a[px] = blend[:, :3], np.minimum(blend[:, 3], 1.0)
    return out, a


def scores(room, model, centre, conf=None) -> dict:
    """Mean scores of the held-out (odd) views rendered from ``model`` (with ``conf``: :func:`confident_frame`)."""
    cfg, recs = g.GatherConfig(), []
    for h in range(1, len(room), 2):
        eye = room[h].camera
        col, a = (g.gather_frame(eye, None, *model[:3], centre, cfg, *model[3:])[:2] if conf is None
                  else confident_frame(eye, model, centre, conf, cfg))
        recs.append(score(room[h], col, a))
    return {k: float(np.nanmean([r[k] for r in recs])) for k in KEYS}


def confidences(kind: str, model, truth, photo, cls, eps: float) -> np.ndarray:
    """(V, H, W) float32 confidence of the kept views (module docstring)."""
    rgb, al = model[1], model[3]
    a_true, c_black = truth
    band = al < 0.999
    if kind == "oracle-alpha":
        c = 1.0 / (1.0 + ((al - a_true) / 0.05) ** 2)
    elif kind == "oracle-premult":
        c = 1.0 / (1.0 + ((rgb * al[..., None] - c_black) ** 2).sum(-1) / 0.01 ** 2)
    else:
        low = {"photo-clipped": photo.min(-1) >= CLIP, "blown": cls == 2,
               "blown-unknown": (cls == 2) | (cls == 3)}[kind]
        c = np.where(band & low, eps, 1.0)
    return c.astype(np.float32)


def shifted(model, cls, plate, d: float):
    """The model with alpha lowered by ``d`` where B is known (module docstring) and a F by the same times B."""
    cams, rgb, dep, al, meas = model
    sel = ((cls == 0) | (cls == 1)) & (al >= 0.3) & (al < 1)
    a2 = np.where(sel, np.clip(al - d * np.clip((al - 0.3) / 0.2, 0, 1), 0, 1), al)
    return _with_premult(model, np.clip(rgb * al[..., None] - (al - a2)[..., None] * plate, 0, None), a2)


def decorrelated(model, cls, plate, r: int, reg: float):
    """The model with each view's partial known-B pixels' a F made uncorrelated with B in windows of radius ``r``."""
    rgb, al = model[1], model[3]
    a2, pm2 = al.astype(np.float64).copy(), rgb * al[..., None].astype(np.float64)
    for v in range(len(al)):
        m = (((cls[v] == 0) | (cls[v] == 1)) & (al[v] > 0) & (al[v] < 1)).astype(np.float64)
        n = uniform_filter(m, 2 * r + 1) + 1e-12

        def mean(x, m=m, n=n):
            return uniform_filter(x * m, 2 * r + 1) / n

        cov = sum(mean(pm2[v, ..., c] * plate[v, ..., c]) - mean(pm2[v, ..., c]) * mean(plate[v, ..., c])
                  for c in range(3))
        var = sum(mean(plate[v, ..., c] ** 2) - mean(plate[v, ..., c]) ** 2 for c in range(3))
        d = np.where((m > 0) & (n > 0.3), np.clip(cov / (var + reg), -0.3, 0.3), 0.0)
        a2[v] = np.clip(al[v] - d, 0, 1)
        pm2[v] = np.clip(pm2[v] - d[..., None] * plate[v], 0, None)
    return _with_premult(model, pm2, a2)


def _with_premult(model, pm, a):
    cams, rgb, dep, _, meas = model
    straight = np.where(a[..., None] > 0, pm / np.maximum(a, 1e-6)[..., None], rgb)
    return cams, straight.astype(np.float32), dep, a.astype(np.float32), meas


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    for name in ("room", "black", "model", "classes"):
        ap.add_argument(name)
    ap.add_argument("lab", choices=("confidence", "shift", "decorrelate"))
    ap.add_argument("args", nargs="*", help="confidence: kinds; shift: D values; decorrelate: radii")
    ap.add_argument("--eps", type=float, default=0.1, help="the low confidence (confidence lab)")
    ap.add_argument("--reg", type=float, default=1e-2, help="the slope's regulariser (decorrelate lab)")
    a = ap.parse_args()
    room = read_scanset(a.room).scans
    kept = range(0, len(room), 2)
    model = _arrays(a.model)
    dumps = [np.load(Path(a.classes) / f"{k:02d}.npz") for k in range(len(kept))]
    cls = np.stack([d["cls"] for d in dumps])
    plate = np.stack([d["plate"].astype(np.float64) for d in dumps])
    centre = np.concatenate([c.depth_to_points(d)[0] for c, d in zip(model[0], model[2])]).mean(0)
    print(f"{'as modelled':24s} " + " / ".join(f"{v:.4f}" for v in scores(room, model, centre).values()), flush=True)
    if a.lab == "confidence":
        black = read_scanset(a.black).scans
        truth = (np.stack([np.asarray(room[i].alpha, np.float32) for i in kept]),
                 np.stack([black[i].linear_rgb for i in kept]))
        photo = np.stack([room[i].linear_rgb for i in kept])
        runs = [(k, model, confidences(k, model, truth, photo, cls, a.eps)) for k in a.args]
    elif a.lab == "shift":
        runs = [(f"shift {d}", shifted(model, cls, plate, float(d)), None) for d in a.args]
    else:
        runs = [(f"decorrelate r {r}", decorrelated(model, cls, plate, int(r), a.reg), None) for r in a.args]
    for name, m, conf in runs:
        print(f"{name:24s} " + " / ".join(f"{v:.4f}" for v in scores(room, m, centre, conf).values()), flush=True)


if __name__ == "__main__":
    main()
