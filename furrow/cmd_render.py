"""``furrow render MODEL --cameras TRANSFORMS -o DIR``: render a model from given cameras."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

HELP = "render a model with view-dependent microfacet billboards (or the fixed-mesh baseline)"
DESCRIPTION = """Render a furrow model (from `furrow model`) from the cameras of a transforms.json, one
PNG per selected frame, named after the frame's file_path basename, black background,
8-bit sRGB.  METHODS §1.2-1.7: the pyramid level and slice spacing follow the screen-space
tolerance E (--tolerance, pixels; the paper's default 8).

examples:
  furrow render out/fur_model --cameras out/furball/transforms.json -o out/renders
  furrow render out/fur_model --cameras out/furball --frames 1::2 --tolerance 4 -o out/r4
  furrow render out/fur_model --cameras out/furball --orbit 72 -o out/orbit
  furrow render out/fur_model --cameras out/furball --method mesh-vdtm -o out/baseline"""

METHODS = ("microfacet", "mesh-vdtm", "mesh-colour")
#: Orbit: elevation offset (degrees) and distance factor relative to the mean input camera.
ORBIT_FRAMES_DEFAULT = 36


#: Default samples per pixel and axis (render.antialias; README "Where the design moved").
DEFAULT_SUPERSAMPLE = 2


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", type=Path, help="model folder written by `furrow model`")
    p.add_argument("--cameras", type=Path, required=True, help="transforms.json (or a folder holding one) with the cameras")
    p.add_argument("--frames", default=None, help="frames to render, python slice style: '1::2', '3', '0,4,8' (default all)")
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder")
    p.add_argument("--method", choices=METHODS, default="microfacet",
                   help="microfacet (default), mesh-vdtm (fixed-mesh baseline) or mesh-colour (per-vertex colour floor)")
    p.add_argument("--tolerance", type=float, default=8.0, help="screen-space tolerance E in pixels (default 8)")
    p.add_argument("--level", type=int, default=None, help="force this pyramid resolution L (e.g. 64) instead of Eq. 11")
    p.add_argument("--supersample", type=int, default=DEFAULT_SUPERSAMPLE, metavar="S",
                   help=f"anti-aliasing: S x S samples per pixel, box-resolved (default {DEFAULT_SUPERSAMPLE}; 1 = off, "
                        "about S^2 x the fill cost)")
    p.add_argument("--refine", type=int, default=None, metavar="N",
                   help="microfacet parallax correction: steps along the eye ray to each camera's depth "
                        "(default 2; 0 = the paper's colour at the slice point)")
    p.add_argument("--mode", choices=["instanced", "geometry"], default="instanced",
                   help="microfacet slice generation: compute + instancing (default) or geometry shader")
    p.add_argument("--orbit", type=int, default=None, metavar="N",
                   help="instead of the given frames: a turntable of N frames around the rig's up axis (estimated "
                        "from the cameras) at their mean distance and height, with the first camera's intrinsics")
    g = p.add_argument_group("environment compositing (METHODS §3-§4)")
    g.add_argument("--env", default=None, metavar="MAP",
                   help="composite the object into an HDR environment: a .exr/.hdr equirect map or a bundled name "
                        "(studio, courtyard, forest, sunset); background from the map, tone mapped")
    g.add_argument("--ground", action="store_true",
                   help="with --env: the object's shadow on a ground plane under it, from its sphere set (SSDF)")
    g.add_argument("--exposure", type=float, default=1.0, help="with --env: linear exposure factor (default 1)")
    g.add_argument("--no-glare", action="store_true", help="with --env: no glare streaks on over-bright pixels")
    g.add_argument("--env-rotation", type=float, default=0.0, help="with --env: rotate the map about its up axis (deg)")
    p.add_argument("--debug", action="store_true", help="show tracebacks")


def run(args, console) -> int:
    from capture.imageio import write_png
    from capture.io import read_cameras
    from capture.scan import select_indices, to_uint8_srgb
    from furrow.console import StageTimer, track
    from render.gl import gl_context
    from volume.model import load_model

    from render.antialias import check_factor

    check_factor(args.supersample)
    if args.refine is not None and args.method != "microfacet":
        raise ValueError("--refine applies to --method microfacet only")
    from render.microfacet import MAX_REFINE

    if args.refine is not None and not 0 <= args.refine <= MAX_REFINE:
        raise ValueError(f"--refine must be 0..{MAX_REFINE} steps, got {args.refine}")
    if (args.ground or args.exposure != 1.0 or args.no_glare) and not args.env:
        raise ValueError("--ground, --exposure and --no-glare need --env MAP")
    timer = StageTimer()
    with timer.stage("load model"):
        model = load_model(args.model)
    frames = read_cameras(args.cameras)
    if args.orbit is not None:
        from capture.orbit import orbit_cameras

        views = [(c, c.name) for c in orbit_cameras([f.camera for f in frames], args.orbit,
                                                     center=np.asarray(model.bounds).mean(axis=0))]
    else:
        idx = select_indices(args.frames, len(frames))
        views = [(frames[i].camera, Path(frames[i].file_path).name) for i in idx]
        names = [v[1] for v in views]
        if len(set(names)) != len(names):
            raise ValueError(f"{args.cameras}: several selected frames share a file name; output names would clash")
    level = None
    if args.level is not None:
        res = model.pyramid.resolutions
        if args.level not in res:
            raise ValueError(f"--level {args.level}: the model has levels {res}")
        level = res.index(args.level)
    env = None
    if args.env:
        if args.method != "microfacet":
            raise ValueError("--env compositing needs --method microfacet (it uses the rendered depth)")
        from capture.orbit import estimate_up
        from render.shading.envmap import bundled_envmap, load_envmap

        p = Path(args.env)
        env = load_envmap(p) if p.suffix.lower() in (".exr", ".hdr") else bundled_envmap(args.env)
        if args.env_rotation:
            env = env.rotated(np.radians(args.env_rotation))
        up = estimate_up([f.camera for f in frames])
    args.out.mkdir(parents=True, exist_ok=True)
    stats = []
    with gl_context() as ctx:
        compositor = None
        if env is not None:
            from render.composite import Compositor

            compositor = Compositor(ctx)
        if args.method == "microfacet":
            from render.microfacet import MicrofacetRenderer

            r = MicrofacetRenderer.from_model(ctx, model, mode=args.mode, refine=args.refine)
        elif args.method == "mesh-vdtm":
            from render.vdtm import VdtmRenderer

            r = VdtmRenderer.from_model(ctx, model)
        else:
            r = None
        if r is not None and views:  # warm-up: llvmpipe compiles shaders on the first draw
            if args.method == "microfacet":
                r.render(views[0][0], args.tolerance, level=level, read=False, supersample=args.supersample)
            else:
                r.render(views[0][0], read=False, supersample=args.supersample)
        with timer.stage(f"render {len(views)} frames ({args.method})"):
            for cam, name in track(views, "rendering", total=len(views)):
                if args.method == "microfacet":
                    fr = r.render(cam, args.tolerance, level=level, supersample=args.supersample)
                    st = {"file": name, "ms": fr.ms, "facets": fr.facets, "level": fr.resolution,
                          "spacing_m": fr.spacing}
                elif args.method == "mesh-vdtm":
                    fr = r.render(cam, supersample=args.supersample)
                    st = {"file": name, "ms": fr.ms, "facets": fr.facets}
                else:
                    from render.vdtm import render_vertex_colour

                    fr = render_vertex_colour(ctx, model, cam)
                    st = {"file": name, "ms": fr.ms, "facets": fr.facets}
                out_name = name if name.lower().endswith(".png") else Path(name).stem + ".png"
                img = fr.rgb
                if compositor is not None:
                    from render.composite import composite_frame

                    # the compositor takes a binary object mask (depth > 0): un-premultiply the
                    # supersampled edge pixels (their samples were averaged with black)
                    cov = fr.coverage if fr.coverage is not None else fr.alpha.astype(np.float32)
                    obj = np.where(cov[..., None] > 0, fr.rgb / np.maximum(cov, 1e-6)[..., None], 0.0)
                    img = composite_frame(ctx, obj.astype(np.float32), fr.depth, cam, env,
                                          spheres=model.spheres if args.ground else None,
                                          ground=None if args.ground else False, exposure=args.exposure,
                                          glare=not args.no_glare, up=up, compositor=compositor)
                write_png(args.out / out_name, to_uint8_srgb(img))
                stats.append(st)
        if r is not None:
            r.release()
        if compositor is not None:
            compositor.release()
    (args.out / "render_stats.json").write_text(json.dumps({"method": args.method, "tolerance_px": args.tolerance,
                                                            "supersample": args.supersample, "frames": stats}, indent=1))
    ms = [s["ms"] for s in stats]
    console.print(f"[green]wrote[/] {len(stats)} images to {args.out}  (mean {np.mean(ms):.1f} ms/frame, "
                  f"mean facets {np.mean([s['facets'] for s in stats]):.0f})")
    console.print(timer.table())
    return 0
