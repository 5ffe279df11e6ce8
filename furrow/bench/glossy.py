"""``furrow bench glossy``: glossy sphere and Utah teapot with non-uniform roughness rendered with
the multi-scale environment map (render/mesh/glossy/gl.py, docs/methods.md §2) against the per-pixel brute-force
Phong reference (render/mesh/glossy/reference.py) -- the thesis' Table 5 (and Table 6: frame time).

For each object (sphere, teapot) and roughness mode (``vertex``: smoothness lambda interpolated
from the vertices, a gradient over the height; ``texel``: a smoothness texture of five bands,
bilinear), the MSEM render is compared at every covered pixel with

  * ``gated``:   the Phong model of the thesis (Eq. 1-2: cos^Lambda lobe around the reflection
                 vector, lights below the surface's horizon excluded) -- Table 5's reference;
  * ``ungated``: the same integral without the horizon gate (what the MSEM tabulates, Eq. 3-4),
                 which isolates the table + trilinear-lookup error.

Errors are the mean absolute difference per channel in 1/256 of the map's white level (99th
percentile luminance, ``render.shading.msem.white_level``), binned by the pixel's smoothness
lambda; the Phong exponent of each bin is Lambda = g(lambda) (Eq. 13).  The default setup is the
thesis' one: a 128^3 MSEM from a 512x256 map (the bundled 1024x512 courtyard, area-resampled), and
the reference sums over the same 512x256 map.  Frame time: GL draw (+ finish) and draw + colour
readback at 640x480 (the thesis' size), median of repeats, llvmpipe on this machine.

    furrow bench glossy [--quick] [--map courtyard] [--s 128] [--ref-height 256] [-o DIR] [--json]

Writes ``glossy_error_vs_smoothness.png`` and, per object and mode, ``<object>_<mode>.png``
(MSEM | Phong reference | |error| x8) and ``side_by_side_<mode>.png`` (sphere and teapot) under -o.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from furrow.bench import OUT_ROOT
from furrow.bench._common import print_result, save_figure

#: Smoothness bins (lambda) of the error table.
BINS = ((0.0, 0.2), (0.2, 0.4), (0.4, 0.6), (0.6, 0.8), (0.8, 1.0001))
#: Smoothness levels of the per-texel band map (bin centres).
BAND_LEVELS = (0.1, 0.3, 0.5, 0.7, 0.9)
#: Vertex mode: lambda = VERTEX_MIN + (1 - VERTEX_MIN) * normalised height.
VERTEX_MIN = 0.05
#: The thesis' Table 5 (mean error, 256 levels, vs the Phong render) and Table 6.
PAPER_TABLE5 = "mean 0.3-1.3 (colour pattern map), 2.0-3.7 (real map); grows with roughness"
PAPER_TABLE6 = "Phong reference 1 h 03 min per frame; MSEM > 60 fps at 640x480 (GeForce3)"
#: Frame-time image size and repeats.
FRAME_W, FRAME_H, FRAME_REPEATS = 640, 480, 10


def _camera(W: int, H: int, which: str):
    from capture.camera import Camera, look_at, make_K

    d = 0.42 if which == "sphere" else 0.5
    e, a = np.radians(20.0), np.radians(-60.0)
    eye = d * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    f = 1.5 * W
    return Camera(make_K(f, f, (W - 1) / 2, (H - 1) / 2), look_at(eye, (0.0, 0.0, 0.0)), W, H)


def _meshes(quick: bool) -> dict:
    from render.mesh.glossy.gl import GlossyMesh, utah_teapot, uv_sphere

    out = {}
    band = np.repeat(np.array(BAND_LEVELS)[:, None], 8, 0).repeat(32, 1).astype(np.float32)
    for which, (v, f, n, uv) in (("sphere", uv_sphere(0.1, 32 if quick else 64)),
                                 ("teapot", utah_teapot(0.25, 8 if quick else 14))):
        z = v[:, 2]
        sm = VERTEX_MIN + (1 - VERTEX_MIN) * (z - z.min()) / (z.max() - z.min())
        out[(which, "vertex")] = GlossyMesh(v, f, n, sm)
        out[(which, "texel")] = GlossyMesh(v, f, n, sm, uv, band)
    return out


def _tonemap(img, wl):
    from capture.scan import to_uint8_srgb

    return to_uint8_srgb(np.clip(np.asarray(img) / wl * 0.8, 0, 1))


def _frame_times(g, cam, repeats: int) -> dict:
    g.draw(cam)
    g.ctx.finish()
    td, tr = [], []
    for _ in range(max(1, repeats)):
        t = time.perf_counter(); g.draw(cam); g.ctx.finish(); td.append(time.perf_counter() - t)
        t = time.perf_counter(); g.render(cam); tr.append(time.perf_counter() - t)
    return {"draw_ms": 1e3 * float(np.median(td)), "draw_readback_ms": 1e3 * float(np.median(tr))}


def run(quick: bool, map_name: str, s: int, ref_height: int, W: int, H: int, out: Path,
        repeats: int = FRAME_REPEATS) -> dict:
    import imageio.v3 as iio

    from render.gl import create_context
    from render.mesh.glossy.gl import GlossyRenderer
    from render.mesh.glossy.reference import glossy_phong_reference_pair, glossy_pixels
    from render.shading.envmap import bundled_envmap
    from render.shading.msem import msem_build, msem_lambda, white_level

    env = bundled_envmap(map_name).resized(ref_height)
    wl = white_level(env)
    b = msem_build(env, s)
    res = {"map": map_name, "map_size": [env.width, env.height], "s": s, "msem_build_s": b.seconds,
           "white_level": wl, "image": [W, H], "paper_table5": PAPER_TABLE5, "paper_table6": PAPER_TABLE6,
           "bins": [], "frames": {}, "images": []}
    print(f"[glossy] MSEM {s}^3 from {env.width}x{env.height}: {b.seconds:.1f} s", file=sys.stderr)
    out.mkdir(parents=True, exist_ok=True)
    ctx = create_context()
    panels: dict = {}
    try:
        with GlossyRenderer(ctx) as g:
            g.set_msem(b.volume)
            for (which, mode), mesh in _meshes(quick).items():
                g.set_mesh(mesh)
                cam = _camera(W, H, which)
                r = g.render(cam)
                px = glossy_pixels(mesh, cam)
                t = time.perf_counter()
                ref_u, ref_g = glossy_phong_reference_pair(env, px, s)
                t_ref = time.perf_counter() - t
                ok = r.mask & px["mask"]
                e_u = np.abs(r.color - ref_u).mean(-1) / wl * 256
                e_g = np.abs(r.color - ref_g).mean(-1) / wl * 256
                sm = r.smoothness
                for lo, hi in BINS:
                    k = ok & (sm >= lo) & (sm < hi)
                    if not k.any():
                        continue
                    res["bins"].append({
                        "object": which, "mode": mode, "smoothness": f"{lo:.1f}-{min(hi, 1.0):.1f}",
                        "phong_exp": f"{msem_lambda(lo, s):.3g}-{msem_lambda(min(hi, 1.0), s):.3g}",
                        "pixels": int(k.sum()), "mean_err_gated_256": float(e_g[k].mean()),
                        "mean_err_ungated_256": float(e_u[k].mean()),
                        "median_err_gated_256": float(np.median(e_g[k]))})
                res["bins"].append({"object": which, "mode": mode, "smoothness": "all", "phong_exp": "",
                                    "pixels": int(ok.sum()), "mean_err_gated_256": float(e_g[ok].mean()),
                                    "mean_err_ungated_256": float(e_u[ok].mean()),
                                    "median_err_gated_256": float(np.median(e_g[ok]))})
                fr = _frame_times(g, _camera(FRAME_W, FRAME_H, which), repeats)
                fr.update({"reference_s": t_ref, "reference_pixels": int(px["mask"].sum()),
                           "triangles": int(len(mesh.faces))})
                res["frames"][f"{which}/{mode}"] = fr
                print(f"[glossy] {which}/{mode}: mean gated {e_g[ok].mean():.2f}/256, reference {t_ref:.1f} s, "
                      f"frame {fr['draw_ms']:.1f} ms", file=sys.stderr)
                err = np.clip(np.abs(r.color - ref_g).mean(-1, keepdims=True) / wl * 8, 0, 1).repeat(3, -1)
                row = np.concatenate([_tonemap(r.color, wl), _tonemap(ref_g, wl),
                                      (err * 255).astype(np.uint8)], 1)
                p = out / f"{which}_{mode}.png"
                iio.imwrite(p, row)
                res["images"].append(str(p))
                panels[(which, mode)] = row
        for mode in ("vertex", "texel"):
            p = out / f"side_by_side_{mode}.png"
            iio.imwrite(p, np.concatenate([panels[("sphere", mode)], panels[("teapot", mode)]], 0))
            res["images"].append(str(p))
    finally:
        ctx.release()
    res["plots"] = [_plot(res, out)]
    return res


def _plot(res: dict, out: Path) -> str:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.8))
    for key in sorted({(r["object"], r["mode"]) for r in res["bins"]}):
        rr = [r for r in res["bins"] if (r["object"], r["mode"]) == key and r["smoothness"] != "all"]
        x = [float(r["smoothness"].split("-")[0]) + 0.1 for r in rr]
        ax.plot(x, [r["mean_err_gated_256"] for r in rr], "o-", label=f"{key[0]} {key[1]} (gated)")
        ax.plot(x, [r["mean_err_ungated_256"] for r in rr], "x--", label=f"{key[0]} {key[1]} (ungated)")
    ax.set_xlabel("smoothness lambda (bin centre)"); ax.set_ylabel("mean error (1/256 of white)")
    ax.set_title(f"MSEM {res['s']}^3 vs Phong, {res['map']}"); ax.legend(fontsize=6)
    return str(save_figure(fig, out / "glossy_error_vs_smoothness.png"))


def _print_tables(res: dict) -> None:
    from rich.table import Table

    from furrow.console import console

    t = Table(title=f"MSEM {res['s']}^3 ({res['msem_build_s']:.1f} s) from {res['map']} "
                    f"{res['map_size'][0]}x{res['map_size'][1]} vs per-pixel Phong: mean error in 1/256 of white "
                    f"(thesis Table 5: {PAPER_TABLE5})")
    for c in ("object", "mode", "smoothness", "Phong exp.", "pixels", "gated mean", "ungated mean", "gated median"):
        t.add_column(c)
    for r in res["bins"]:
        t.add_row(r["object"], r["mode"], r["smoothness"], r["phong_exp"], str(r["pixels"]),
                  f"{r['mean_err_gated_256']:.2f}", f"{r['mean_err_ungated_256']:.2f}",
                  f"{r['median_err_gated_256']:.2f}")
    console.print(t)
    f = Table(title=f"frame time at {FRAME_W}x{FRAME_H} (llvmpipe) vs the reference (thesis Table 6: {PAPER_TABLE6})")
    for c in ("object/mode", "triangles", "draw ms", "draw+readback ms", "reference s (pixels)"):
        f.add_column(c)
    for k, v in res["frames"].items():
        f.add_row(k, str(v["triangles"]), f"{v['draw_ms']:.1f}", f"{v['draw_readback_ms']:.1f}",
                  f"{v['reference_s']:.1f} ({v['reference_pixels']})")
    console.print(f)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="furrow bench glossy", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="64^3 MSEM from a 256x128 map, 96x72 images (~30 s)")
    p.add_argument("--map", default="courtyard", help="bundled environment map")
    p.add_argument("--s", type=int, default=None, help="MSEM resolution (default 128; 64 with --quick)")
    p.add_argument("--ref-height", type=int, default=None,
                   help="rows of the map the MSEM and the reference use (default 256; 128 with --quick)")
    p.add_argument("--width", type=int, default=None, help="error-image width (default 160; 96 with --quick)")
    p.add_argument("--repeats", type=int, default=FRAME_REPEATS, help="frames timed per object and mode")
    p.add_argument("-o", "--out", type=Path, default=OUT_ROOT / "bench" / "glossy")
    p.add_argument("--json", action="store_true", help="print the results as JSON on stdout")
    a = p.parse_args(argv)
    s = a.s or (64 if a.quick else 128)
    rh = a.ref_height or (128 if a.quick else 256)
    W = a.width or (96 if a.quick else 160)
    res = run(a.quick, a.map, s, rh, W, W * 3 // 4, a.out, a.repeats)
    return print_result(res, a.json, _print_tables, f"images: {', '.join(res['images'])}",
                        f"plots: {', '.join(res['plots'])}")


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
