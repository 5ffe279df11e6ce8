"""``furrow bench glare``: glare cost and energy (docs/methods.md §4) and the composite into an environment.

1. Frame cost against the number of bright pixels (the paper: "glare cost is proportional to the
   number of bright pixels"): N random highlights in a W x H frame, for the streak layer's
   supersampling s in {1, 2, 4}: CPU streak setup (ms), GL draw + average + read back (ms).
2. Streak energy: summed GL streak light / analytic light of the pairs inside the frame - 1 for
   each N and s; and / the highlight excess for 200 highlights whose pairs all stay inside, from
   wide (n = 10) to thin (n = 1000, 1 px) pairs.
3. Composite frame cost at W x H (ground-shadow grid, composite pass, glare, tone map) and a
   picture: a glossy sphere composited into a bundled environment with its ground shadow and
   glare, saved as PNG.

    furrow bench glare [--size 640x480] [--counts 10,100,1000,3000,10000] [--env studio]
                       [-o out/bench/glare] [--json] [--model DIR --scans DIR [--view I]]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from furrow.bench import OUT_ROOT
from furrow.bench._common import save_figure

SUPERSAMPLES = (1, 2, 4)
REPEATS = 5
#: Picture: camera azimuth from the brightest light source (degrees), and the glare settings
#: (k_length / k_size are the paper's free global settings; larger than the defaults to show).
CAMERA_AZIMUTH_FROM_SUN_DEG = 110.0
CAMERA_HEIGHT = 0.6
PICTURE_GLARE_SETTINGS = dict(k_length=3.0, k_size=6.0, n_dirs=6)
#: The thin pairs' energy test keeps its highlights this far from the frame's border (pixels), so that
#: their streaks stay inside; the frame must be wider and taller than twice this.
THIN_MARGIN_PX = 80


def _sources(n, W, H, n_exp, seed=0):
    from render.shading.glare_maps import glare_sources

    rng = np.random.default_rng(seed)
    img = np.full((H, W, 3), 0.1)
    idx = rng.choice(W * H, size=min(n, W * H), replace=False)
    img.reshape(-1, 3)[idx] = rng.uniform(1.5, 40.0, (len(idx), 3))
    return glare_sources(img, 1.0, default_n=n_exp)


def bench_cost(ctx, W, H, counts, n_exp=100.0):
    from render.composite.glare_layer import GlareLayer
    from render.shading.glare import GlareConfig
    from render.shading.glare_maps import make_streaks, streak_energy_on_screen

    rows = []
    layers = {s: GlareLayer(ctx, W, H, s) for s in SUPERSAMPLES}
    try:
        for n in counts:
            src = _sources(n, W, H, n_exp)
            t0 = time.perf_counter()
            st = make_streaks(src, GlareConfig())
            cpu = 1e3 * (time.perf_counter() - t0)
            exc = streak_energy_on_screen(st, W, H)  # the analytic light that stays in the frame
            for s, layer in layers.items():
                ms = []
                for _ in range(REPEATS):
                    light = layer.render(st)
                    ms.append(layer.last_ms)
                err = float(np.max(np.abs(light.sum((0, 1)) / exc - 1)))
                rows.append({"bright_pixels": int(n), "pairs": len(st), "supersample": s, "setup_ms": cpu,
                             "gl_ms": float(np.median(ms)), "energy_rel_err": err})
    finally:
        for layer in layers.values():
            layer.release()
    return rows


def bench_energy_thin(ctx, W, H):
    """Energy error of pairs away from the border, for exponents giving wide .. 1 px pairs."""
    from render.composite.glare_layer import GlareLayer
    from render.shading.glare import GlareConfig
    from render.shading.glare_maps import glare_sources, make_streaks

    out = []
    rng = np.random.default_rng(5)
    img = np.full((H, W, 3), 0.1)
    m = THIN_MARGIN_PX
    img[rng.integers(m, H - m, 200), rng.integers(m, W - m, 200)] = rng.uniform(1.5, 40.0, (200, 3))
    for n_exp in (10.0, 100.0, 1000.0):
        src = glare_sources(img, 1.0, default_n=n_exp)
        st = make_streaks(src, GlareConfig())
        for s in SUPERSAMPLES:
            with GlareLayer(ctx, W, H, s) as layer:
                light = layer.render(st)
            out.append({"n": n_exp, "supersample": s, "width_px": float(np.median(st.width)),
                        "energy_rel_err": float(np.max(np.abs(light.sum((0, 1)) / src.excess.sum(0) - 1)))})
    return out


def sphere_scene(camera, centre, radius, albedo):
    """Analytic sphere: depth and normals (render.composite.reference.raycast_sphere)."""
    from render.composite.reference import raycast_sphere

    return raycast_sphere(camera, centre, radius)


def bench_composite(ctx, W, H, env_name, out_dir: Path):
    from capture.camera import Camera, look_at, make_K
    from capture.scan import to_uint8_srgb
    from render.composite.ground_shadow import shadow_sg_fit
    from render.composite.pipeline import composite_frame
    from render.composite.tonemap import TONE_WHITE
    from render.shading.envmap import bundled_envmap
    from render.shading.glare import GlareConfig
    from render.shading.irradiance import irradiance_lookup, irradiance_table
    from volume.model import SphereSet

    PICTURE_GLARE = GlareConfig(display_max=TONE_WHITE, **PICTURE_GLARE_SETTINGS)
    env = bundled_envmap(env_name)
    fit = shadow_sg_fit(env)
    centre, radius = np.array([0.0, 0.0, 0.1]), 0.1
    from render.shading.glare_maps import light_source_map, light_sources

    # camera 100 degrees of azimuth away from the brightest source: the shadow is seen from the side
    src = light_sources(light_source_map(env))
    sun = src.dirs[np.argmax(src.irradiance.sum(1))] if len(src.dirs) else np.array([1.0, 0.0, 0.5])
    az = np.arctan2(sun[1], sun[0]) + np.radians(CAMERA_AZIMUTH_FROM_SUN_DEG)
    eye = np.array([0.8 * np.cos(az), 0.8 * np.sin(az), CAMERA_HEIGHT])
    f = 1.1 * W
    cam = Camera(make_K(f, f, (W - 1) / 2, (H - 1) / 2), look_at(eye, [0.0, 0.0, 0.05]), W, H)
    z, n = sphere_scene(cam, centre, radius, None)
    obj = z > 0
    albedo = np.array([0.55, 0.12, 0.08])
    irr = irradiance_lookup(irradiance_table(env), n[obj].reshape(-1, 3))
    rgb = np.zeros((H, W, 3))
    rgb[obj] = albedo * irr / np.pi
    spec = np.zeros((H, W, 2))
    spec[obj] = (0.6, 800.0)
    spheres = SphereSet(centre[None], np.array([radius]))
    results = {}
    from render.composite.pipeline import Compositor

    comp = Compositor(ctx)  # reused: programs, environment, light sources and shadow grid set up once
    for glare in (False, True):
        st = {}
        img = composite_frame(ctx, rgb, z, cam, env, spheres=spheres, exposure=1.0, glare=glare, specular=spec,
                              normals=n, sg_fit=fit, stats=st, glare_config=PICTURE_GLARE, compositor=comp)
        results[("first_" if glare else "first_no_") + "glare_total_ms"] = st["total_ms"]
        if "shadow_ms" in st:
            results.setdefault("shadow_grid_ms", st["shadow_ms"])  # computed once (cached by the Compositor)
        # second call: the steady-state frame cost
        st = {}
        img = composite_frame(ctx, rgb, z, cam, env, spheres=spheres, exposure=1.0, glare=glare, specular=spec,
                              normals=n, sg_fit=fit, stats=st, glare_config=PICTURE_GLARE, compositor=comp)
        results["glare" if glare else "no_glare"] = {k: v for k, v in st.items() if not isinstance(v, list)}
        out_dir.mkdir(parents=True, exist_ok=True)
        path = out_dir / f"composite_{env_name}_{'glare' if glare else 'plain'}.png"
        import imageio.v3 as iio
        iio.imwrite(path, to_uint8_srgb(img))
        results["glare" if glare else "no_glare"]["png"] = str(path)
    comp.release()
    results["sg_fit_s"] = fit.seconds
    return results


def composite_captured(ctx, model_dir: Path, scans: Path, view: int, env_name: str, out_dir: Path) -> dict:
    """A captured view (its colour + depth) composited into the map with the model's sphere-set
    shadow (ground at the spheres' lowest point) and glare; PNG + shadow-ratio PNG written."""
    import imageio.v3 as iio

    from capture.io import read_scanset
    from capture.scan import to_uint8_srgb
    from render.composite.pipeline import composite_frame
    from render.shading.envmap import bundled_envmap
    from volume.model import load_model

    ss = read_scanset(scans)
    m = load_model(model_dir)
    sc = ss.scans[view]
    env = bundled_envmap(env_name)
    st = {}
    img = composite_frame(ctx, sc.linear_rgb, sc.depth, sc.camera, env, spheres=m.spheres, glare=True, stats=st)
    a = composite_frame(ctx, sc.linear_rgb, sc.depth, sc.camera, env, spheres=m.spheres, glare=False, output="linear")
    b = composite_frame(ctx, sc.linear_rgb, sc.depth, sc.camera, env, spheres=m.spheres, ground=False, glare=False,
                        output="linear")
    ratio = np.clip((a.sum(-1) + 1e-9) / (b.sum(-1) + 1e-9), 0, 1)
    out_dir.mkdir(parents=True, exist_ok=True)
    p = out_dir / f"composite_{Path(scans).name}_{env_name}.png"
    iio.imwrite(p, to_uint8_srgb(img))
    pr = out_dir / f"composite_{Path(scans).name}_{env_name}_shadow_ratio.png"
    iio.imwrite(pr, np.round(ratio * 255).astype(np.uint8))
    return {"png": str(p), "ratio_png": str(pr), "spheres": len(m.spheres), "min_ratio": float(ratio.min()),
            **{k: v for k, v in st.items() if not isinstance(v, list)}}


def _plot(rows, out_dir: Path) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for s in SUPERSAMPLES:
        r = [x for x in rows if x["supersample"] == s]
        n = [x["bright_pixels"] for x in r]
        ax[0].loglog(n, [x["gl_ms"] for x in r], "o-", label=f"GL, s={s}")
        ax[1].semilogx(n, [100 * x["energy_rel_err"] for x in r], "o-", label=f"s={s}")
    r = [x for x in rows if x["supersample"] == SUPERSAMPLES[0]]
    ax[0].loglog([x["bright_pixels"] for x in r], [x["setup_ms"] for x in r], "k--", label="CPU streak setup")
    ax[0].set_xlabel("bright pixels")
    ax[0].set_ylabel("ms per frame")
    ax[0].legend()
    ax[0].set_title("glare cost vs bright pixels")
    ax[1].set_xlabel("bright pixels")
    ax[1].set_ylabel("|streak light / excess - 1| (%)")
    ax[1].set_title("streak energy: GL vs analytic on screen")
    ax[1].legend()
    return save_figure(fig, out_dir / "glare_cost.png")


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="furrow bench glare", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", default="640x480",
                    help=f"frame WxH (default 640x480; each side above {2 * THIN_MARGIN_PX} px)")
    ap.add_argument("--counts", default="10,100,1000,3000,10000")
    ap.add_argument("--env", default="studio")
    ap.add_argument("-o", "--out", default=str(OUT_ROOT / "bench" / "glare"))
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--model", help="a furrow model folder: also composite a captured view with its sphere shadow")
    ap.add_argument("--scans", help="the scan set of --model")
    ap.add_argument("--view", type=int, default=4, help="index of the captured view for --model")
    a = ap.parse_args(argv)
    try:
        W, H = (int(v) for v in a.size.lower().split("x"))
    except ValueError:
        ap.error(f"--size must be WxH in pixels, got {a.size!r}")
    if min(W, H) <= 2 * THIN_MARGIN_PX:
        ap.error(f"--size {a.size}: each side must be above {2 * THIN_MARGIN_PX} px (the thin pairs' energy test keeps "
                 f"its highlights {THIN_MARGIN_PX} px from the border)")
    counts = [int(c) for c in a.counts.split(",")]
    out_dir = Path(a.out)
    from render.gl import gl_context

    with gl_context() as ctx:
        rows = bench_cost(ctx, W, H, counts)
        thin = bench_energy_thin(ctx, W, H)
        comp = bench_composite(ctx, W, H, a.env, out_dir)
        captured = (composite_captured(ctx, Path(a.model), Path(a.scans), a.view, a.env, out_dir)
                    if a.model and a.scans else None)
    plot = _plot(rows, out_dir)
    res = {"size": [W, H], "cost": rows, "energy": thin, "composite": comp, "captured": captured, "plot": str(plot)}
    if a.json:
        print(json.dumps(res, indent=1))
        return 0
    from rich.table import Table

    from furrow.console import console

    t = Table(title=f"glare cost vs bright pixels ({W}x{H}, llvmpipe)")
    for c in ("bright px", "pairs", "s", "setup ms", "GL ms", "energy err %"):
        t.add_column(c, justify="right")
    for r in rows:
        t.add_row(str(r["bright_pixels"]), str(r["pairs"]), str(r["supersample"]), f"{r['setup_ms']:.1f}",
                  f"{r['gl_ms']:.1f}", f"{100 * r['energy_rel_err']:.3f}")
    console.print(t)
    t = Table(title="streak energy, all pairs on screen (200 highlights)")
    for c in ("n", "median width px", "s", "energy err %"):
        t.add_column(c, justify="right")
    for r in thin:
        t.add_row(f"{r['n']:.0f}", f"{r['width_px']:.2f}", str(r["supersample"]), f"{100 * r['energy_rel_err']:.3f}")
    console.print(t)
    t = Table(title=f"composite frame {W}x{H}, steady state ({a.env}; once per map: SG fit {comp['sg_fit_s']:.2f} s, "
                    f"first frame {comp['first_no_glare_total_ms']:.0f} ms incl. shadow grid "
                    f"{comp.get('shadow_grid_ms', 0):.0f} ms)")
    for c in ("", "comp ms", "glare ms", "bright px", "total ms", "picture"):
        t.add_column(c)
    for k in ("no_glare", "glare"):
        r = comp[k]
        t.add_row(k, f"{r['composite_ms']:.1f}", f"{r.get('glare_ms', 0):.1f}",
                  str(r.get("bright_pixels", "-")), f"{r['total_ms']:.1f}", Path(r["png"]).name)
    console.print(t)
    if captured:
        console.print(f"captured view ({captured['spheres']} spheres): shadow {captured.get('shadow_ms', 0):.0f} ms, "
                      f"composite {captured['composite_ms']:.0f} ms, glare {captured.get('glare_ms', 0):.0f} ms, "
                      f"min shadow ratio {captured['min_ratio']:.2f} -> {captured['png']}")
    console.print(f"plot: {plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
