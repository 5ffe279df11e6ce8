"""``furrow bench shading``: speed against error of the environment-shading module (docs/methods.md §2-§4).

Sections (each a table; plots under -o):
  irradiance  SH9 and the exact irradiance table vs the full-resolution brute-force integral
              (100 random normals, every bundled map).
  msem        the multi-scale environment map vs its brute force: mean / p99 / max error in
              1/256 of the map's white level (99th percentile luminance) and build time, for th in
              {0.001, 0.005, 0.01, 0.05, 0.1} at 64^3 and 128^3 from a 1024x512 HDR map, beside the
              thesis' Tables 3-4; plus the table-only (fastest) mode.
  sphere      a glossy sphere with smoothness varying across it, MSEM lookup vs the exact per-pixel
              Phong integral (with and without the horizon gate the MSEM drops), error per
              roughness bin (the thesis' Table 5; no teapot: furrow has no mesh renderer here).
  sg          f_h: our fitted table vs the printed fits; the environment fitted by K SGs (L-BFGS-B):
              radiance error, diffuse irradiance error, time, K in {4, 10, 32, 128}.
  ssdf        SSDF from 8 / 64 / 512 spheres (a torus' medial circle) vs ray-cast visibility:
              error of the visibility-weighted SG integral and time.
  prefilter   the prefiltered SG pyramid Gamma(p, lambda) (half-octave levels) vs the brute-force
              sum: relative error at and between levels, build time.
Glare cost / energy and the compositing shadow ratio are measured by ``furrow bench glare``
(render/composite/glare_layer.py, render/composite/pipeline.py).

    furrow bench shading [--quick] [--map courtyard] [--sections msem,sg,...] [-o DIR] [--json]

The msem and sphere sections take a few minutes (brute-force references); --quick: ~1 minute.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from capture.sampling import cell_centres, to_texcoord
from furrow.bench import OUT_ROOT
from furrow.bench._common import print_result, save_figure

SECTIONS = ("irradiance", "msem", "sphere", "sg", "prefilter", "ssdf")
#: The thesis' Table 3 (mean error, 256 levels, vs unaccelerated) and Table 4 (time).
PAPER_TABLE3 = {0.001: "0.1-1.0", 0.005: "2.0", 0.01: "3.6-4.0", 0.05: "17-19", 0.1: "35-38"}
PAPER_TABLE4 = "unaccelerated 73 h 52 min; accelerated 21 h 24 min table + 7-9 s filtering (128^3, 512x256)"


def _dirs(n, seed):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def bench_irradiance(quick: bool) -> list[dict]:
    from render.shading.envmap import BUNDLED_NAMES, bundled_envmap
    from render.shading.irradiance import irradiance_lookup, irradiance_table
    from render.shading.sh import irradiance_brute, sh9_irradiance, sh9_project

    rows = []
    n = _dirs(100, 7)
    for name in BUNDLED_NAMES[:2] if quick else BUNDLED_NAMES:
        env = bundled_envmap(name)
        t = time.perf_counter(); ref = irradiance_brute(env, n); tb = time.perf_counter() - t
        t = time.perf_counter(); sh = sh9_irradiance(sh9_project(env), n); ts = time.perf_counter() - t
        row = {"map": name, "brute_s": tb, "sh9_s": ts,
               "sh9_max_rel": float((abs(sh - ref) / ref).max()), "sh9_mean_rel": float((abs(sh - ref) / ref).mean())}
        for h in (64, 128):
            t = time.perf_counter(); tab = irradiance_table(env, h); tt = time.perf_counter() - t
            e = abs(irradiance_lookup(tab, n) - ref) / ref
            row.update({f"table{h}_s": tt, f"table{h}_max_rel": float(e.max()), f"table{h}_mean_rel": float(e.mean())})
        rows.append(row)
    return rows


def _voxel_sample(s, n, seed):
    idx = np.random.default_rng(seed).integers(0, s, (3 * n, 3))
    return idx[np.linalg.norm(to_texcoord(idx, s) * 2 - 1, axis=1) <= 1.0][:n]


def bench_msem(quick: bool, map_name: str, samples: int) -> list[dict]:
    from render.shading.envmap import bundled_envmap
    from render.shading.msem import msem_brute, msem_build, white_level

    env = bundled_envmap(map_name)
    wl = white_level(env)
    rows = []
    sizes = (64,) if quick else (64, 128)
    ths = (0.001, 0.01, 0.1) if quick else (0.001, 0.005, 0.01, 0.05, 0.1)
    for s in sizes:
        idx = _voxel_sample(s, samples, s)
        t = time.perf_counter(); ref = msem_brute(env, s, idx); tb = time.perf_counter() - t
        modes = [("edges-direct", None)] + ([("table-only", np.inf)] if True else [])
        for mode, rt in modes:
            for th in ths if mode == "edges-direct" else ths[:1]:
                kw = {} if rt is None else {"range_tol": rt}
                b = msem_build(env, s, th, **kw)
                got = b.volume[idx[:, 0], idx[:, 1], idx[:, 2]]
                err = np.abs(got - ref) / wl * 256
                rows.append({"s": s, "th": th, "mode": mode, "build_s": b.seconds, "shells": b.shells,
                             "direct_voxels": b.direct, "mean_err_256": float(err.mean()),
                             "p99_err_256": float(np.percentile(err, 99)), "max_err_256": float(err.max()),
                             "brute_s_per_voxel": tb / len(idx), "brute_full_est_s": tb / len(idx) * s**3,
                             "paper_table3": PAPER_TABLE3.get(th, "")})
                print(f"  msem {s}^3 th={th} {mode}: {b.seconds:.1f} s, mean {err.mean():.3f}/256", file=sys.stderr)
    return rows


def bench_sphere(quick: bool, map_name: str) -> list[dict]:
    """Glossy sphere, smoothness 0.05..1 left to right, orthographic view along +y."""
    from render.shading.envmap import bundled_envmap
    from render.shading.msem import msem_build, msem_lambda, msem_lookup, phong_weights, white_level

    env = bundled_envmap(map_name).resized(128 if quick else 256)
    s = 64 if quick else 128
    vol = msem_build(env, s).volume
    res = 48 if quick else 96
    u = cell_centres(res, -1.0, 1.0)
    X, Z = np.meshgrid(u, -u)
    inside = X**2 + Z**2 < 1
    nx, nz = X[inside], Z[inside]
    ny = -np.sqrt(np.maximum(0, 1 - nx**2 - nz**2))
    n = np.stack([nx, ny, nz], 1)
    v = np.array([0.0, -1.0, 0.0])  # towards the viewer
    r = 2 * (n @ v)[:, None] * n - v
    smooth = 0.05 + 0.95 * (nx + 1) / 2
    got = msem_lookup(vol, r, smooth)
    lam = msem_lambda(smooth, s)
    d = env.pixel_directions().reshape(-1, 3)
    om = env.pixel_solid_angles().reshape(-1)
    L = env.data.reshape(-1, 3).astype(np.float64)
    ref = np.empty_like(got)
    ref_gate = np.empty_like(got)
    for a in range(0, len(r), 128):
        c = r[a:a + 128] @ d.T
        w = phong_weights(c, lam[a:a + 128, None]) * om
        ref[a:a + 128] = (w @ L) / w.sum(1, keepdims=True)
        wg = w * ((n[a:a + 128] @ d.T) >= 0)
        ref_gate[a:a + 128] = (wg @ L) / np.maximum(wg.sum(1, keepdims=True), 1e-300)
    wl = white_level(env)
    rows = []
    for lo, hi in ((0.05, 0.25), (0.25, 0.5), (0.5, 0.75), (0.75, 1.0)):
        k = (smooth >= lo) & (smooth <= hi)
        rows.append({"smoothness": f"{lo}-{hi}", "pixels": int(k.sum()),
                     "mean_err_256": float(np.abs(got[k] - ref[k]).mean() / wl * 256),
                     "mean_err_gated_256": float(np.abs(got[k] - ref_gate[k]).mean() / wl * 256)})
    return rows


def bench_sg(quick: bool, map_name: str) -> dict:
    from render.shading.envmap import bundled_envmap
    from render.shading.sg import (
        fh_exact,
        fh_fit,
        fh_printed_001,
        fh_printed_004,
        fit_cosine_lobe,
        sg_hemi_integral,
        sg_irradiance,
    )
    from render.shading.sg_fit import fit_env_sg
    from render.shading.sh import irradiance_brute

    rng = np.random.default_rng(0)
    td = rng.uniform(-np.pi / 2, np.pi / 2, 4000)
    lam = 10 ** rng.uniform(-3, 5, 4000)
    ex = fh_exact(td, lam)
    h = sg_hemi_integral(lam)
    fh = {}
    for name, f in (("ours", fh_fit), ("printed_001", fh_printed_001), ("printed_004", fh_printed_004)):
        e = np.abs(f(td, lam) - ex) / h
        fh[name] = {"max": float(np.nanmax(e)), "mean": float(np.nanmean(e)), "nan": int(np.isnan(e).sum())}
    cl = fit_cosine_lobe()
    env = bundled_envmap(map_name)
    n = _dirs(200, 3)
    ref = irradiance_brute(env.resized(128), n)
    fits = []
    for k in (4, 10, 32) if quick else (4, 10, 32, 128):
        f = fit_env_sg(env, k)
        e = np.abs(sg_irradiance(f.axes, f.lams, f.mus, n) - ref) / ref
        fits.append({"K": k, "radiance_rel_l2": f.rel_error, "seconds": f.seconds,
                     "irradiance_mean_rel": float(e.mean()), "irradiance_max_rel": float(e.max())})
    return {"fh": fh, "cosine_lobe_fit": {"lambda": cl[0], "mu": cl[1], "published": [2.133, 1.170]}, "env_fit": fits}


def bench_prefilter(quick: bool, map_name: str) -> list[dict]:
    from render.shading.envmap import bundled_envmap
    from render.shading.sg_env import sg_env_integral, sg_env_integral_brute, sg_prefilter

    env = bundled_envmap(map_name).resized(64 if quick else 128)
    t = time.perf_counter(); pre = sg_prefilter(env); tb = time.perf_counter() - t
    p = _dirs(200, 5)
    rows = []
    for lam in (1.0, 8.0, 10.0, 30.0, 64.0, 100.0, 300.0, 1000.0):
        ref = sg_env_integral_brute(env, p, lam)
        rel = np.abs(sg_env_integral(pre, p, np.full(len(p), lam)) - ref) / ref
        rows.append({"lambda": lam, "map_rows": env.height, "build_s": tb, "median_rel": float(np.median(rel)),
                     "p95_rel": float(np.percentile(rel, 95)), "max_rel": float(rel.max())})
    return rows


def bench_ssdf(quick: bool) -> list[dict]:
    import open3d as o3d

    from render.shading.sg import fh_fit, sg_hemi_integral
    from render.shading.ssdf import (
        fibonacci_directions,
        raycast_visibility,
        sg_visible_integral_raycast,
        ssdf_ground,
        ssdf_spheres,
    )

    R, r, z0 = 0.1, 0.03, 0.06  # torus lying flat, raised z0 above the ground
    m = o3d.geometry.TriangleMesh.create_torus(torus_radius=R, tube_radius=r, radial_resolution=120,
                                               tubular_resolution=40)
    V = np.asarray(m.vertices) + [0, 0, z0]
    F = np.asarray(m.triangles)
    G = np.array([[-50, -50, 0.0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]])
    V2, F2 = np.vstack([V, G]), np.vstack([F, np.array([[0, 1, 2], [0, 2, 3]]) + len(V)])
    rng = np.random.default_rng(1)
    P = np.c_[rng.uniform(-0.2, 0.2, (40 if quick else 120, 2)), np.full(40 if quick else 120, 1e-4)]
    N = np.tile([0, 0, 1.0], (len(P), 1))
    D = fibonacci_directions(20000 if quick else 40000)
    axes = fibonacci_directions(40)
    axes = axes[axes[:, 2] > 0.05]
    t = time.perf_counter(); vis = raycast_visibility(V2, F2, P, D); t_rc = time.perf_counter() - t
    rows = []
    for k in (8, 64, 512):
        a = 2 * np.pi * np.arange(k) / k
        centers = np.stack([R * np.cos(a), R * np.sin(a), np.full(k, z0)], 1)
        radii = np.full(k, r)
        t = time.perf_counter()
        ss = np.minimum(ssdf_spheres(P, N, axes, centers, radii), ssdf_ground(axes)[None])
        t_s = time.perf_counter() - t
        row = {"spheres": k, "ssdf_s": t_s, "ssdf_us_per_point_axis": t_s / (len(P) * len(axes)) * 1e6,
               "raycast_s": t_rc, "rays": int(len(P) * len(D))}
        for lam in (1.0, 10.0, 100.0):
            ref = sg_visible_integral_raycast(vis, D, axes, np.full(len(axes), lam))
            e = np.abs(fh_fit(ss, lam) - ref) / sg_hemi_integral(lam)
            row[f"err_mean_l{lam:g}"] = float(e.mean())
            row[f"err_max_l{lam:g}"] = float(e.max())
        rows.append(row)
    return rows


def _plots(res: dict, out: Path) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    saved = []
    if res.get("msem"):
        fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
        for s in sorted({r["s"] for r in res["msem"]}):
            rr = [r for r in res["msem"] if r["s"] == s and r["mode"] == "edges-direct"]
            ax[0].loglog([r["th"] for r in rr], [r["mean_err_256"] for r in rr], "o-", label=f"{s}^3 mean")
            ax[0].loglog([r["th"] for r in rr], [r["max_err_256"] for r in rr], "x--", label=f"{s}^3 max")
            ax[1].semilogx([r["th"] for r in rr], [r["build_s"] for r in rr], "o-", label=f"{s}^3")
        ax[0].set_xlabel("th"); ax[0].set_ylabel("error (1/256 of white)"); ax[0].legend(fontsize=7)
        ax[1].set_xlabel("th"); ax[1].set_ylabel("build time (s)"); ax[1].legend(fontsize=7)
        saved.append(str(save_figure(fig, out / "msem_error_time.png")))
    if res.get("sg"):
        f = res["sg"]["env_fit"]
        fig, ax = plt.subplots(figsize=(5, 3.5))
        ax.semilogx([r["K"] for r in f], [r["radiance_rel_l2"] for r in f], "o-", label="radiance rel. L2")
        ax.semilogx([r["K"] for r in f], [r["irradiance_mean_rel"] for r in f], "x-", label="irradiance mean rel.")
        ax.set_xlabel("K lobes"); ax.legend()
        saved.append(str(save_figure(fig, out / "sg_fit_vs_k.png")))
    if res.get("ssdf"):
        fig, ax = plt.subplots(figsize=(5, 3.5))
        for lam in ("1", "10", "100"):
            ax.semilogx([r["spheres"] for r in res["ssdf"]], [r[f"err_mean_l{lam}"] for r in res["ssdf"]], "o-",
                        label=f"lambda {lam}")
        ax.set_xlabel("spheres"); ax.set_ylabel("mean |error| / f_h(pi/2)"); ax.legend()
        saved.append(str(save_figure(fig, out / "ssdf_error_vs_spheres.png")))
    return saved


def _print_tables(res: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(width=200)  # wide tables, also when piped

    def table(title, rows, cols):
        t = Table(title=title)
        for c in cols:
            t.add_column(c)
        for r in rows:
            t.add_row(*[f"{r[c]:.4g}" if isinstance(r[c], float) else str(r[c]) for c in cols])
        console.print(t)

    if res.get("irradiance"):
        table("Irradiance vs full-res brute force (100 normals; relative error)", res["irradiance"],
              ["map", "sh9_mean_rel", "sh9_max_rel", "table64_max_rel", "table128_mean_rel", "table128_max_rel",
               "table128_s", "brute_s"])
    if res.get("msem"):
        table("MSEM vs brute force (error in 1/256 of white; thesis Table 3 beside)", res["msem"],
              ["s", "mode", "th", "build_s", "shells", "direct_voxels", "mean_err_256", "p99_err_256", "max_err_256",
               "brute_full_est_s", "paper_table3"])
        console.print(f"thesis Table 4: {PAPER_TABLE4}")
    if res.get("sphere"):
        table("Glossy sphere: MSEM lookup vs exact per-pixel Phong (1/256 of white)", res["sphere"],
              ["smoothness", "pixels", "mean_err_256", "mean_err_gated_256"])
    if res.get("sg"):
        sg = res["sg"]
        table("f_h vs exact (|error| / f_h(pi/2), 4000 random (theta_d, lambda 1e-3..1e5))",
              [{"fit": k, **v} for k, v in sg["fh"].items()], ["fit", "mean", "max", "nan"])
        console.print(f"cosine lobe, our L2 fit: lambda {sg['cosine_lobe_fit']['lambda']:.4f}, "
                      f"mu {sg['cosine_lobe_fit']['mu']:.4f} (published 2.133, 1.170)")
        table("Environment fitted by K SGs (L-BFGS-B)", sg["env_fit"],
              ["K", "radiance_rel_l2", "irradiance_mean_rel", "irradiance_max_rel", "seconds"])
    if res.get("prefilter"):
        table("Prefiltered SG pyramid Gamma(p, lambda) vs brute force (relative error)", res["prefilter"],
              ["lambda", "map_rows", "median_rel", "p95_rel", "max_rel", "build_s"])
    if res.get("ssdf"):
        table("SSDF from spheres vs ray casting (|error of integral G V| / f_h(pi/2))", res["ssdf"],
              ["spheres", "err_mean_l1", "err_mean_l10", "err_max_l10", "err_mean_l100", "err_max_l100", "ssdf_s",
               "raycast_s"])


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="furrow bench shading", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="smaller sizes (a minute instead of several)")
    p.add_argument("--map", default="courtyard", help="bundled map for msem / sphere / sg")
    p.add_argument("--sections", default=",".join(SECTIONS), help=f"comma list of {', '.join(SECTIONS)}")
    p.add_argument("--samples", type=int, default=300, help="voxels compared with the MSEM brute force")
    p.add_argument("-o", "--out", type=Path, default=OUT_ROOT / "bench" / "shading")
    p.add_argument("--json", action="store_true", help="print the results as JSON on stdout")
    a = p.parse_args(argv)
    secs = [s.strip() for s in a.sections.split(",") if s.strip()]
    bad = [s for s in secs if s not in SECTIONS]
    if bad:
        p.error(f"unknown sections {bad}")
    res: dict = {"map": a.map, "quick": a.quick}
    runners = {"irradiance": lambda: bench_irradiance(a.quick), "msem": lambda: bench_msem(a.quick, a.map, a.samples),
               "sphere": lambda: bench_sphere(a.quick, a.map), "sg": lambda: bench_sg(a.quick, a.map),
               "prefilter": lambda: bench_prefilter(a.quick, a.map),
               "ssdf": lambda: bench_ssdf(a.quick)}
    for s in secs:
        t = time.perf_counter()
        print(f"[shading bench] {s} ...", file=sys.stderr)
        res[s] = runners[s]()
        print(f"[shading bench] {s} done in {time.perf_counter() - t:.1f} s", file=sys.stderr)
    res["plots"] = _plots(res, a.out)
    print_result(res, a.json, _print_tables, f"plots: {', '.join(res['plots'])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
