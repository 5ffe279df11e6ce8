"""``furrow bench synth_realism SCANS... [--eval DIR...]``: statistics of captures, to set our
synthetic data beside the unseen path-traced ones (issues 11, 15, 16).

Per scan set, with the frames i % 2 == 0 kept and the others held out (as ``furrow eval
--holdout 2``):

* ``fg``: foreground fraction of the image; ``fg_luma``: mean 8-bit sRGB luma on it;
  ``sharp``: RMS of the Laplacian of the grey image inside the foreground (8-bit units);
* ``depth_cover``: fraction of colour-foreground pixels with a depth measurement (1 - holes);
* ``miss@1/2/4``: the strand-exact reprojection statistic of issue 11: each held-out pixel's own
  depth, looked up in the 1 / 2 / 4 kept views nearest in viewing angle with a strict 4 mm
  visibility test, finds no visible match (unseen captures: fur ball 60/39/23 %, conifer
  48/31/21 %);
* ``points``: the plain RGB-D point splatter of issue 11 (back-project every kept pixel; for a
  held-out view take the 4 kept cameras nearest in viewing angle, z-buffer their points in 2 x 2
  splats, average the colours within 4 mm of the front, weighted by 1 / angle): masked PSNR,
  masked SSIM and the sharpness ratio (RMS Laplacian of the rendering over the reference's,
  inside the union of foregrounds).  Unseen captures: fur ball 20.50 dB / 0.43 / 1.26, conifer
  23.55 / 0.61 / 1.44, furry bunny 20.43 / 0.49 / 1.41.
* with ``--eval FILE`` (one per scan set: the ``furrow eval --json`` file): its microfacet masked
  PSNR / SSIM / hole fraction beside these; with ``--sheets DIR`` (the ``furrow eval -o DIR``
  folder): the microfacet sharpness ratio from its side-by-side sheets (reference | microfacet |
  baseline | error).

This numpy splatter is here to measure data, not to render; the renderer's ``points`` method is
the product's.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

#: Visibility tolerance of the reprojection statistic and of the splatter (issue 11: 4 mm).
VIS_TOL_M = 0.004
#: Kept cameras used by the splatter, and the neighbour counts of the reprojection statistic.
SPLAT_VIEWS = 4
MISS_VIEWS = (1, 2, 4)
#: Splat footprint (pixels per side).
SPLAT_PX = 2


def _grey(img8: np.ndarray) -> np.ndarray:
    return img8.astype(np.float64) @ np.array([0.299, 0.587, 0.114])


def laplacian_rms(img8: np.ndarray, mask: np.ndarray) -> float:
    """RMS of the Laplacian of the grey image (8-bit units) over ``mask``."""
    from scipy import ndimage

    lap = ndimage.laplace(_grey(img8))
    return float(np.sqrt(np.mean(lap[mask] ** 2))) if mask.any() else float("nan")


def _view_dir(cam, centre) -> np.ndarray:
    d = cam.center - centre
    return d / np.linalg.norm(d)


def _nearest(target, kept, centre, k):
    """Indices into ``kept`` of the k cameras nearest in viewing angle, and the angles (rad)."""
    t = _view_dir(target, centre)
    ang = np.array([np.arccos(np.clip(t @ _view_dir(c, centre), -1, 1)) for c in kept])
    order = np.argsort(ang)[:k]
    return order, ang[order]


def miss_fractions(held, kept_scans, centre) -> dict:
    """Fraction of the held-out view's depth pixels with no visible match in the n nearest kept views."""
    pts, _ = held.camera.depth_to_points(held.depth)
    out = {}
    order, _ = _nearest(held.camera, [s.camera for s in kept_scans], centre, max(MISS_VIEWS))
    seen = np.zeros(len(pts), bool)
    for n, j in enumerate(order, 1):
        s = kept_scans[j]
        uv, z = s.camera.project(pts)
        ij = np.round(uv).astype(np.int64)
        ok = (z > 0) & (ij[:, 0] >= 0) & (ij[:, 1] >= 0) & (ij[:, 0] < s.camera.width) & (ij[:, 1] < s.camera.height)
        d = np.zeros(len(pts))
        d[ok] = s.depth[ij[ok, 1], ij[ok, 0]]
        seen |= ok & (d > 0) & (np.abs(d - z) < VIS_TOL_M)
        if n in MISS_VIEWS:
            out[f"miss@{n}"] = float(1 - seen.mean()) if len(pts) else float("nan")
    return out


def splat(target, kept_scans, centre) -> np.ndarray:
    """(H, W, 3) float64 linear colour of the point splatter (module docstring) for ``target``."""
    order, ang = _nearest(target, [s.camera for s in kept_scans], centre, SPLAT_VIEWS)
    W, H = target.width, target.height
    P, C, Wt = [], [], []
    for j, a in zip(order, ang):
        s = kept_scans[j]
        p, m = s.camera.depth_to_points(s.depth)
        P.append(p)
        C.append(s.linear_rgb[m])
        Wt.append(np.full(len(p), 1.0 / max(a, 1e-3)))
    P, C, Wt = np.concatenate(P), np.concatenate(C), np.concatenate(Wt)
    uv, z = target.project(P)
    x0 = np.floor(uv[:, 0] - 0.5 * (SPLAT_PX - 1)).astype(np.int64)
    y0 = np.floor(uv[:, 1] - 0.5 * (SPLAT_PX - 1)).astype(np.int64)
    pix, zz, cc, ww = [], [], [], []
    for dy in range(SPLAT_PX):
        for dx in range(SPLAT_PX):
            x, y = x0 + dx, y0 + dy
            ok = (z > 0) & (x >= 0) & (y >= 0) & (x < W) & (y < H)
            pix.append(y[ok] * W + x[ok])
            zz.append(z[ok])
            cc.append(C[ok])
            ww.append(Wt[ok])
    pix, zz, cc, ww = (np.concatenate(a) for a in (pix, zz, cc, ww))
    front = np.full(H * W, np.inf)
    np.minimum.at(front, pix, zz)
    near = zz < front[pix] + VIS_TOL_M
    wsum = np.bincount(pix[near], ww[near], H * W)
    out = np.stack([np.bincount(pix[near], ww[near] * cc[near, k], H * W) for k in range(3)], 1)
    out = np.where(wsum[:, None] > 0, out / np.maximum(wsum[:, None], 1e-300), 0.0)
    return out.reshape(H, W, 3)


def capture_stats(path: Path) -> dict:
    from capture.io import read_scanset
    from capture.scan import to_uint8_srgb
    from render.metrics import as_srgb8, foreground, psnr, ssim

    ss = read_scanset(path)
    kept = [s for i, s in enumerate(ss.scans) if i % 2 == 0]
    held = [s for i, s in enumerate(ss.scans) if i % 2 == 1]
    centre = 0.5 * (ss.bounds[0] + ss.bounds[1])
    rows = []
    for h in held:
        ref8 = as_srgb8(h.rgb)
        fg = foreground(ref8)
        row = {"fg": float(fg.mean()), "fg_luma": float(_grey(ref8)[fg].mean()), "sharp": laplacian_rms(ref8, fg),
               "depth_cover": float((h.depth[fg] > 0).mean())}
        row.update(miss_fractions(h, kept, centre))
        pred = to_uint8_srgb(splat(h.camera, kept, centre))
        union = fg | foreground(pred)
        row.update(points_psnr=psnr(ref8, pred, union), points_ssim=ssim(ref8, pred, union),
                   points_sharp_ratio=laplacian_rms(pred, union) / laplacian_rms(ref8, union))
        rows.append(row)
    return {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}


def sheet_sharpness(folder: Path) -> dict:
    """Mean sharpness ratio of the microfacet and baseline panels of ``furrow eval``'s side-by-side
    sheets (4 panels of equal width) against the reference panel, inside the union of foregrounds."""
    import cv2

    from render.metrics import foreground

    ratios = {"microfacet_sharp_ratio": [], "vdtm_sharp_ratio": []}
    for f in sorted((Path(folder) / "side_by_side").glob("*.png")):
        im = cv2.imread(str(f))[..., ::-1]
        w = im.shape[1] // 4
        ref, mf, base = im[:, :w], im[:, w:2 * w], im[:, 2 * w:3 * w]
        for key, pred in (("microfacet_sharp_ratio", mf), ("vdtm_sharp_ratio", base)):
            union = foreground(ref) | foreground(pred)
            ratios[key].append(laplacian_rms(pred, union) / laplacian_rms(ref, union))
    return {k: float(np.mean(v)) for k, v in ratios.items() if v}


def _eval_numbers(p: Path) -> dict:
    if not p.is_file():
        return {}
    e = json.loads(p.read_text())
    mf = e.get("microfacet", {})
    return {"microfacet_psnr": mf.get("psnr_masked"), "microfacet_ssim": mf.get("ssim_masked"),
            "microfacet_holes": mf.get("hole_fraction")}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="furrow bench synth_realism", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scans", nargs="*", type=Path, help="scan sets (transforms.json folders)")
    ap.add_argument("--eval", nargs="*", type=Path, default=[], help="furrow eval JSON per scan set (same order)")
    ap.add_argument("--sheets", nargs="*", type=Path, default=[], help="furrow eval -o folder per scan set (same order)")
    ap.add_argument("--json", type=Path, default=None, help="write the table as JSON")
    args = ap.parse_args(argv)
    if not args.scans:
        print("synth_realism: nothing to measure (give scan sets, e.g. from furrow synth)")
        return 0
    table = {}
    for i, p in enumerate(args.scans):
        st = capture_stats(p)
        if i < len(args.eval):
            st.update(_eval_numbers(args.eval[i]))
        if i < len(args.sheets):
            st.update(sheet_sharpness(args.sheets[i]))
        table[str(p)] = st
    keys = list(next(iter(table.values())).keys())
    print("capture".ljust(34) + "".join(k[:12].rjust(13) for k in keys))
    for name, st in table.items():
        print(name[-34:].ljust(34) + "".join(
            (f"{st[k]:13.3f}" if isinstance(st[k], float) else str(st[k]).rjust(13)) for k in keys))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(table, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
