"""``furrow bench ambient``: the ambient (diffuse) term of the synthetic ground-truth renderer
against the brute-force irradiance integral (datasets_synthetic/lighting.py, docs/methods.md §2-§3).

The synthetic renderer lights a scene with K dominant lights (shadow-mapped) plus the diffuse
irradiance of the environment minus those lights.  Before 2026-11-22 that residual was lit by its
SH9 projection; now by the exact irradiance table (render.shading.irradiance).  For every bundled
map this prints both against ``irradiance_brute`` of the same residual map at random normals:
mean / max relative error, and the worst error relative to the brightest ambient irradiance.
Second table: a rendered white sphere (albedo 0.8, ambient only, the scene's exposure) from the
GL shaded raster mode with each ambient, against the same brute force at every pixel's normal:
mean / max |error| in 8-bit levels of linear radiance (1/255).

    furrow bench ambient [--normals 500] [--lights 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="furrow bench ambient", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--normals", type=int, default=500, help="random unit normals compared")
    p.add_argument("--lights", type=int, default=3, help="dominant lights removed from the map")
    p.add_argument("--json", action="store_true", help="print the results as JSON on stdout")
    a = p.parse_args(argv)
    from datasets_synthetic.lighting import LightingConfig, ambient_accuracy, resolve_env
    from render.shading.envmap import BUNDLED_NAMES

    rows = []
    for name in BUNDLED_NAMES:
        t = time.perf_counter()
        r = ambient_accuracy(resolve_env(name), LightingConfig(env=name, lights=a.lights), normals=a.normals)
        r["seconds"] = time.perf_counter() - t
        rows.append(r)
    for r in rows:
        r["sphere"] = _sphere_image_error(r["env"], a.lights)
    if a.json:
        print(json.dumps(rows, indent=1))
        return 0
    from rich.table import Table

    from furrow.console import console

    t = Table(title=f"ambient irradiance of env minus {a.lights} lights vs brute force ({a.normals} normals)")
    for c in ("map", "SH9 mean rel", "SH9 max rel", "SH9 max/peak",
              "table mean rel", "table max rel", "table max/peak"):
        t.add_column(c)
    for r in rows:
        t.add_row(r["env"], *(f"{100 * r[k][m]:.2f}%" for k in ("sh9", "table")
                              for m in ("mean_rel", "max_rel", "max_of_peak")))
    console.print(t)
    t = Table(title="rendered sphere, ambient only: |GL - brute force| in 1/255 of linear radiance")
    for c in ("map", "SH9 mean", "SH9 max", "table mean", "table max", "pixels"):
        t.add_column(c)
    for r in rows:
        sp = r["sphere"]
        t.add_row(r["env"], *(f"{sp[k][m]:.2f}" for k in ("sh9", "table") for m in ("mean_255", "max_255")),
                  str(sp["pixels"]))
    console.print(t)
    return 0


def _sphere_image_error(name: str, lights: int) -> dict:
    """Ambient-only render of a white sphere (GL shaded mode) vs the brute-force irradiance."""
    from dataclasses import replace

    import numpy as np

    from capture.camera import Camera, look_at, make_K
    from datasets_synthetic.lighting import LightingConfig, ambient_residual, resolve_env, scene_lighting
    from render.gl import create_context
    from render.mesh.glossy.gl import uv_sphere
    from render.mesh.raster.gl import MeshRasterizer, RasterMesh
    from render.shading.sh import irradiance_brute

    env = resolve_env(name)
    cfg = LightingConfig(env=name, lights=lights, shadows=False)
    lt, _ = scene_lighting(env, cfg)
    rest = ambient_residual(env, cfg)
    v, f, n, _ = uv_sphere(0.1, 48)
    albedo = 0.8
    mesh = RasterMesh(v, f, np.full((len(v), 3), albedo), normals=n)
    W = H = 96
    cam = Camera(make_K(2.5 * W, 2.5 * W, (W - 1) / 2, (H - 1) / 2),
                 look_at(np.array([0.3, -0.3, 0.2]), (0, 0, 0)), W, H)
    amb = replace(lt, light_colors=np.zeros_like(lt.light_colors))
    out = {}
    ctx = create_context()
    try:
        with MeshRasterizer(ctx) as r:
            r.set_mesh(mesh)
            for key, l in (("table", amb), ("sh9", replace(amb, irradiance=None))):
                r.set_lighting(l)
                res = r.render(cam)
                m = res.mask
                if "ref" not in out:
                    ref = np.zeros_like(res.color, dtype=np.float64)
                    ref[m] = lt.exposure * albedo / np.pi * irradiance_brute(rest, res.normal[m].astype(np.float64))
                    out["ref"] = ref
                d = np.abs(res.color - out["ref"])[m] * 255
                out[key] = {"mean_255": float(d.mean()), "max_255": float(d.max())}
                out["pixels"] = int(m.sum())
    finally:
        ctx.release()
    del out["ref"]
    return out


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
