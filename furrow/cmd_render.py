"""``furrow render MODEL --cameras TRANSFORMS -o DIR``: render a model from given cameras."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from render.methods import DEFAULT_METHOD, RenderOptions, method_names

HELP = "render a model from new cameras (gather by default; microfacets, point splatting, mesh baselines)"
DESCRIPTION_HEAD = """Render a furrow model (from `furrow model`) from the cameras of a transforms.json, one
PNG per selected frame, named after the frame's file_path basename: 8-bit sRGB RGBA with the
object's soft alpha (straight colour, as PNG stores it), or flattened RGB over --background
COLOUR|MAP or composited into --env MAP (linear light: premultiplied + (1 - alpha) background).
--video writes the flattened frames (over black unless --background / --env say otherwise).
Methods (--method; each one's spec in render/NAME/spec.py, registered in render.methods.METHODS):"""
DESCRIPTION_TAIL = """Every method can be composited with --env; a flag the chosen method does not read is an error.

examples:
  furrow render out/fur_model --cameras out/furball/transforms.json -o out/renders
  furrow render out/fur_model --cameras out/furball --frames 1::2 --method microfacet --tolerance 4 -o out/r4
  furrow render out/fur_model --cameras out/furball --orbit 72 -o out/orbit
  furrow render out/fur_model --cameras out/furball --orbit 120 --video out/orbit.mp4 --fps 30
  furrow render out/fur_model --cameras out/furball --method mesh-vdtm -o out/baseline
  furrow render out/fur_model --cameras out/furball --relight sunset -o out/relit
  furrow render out/fur_model --cameras out/furball --relight --env sunset --ground -o out/relit_env
  furrow render out/fur_model --cameras out/furball --background white -o out/on_white
  furrow render out/fur_model --cameras out/furball --background 235,235,235 -o out/product"""

#: Frames per second of --video.
DEFAULT_FPS = 24.0


def description() -> str:
    """The --help text: the methods' entries come from their specs (furrow.method_flags)."""
    from furrow.method_flags import methods_help

    return f"{DESCRIPTION_HEAD}\n{methods_help(DEFAULT_METHOD)}\n{DESCRIPTION_TAIL}"


def add_arguments(p: argparse.ArgumentParser) -> None:
    from furrow.method_flags import add_option_arguments

    p.add_argument("model", type=Path, help="model folder written by `furrow model`")
    p.add_argument("--cameras", type=Path, required=True,
                   help="transforms.json (or a folder holding one) with the cameras")
    p.add_argument("--frames", default=None,
                   help="frames to render, python slice style: '1::2', '3', '0,4,8' (default all)")
    p.add_argument("-o", "--out", type=Path, default=None,
                   help="output folder for the PNG frames and render_stats.json (required unless --video is given)")
    p.add_argument("--video", type=Path, default=None, metavar="OUT.mp4",
                   help="also (or, without -o, only) write the frames as an H.264 MP4 "
                        "(render.composite.video.write_mp4)")
    p.add_argument("--fps", type=float, default=DEFAULT_FPS,
                   help=f"frames per second of --video (default {DEFAULT_FPS:g})")
    p.add_argument("--method", choices=method_names(), default=DEFAULT_METHOD,
                   help=f"rendering method (default {DEFAULT_METHOD}; see above)")
    add_option_arguments(p)
    p.add_argument("--orbit", type=int, default=None, metavar="N",
                   help="instead of the given frames: a turntable of N frames around the rig's up axis (estimated "
                        "from the cameras) at their mean distance and height, with the first camera's intrinsics")
    p.add_argument("--background", default=None, metavar="COLOUR|MAP",
                   help="flatten the output over a background in linear light (premultiplied + (1 - alpha) B): a "
                        "colour name or #hex (white, #ebebeb), an sRGB triple (235,235,235 or 0.92,0.92,0.92), or an "
                        "environment map (bundled name or .exr/.hdr; seen from the camera, not tone mapped). Without "
                        "it (and without --env) the PNGs are RGBA with straight alpha")
    g = p.add_argument_group("environment compositing (docs/methods.md §3-§4)")
    g.add_argument("--env", default=None, metavar="MAP",
                   help="composite the object into an HDR environment: a .exr/.hdr equirect map or a bundled name "
                        "(studio, courtyard, forest, sunset); background from the map, tone mapped")
    g.add_argument("--ground", action="store_true",
                   help="with --env: the object's shadow on a ground plane under it, from its sphere set (SSDF)")
    g.add_argument("--exposure", type=float, default=1.0, help="with --env: linear exposure factor (default 1)")
    g.add_argument("--no-glare", action="store_true", help="with --env: no glare streaks on over-bright pixels")
    from furrow.relight_flags import add_map_orientation_arguments

    add_map_orientation_arguments(g, "--env and --relight")
    from furrow.relight_flags import add_relight_arguments

    add_relight_arguments(p)
    p.add_argument("--debug", action="store_true", help="show tracebacks")


def render_options(args) -> RenderOptions:
    """The RenderOptions of the flags given (the rest default); a flag the method ignores is an
    error (furrow.method_flags)."""
    from furrow.method_flags import render_options as from_flags

    return from_flags(args, [args.method])


def select_views(args, model) -> tuple[list, list]:
    """(camera, output file name) of every frame to render, and the input cameras."""
    from capture.io import read_cameras
    from capture.scan import select_indices

    frames = read_cameras(args.cameras)
    inputs = [f.camera for f in frames]
    if args.orbit is not None:
        from capture.orbit import orbit_cameras

        cams = orbit_cameras(inputs, args.orbit, center=np.asarray(model.bounds).mean(axis=0))
        views = [(c, c.name) for c in cams]
    else:
        views = [(frames[i].camera, Path(frames[i].name).name) for i in select_indices(args.frames, len(frames))]
        names = [v[1] for v in views]
        if len(set(names)) != len(names):
            raise ValueError(f"{args.cameras}: several selected frames share a file name; output names would clash")
    return [(c, n if n.lower().endswith(".png") else Path(n).stem + ".png") for c, n in views], inputs


def load_env(args):
    """The environment map of --env (rotated by --env-rotation), or None."""
    if not args.env:
        return None
    from render.shading.envmap import named_envmap

    return named_envmap(args.env, args.env_convention, args.env_rotation)


def load_background(args):
    """The --background (render.composite.background.Background) or None; an error with --env."""
    if args.background is None:
        return None
    if args.env:
        raise ValueError("--background and --env both give the background: choose one")
    from render.composite.background import parse_background

    return parse_background(args.background)


def composite(ctx, frame, cam, env, args, model, up, compositor) -> np.ndarray:
    """The frame composited into the environment with its matte (docs/methods.md §3-§4)."""
    from render.composite.pipeline import composite_frame

    return composite_frame(ctx, frame.rgb, frame.depth, cam, env, alpha=frame.alpha,
                           spheres=model.spheres if args.ground else None, ground=None if args.ground else False,
                           exposure=args.exposure, glare=not args.no_glare, up=up, compositor=compositor)


def output_images(frame, cam, background, up, composite_env) -> tuple[np.ndarray, np.ndarray]:
    """(PNG image, video frame) of a rendered frame: --env composite (``composite_env()``), or the
    frame over --background, both RGB; else RGBA straight alpha for the PNG and over black for
    the video (render.composite.background)."""
    from capture.scan import to_uint8_srgb
    from render.composite.background import background_image, flatten, rgba8

    if composite_env is not None:
        img = to_uint8_srgb(composite_env())
        return img, img
    if background is not None:
        img = to_uint8_srgb(np.clip(flatten(frame.rgb, frame.alpha, background_image(background, cam, up)), 0, 1))
        return img, img
    return rgba8(frame.rgb, frame.alpha), to_uint8_srgb(frame.rgb)


def run(args, console) -> int:
    from contextlib import ExitStack

    from capture.atomic import write_json
    from capture.imageio import write_png
    from furrow.console import StageTimer, track
    from furrow.relight_flags import open_relighter
    from render.gl import gl_context
    from render.methods import create_renderer, options_record, samples_per_pixel_side
    from volume.model import load_model

    if args.out is None and args.video is None:
        raise ValueError("give -o DIR for PNG frames and/or --video OUT.mp4")
    if args.video is not None and args.video.suffix.lower() != ".mp4":
        raise ValueError(f"--video {args.video}: write an .mp4 file")
    options = render_options(args)
    if (args.ground or args.exposure != 1.0 or args.no_glare) and not args.env:
        raise ValueError("--ground, --exposure and --no-glare need --env MAP")
    background = load_background(args)
    timer = StageTimer()
    with timer.stage("load model"):
        model = load_model(args.model)
    views, inputs = select_views(args, model)
    env = load_env(args)
    up = None
    if env is not None or (background is not None and background.env is not None):
        from capture.orbit import estimate_up

        up = estimate_up(inputs)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    stats = []
    with gl_context() as ctx, ExitStack() as owned:
        r = owned.enter_context(create_renderer(args.method, ctx, model, options))
        relighter = open_relighter(args, ctx, model, owned)  # None without --relight
        compositor = None
        if env is not None:
            from render.composite.pipeline import Compositor

            compositor = owned.enter_context(Compositor(ctx))
        if views:  # warm-up: llvmpipe compiles shaders on the first draw
            r.render(views[0][0], read=False)

        def frames():
            for cam, name in track(views, "rendering", total=len(views)):
                fr = r.render(cam)
                if relighter is not None:
                    fr = relighter.apply(fr, cam)
                comp = None if compositor is None else (
                    lambda fr=fr, cam=cam: composite(ctx, fr, cam, env, args, model, up, compositor))
                png, video_frame = output_images(fr, cam, background, up, comp)
                if args.out is not None:
                    write_png(args.out / name, png)
                stats.append({"file": name, **fr.stats.record(),
                              **({"relight_ms": relighter.last_ms} if relighter is not None else {})})
                yield video_frame

        with timer.stage(f"render {len(views)} frames ({args.method})"):
            if args.video is not None:
                from render.composite.video import write_mp4

                write_mp4(frames(), args.video, args.fps)
            else:
                for _ in frames():
                    pass
    record = {"method": args.method, "supersample": samples_per_pixel_side(args.method, options),
              "options": options_record(options, args.method), "frames": stats}
    if args.out is not None:
        write_json(args.out / "render_stats.json", record)
    if args.video is not None:
        console.print(f"[green]wrote[/] {len(stats)} frames to {args.video} (H.264, {args.fps:g} fps)", highlight=False)
    ms = [s["ms"] for s in stats]
    facets = [s["facets"] for s in stats if "facets" in s]
    console.print(f"[green]rendered[/] {len(stats)} frames{f' to {args.out}' if args.out else ''}  (mean "
                  f"{np.mean(ms):.1f} ms/frame" + (f", mean facets {np.mean(facets):.0f})" if facets else ")"))
    console.print(timer.table())
    return 0
