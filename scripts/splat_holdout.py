"""Held-out scores of an exported splat PLY drawn by an INDEPENDENT renderer (issue 33).

Deliberately shares no code with furrow's splat path (volume/splats.py, volume/splat_sh.py,
volume/export.py, render/splat/): the PLY is read with ``plyfile``, the activations, the
quaternion, the covariance, the spherical harmonics and the tile-based front-to-back blending are
written here again from the 3D Gaussian Splatting reference (graphdeco-inria/gaussian-splatting
``GaussianModel``, diff-gaussian-rasterization ``forward.cu`` / ``auxiliary.h``), one Gaussian at a
time in depth order, with the reference's 16 x 16 tiles, its 3-sigma radius, its 0.3 px^2 low
pass, alpha = min(0.99, o exp(power)), the 1/255 skip and its stop once T would fall below 1e-4.
Only the cameras, the held-out photographs and the scoring are furrow's (capture.io,
render.evaluate.holdout_split, render.metrics.compare: the numbers of ``furrow eval``).

The blended display colour C and alpha A = 1 - T become the premultiplied linear frame
linear(C / A) * A (the convention of docs/splats.md), scored over black as ``furrow eval`` scores.

usage: python scripts/splat_holdout.py SCANS SPLATS.ply [--holdout 2] [--max-views N] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

# reference constants (auxiliary.h), typed again on purpose
C0 = 0.28209479177387814
C1 = 0.4886025119029199
C2 = [1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396]
C3 = [-0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154, -0.4570457994644658,
      1.445305721320277, -0.5900435899266435]
BLOCK = 16


def load_ply(path):
    """Activated parameters of a 3DGS PLY read with plyfile: xyz, sh (N, 3, K), opacity, cov3d (N, 3, 3)."""
    from plyfile import PlyData

    v = PlyData.read(str(path))["vertex"]
    xyz = np.stack([v["x"], v["y"], v["z"]], 1).astype(np.float64)
    rest = sorted((p.name for p in v.properties if p.name.startswith("f_rest_")), key=lambda s: int(s[7:]))
    k = len(rest) // 3 + 1
    sh = np.zeros((len(xyz), 3, k))
    for c in range(3):
        sh[:, c, 0] = v[f"f_dc_{c}"]
    if rest:
        sh[:, :, 1:] = np.stack([v[n] for n in rest], 1).reshape(len(xyz), 3, k - 1)
    opacity = 1.0 / (1.0 + np.exp(-np.asarray(v["opacity"], np.float64)))
    scale = np.exp(np.stack([v[f"scale_{i}"] for i in range(3)], 1).astype(np.float64))
    q = np.stack([v[f"rot_{i}"] for i in range(4)], 1).astype(np.float64)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    r, x, y, z = q.T
    # glm::mat3 is column-major: these nine values are the columns of R_glm (forward.cu computeCov3D)
    cols = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - r * z), 2 * (x * z + r * y),
                     2 * (x * y + r * z), 1 - 2 * (x * x + z * z), 2 * (y * z - r * x),
                     2 * (x * z - r * y), 2 * (y * z + r * x), 1 - 2 * (x * x + y * y)], 1).reshape(-1, 3, 3)
    R_glm = cols.transpose(0, 2, 1)  # the listed triples are columns
    M = scale[:, :, None] * R_glm    # S * R (S scales rows)
    cov3d = np.einsum("nji,njk->nik", M, M)  # M^T M
    return xyz, sh, opacity, cov3d


def sh_to_rgb(sh, dirs):
    x, y, z = dirs[:, 0], dirs[:, 1], dirs[:, 2]
    k = sh.shape[2]
    res = C0 * sh[:, :, 0]
    if k > 1:
        res = res - C1 * y[:, None] * sh[:, :, 1] + C1 * z[:, None] * sh[:, :, 2] - C1 * x[:, None] * sh[:, :, 3]
    if k > 4:
        xx, yy, zz, xy, yz, xz = x * x, y * y, z * z, x * y, y * z, x * z
        terms = [C2[0] * xy, C2[1] * yz, C2[2] * (2 * zz - xx - yy), C2[3] * xz, C2[4] * (xx - yy)]
        for i, t in enumerate(terms):
            res = res + t[:, None] * sh[:, :, 4 + i]
    if k > 9:
        terms = [C3[0] * y * (3 * xx - yy), C3[1] * xy * z, C3[2] * y * (4 * zz - xx - yy),
                 C3[3] * z * (2 * zz - 3 * xx - 3 * yy), C3[4] * x * (4 * zz - xx - yy), C3[5] * z * (xx - yy),
                 C3[6] * x * (xx - 3 * yy)]
        for i, t in enumerate(terms):
            res = res + t[:, None] * sh[:, :, 9 + i]
    return np.maximum(res + 0.5, 0.0)


def render(ply, K, world_to_cam, W, H, near=0.01):
    """Reference image formation: (display colour C (H, W, 3) over black, final T (H, W))."""
    xyz, sh, opacity, cov3d = ply
    Rw, tw = world_to_cam[:3, :3], world_to_cam[:3, 3]
    t = xyz @ Rw.T + tw
    fx, fy, cx, cy, s = K[0, 0], K[1, 1], K[0, 2], K[1, 2], K[0, 1]
    tanx, tany = 0.5 * W / fx, 0.5 * H / fy
    order = np.argsort(t[:, 2], kind="stable")
    order = order[t[order, 2] > near]
    cam_pos = -Rw.T @ tw
    C = np.zeros((H, W, 3))
    T = np.ones((H, W))
    done = np.zeros((H, W), bool)
    for i in order:
        tx, ty, tz = t[i]
        px = np.clip(tx / tz, -1.3 * tanx, 1.3 * tanx) * tz
        py = np.clip(ty / tz, -1.3 * tany, 1.3 * tany) * tz
        J = np.array([[fx / tz, s / tz, -(fx * px + s * py) / tz ** 2], [0.0, fy / tz, -fy * py / tz ** 2]])
        JW = J @ Rw
        cov = JW @ cov3d[i] @ JW.T
        a, b, c = cov[0, 0] + 0.3, cov[0, 1], cov[1, 1] + 0.3
        det = a * c - b * b
        if det == 0:
            continue
        conic = (c / det, -b / det, a / det)
        mid = 0.5 * (a + c)
        l1 = mid + np.sqrt(max(0.1, mid * mid - det))
        radius = np.ceil(3.0 * np.sqrt(l1))
        u = fx * tx / tz + s * ty / tz + cx
        v = fy * ty / tz + cy
        gx, gy = (W + BLOCK - 1) // BLOCK, (H + BLOCK - 1) // BLOCK
        x0 = min(gx, max(0, int((u - radius) / BLOCK))) * BLOCK
        x1 = min(gx, max(0, int((u + radius + BLOCK - 1) / BLOCK))) * BLOCK
        y0 = min(gy, max(0, int((v - radius) / BLOCK))) * BLOCK
        y1 = min(gy, max(0, int((v + radius + BLOCK - 1) / BLOCK))) * BLOCK
        x1, y1 = min(x1, W), min(y1, H)
        # inside the touched tiles, only pixels with q <= 2 ln(255 o) can reach alpha >= 1/255: the
        # others are skipped by the reference's alpha test anyway, so they are not evaluated here
        reach = 2.0 * np.log(255.0 * opacity[i])
        if reach <= 0:
            continue
        rx, ry = np.sqrt(reach * a), np.sqrt(reach * c)
        x0, x1 = max(x0, int(np.ceil(u - rx))), min(x1, int(np.floor(u + rx)) + 1)
        y0, y1 = max(y0, int(np.ceil(v - ry))), min(y1, int(np.floor(v + ry)) + 1)
        if x1 <= x0 or y1 <= y0:
            continue
        d = xyz[i] - cam_pos
        rgb = sh_to_rgb(sh[i:i + 1], (d / np.linalg.norm(d))[None])[0]
        yy, xx = np.mgrid[y0:y1, x0:x1]
        dx, dy = u - xx, v - yy
        power = -0.5 * (conic[0] * dx * dx + conic[2] * dy * dy) - conic[1] * dx * dy
        alpha = np.minimum(0.99, opacity[i] * np.exp(power))
        Tt, dn = T[y0:y1, x0:x1], done[y0:y1, x0:x1]
        use = (power <= 0) & (alpha >= 1.0 / 255.0) & ~dn
        test_T = Tt * (1 - alpha)
        stop = use & (test_T < 1e-4)
        dn |= stop
        use &= ~stop
        w = np.where(use, alpha * Tt, 0.0)
        C[y0:y1, x0:x1] += w[..., None] * rgb
        Tt[use] = test_T[use]
    return C, T


def to_linear_premultiplied(C, T):
    from capture.scan import srgb_to_linear

    A = 1.0 - T
    safe = np.where(A > 0, A, 1.0)
    straight = np.clip(C / safe[..., None], 0.0, 1.0)
    return np.where(A[..., None] > 0, srgb_to_linear(straight) * A[..., None], 0.0).astype(np.float32), A


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scans", type=Path)
    ap.add_argument("ply", type=Path)
    ap.add_argument("--holdout", type=int, default=2)
    ap.add_argument("--max-views", type=int, default=None)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--save", type=Path, default=None, help="folder for the renderings (PNG)")
    a = ap.parse_args(argv)
    from capture.io import read_scanset
    from render import metrics
    from render.evaluate import holdout_split, reference_foreground

    ply = load_ply(a.ply)
    held = holdout_split(read_scanset(a.scans), a.holdout, a.max_views).held
    views = []
    for scan in held:
        cam = scan.camera
        t0 = time.perf_counter()
        C, T = render(ply, cam.K, cam.cam_from_world, cam.width, cam.height)
        rgb, A = to_linear_premultiplied(C, T)
        m = metrics.compare(scan.srgb8, metrics.as_srgb8(rgb), reference_foreground(scan))
        m.update(view=Path(scan.name).name, seconds=time.perf_counter() - t0)
        views.append(m)
        print(f"{m['view']}: masked PSNR {m['psnr_masked']:.2f} SSIM {m['ssim_masked']:.3f} "
              f"sharpness {m['sharpness']:.2f} ({m['seconds']:.1f} s)", flush=True)
        if a.save:
            from capture.imageio import write_png

            write_png(a.save / (Path(scan.name).stem + ".png"), metrics.as_srgb8(rgb))
    keys = ("psnr", "ssim", "psnr_masked", "ssim_masked", "sharpness")
    mean = {k: float(np.mean([v[k] for v in views])) for k in keys}
    print("mean " + " ".join(f"{k} {v:.3f}" for k, v in mean.items()))
    if a.json:
        a.json.write_text(json.dumps({"ply": str(a.ply), "scans": str(a.scans), **mean, "views": views}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
