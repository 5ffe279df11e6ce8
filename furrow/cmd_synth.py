"""``furrow synth NAME -o DIR``: write a synthetic turntable capture with exact ground truth."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = ("synthesise a turntable capture of a procedural scene (furball, plant, torus, furrybunny) with exact "
        "ground truth")
DESCRIPTION = """Render a seeded procedural scene from a turntable rig (world +z up, cameras ringing the z axis,
looking at the origin) under an environment map, and write a scan set: transforms.json,
images/ (8-bit sRGB), depth/ (z-depth as an RGB-D sensor writes it: 16-bit PNG in millimetres, with
one top-level "depth_unit_scale_factor": 0.001 in transforms.json, as nerfstudio reads it; or
--depth-format png-0.1mm / exr) and gt/ (gt/mesh.ply exact geometry in metres, gt/scene.json
parameters, gt/cameras_true.json when the recorded poses are perturbed) and masks/ (the object's
true alpha matte, 8-bit, its pixel coverage under the film filter; keyed per frame as mask_path).

Real captures see the room behind the object and the table under it: --background env|clutter
puts the lighting map or a cluttered room behind the object, --support disc|table a turntable or
a table top under it (in colour and in depth); --background-frames 0::2 keeps the other views over
black, as the evaluation captures' held-out views are (furrow eval SCANS --holdout 2).

Colour is reconstructed with a Gaussian film filter of --pixel-filter pixels (default 0.5, the
default of pbrt-v4 and Mitsuba 3), as a path tracer's images are; 0 keeps the 1-pixel box.

The depth carries the traits of a sensor (--sensor, datasets_synthetic/sensor.py): d435 (default;
Intel RealSense D435 active stereo: z-squared noise 3.6 mm at 1 m, 1 mm output unit, flying pixels
on 30 % of the depth-edge pixels), kinect-v1 (structured light: 1.4 mm at 1 m, disparity steps of
2.9 mm at 1 m), or ideal (exact float depth; then only the file format quantises).

Relighting ground truth: --relight-env MAP (repeatable) renders every view again under MAP with
the same scene, cameras and exposure, into DIR/relit/MAP/images/NAME.png beside
DIR/relit/MAP/transforms.json (the capture's cameras; depth from the capture's depth/) and
DIR/relit/MAP/lighting.json (map, exposure, lights, clipped fraction); MAP is a bundled name or a
file, its folder the name or the file's stem.

Strands (fur, needles) are shaded with the R / TT / TRT lobes of Chiang et al. 2016 under the
environment's dominant lights and 32 median-cut lights with shadow maps (--hair chiang, default),
or with the older Kajiya-Kay lobe (--hair kajiya-kay).  The GL renderer (--synth-renderer gl,
default) draws each strand segment as the tube's facets facing the camera and evaluates the lobes
and the shadow lookups on the GPU (llvmpipe without one); --synth-renderer numpy draws the whole
tubes and evaluates the lobes in numpy, the reference it is tested against (same images to the
tolerances of docs/synthetic.md, 5-6 times slower).

scenes: furball  ellipsoidal body with thousands of thin curved strands (real tube geometry)
        plant    pot, stem, branches with many thin needles, a few flat leaves
        torus    smooth control object
        furrybunny  fur grown on a real scanned surface (the Stanford Bunny that ships in pymeshlab's
                 test data; licence noted in datasets_synthetic/scanned.py)

examples:
  furrow synth furball -o out/furball_scan --preview
  furrow synth plant -o out/plant_small --small
  furrow synth furball -o out/furball_relit --relight-env forest --relight-env sunset
  furrow synth plant -o out/plant_room --background env --support table --background-frames 0::2
  furrow synth torus -o out/torus_noisy --depth-noise 0.002 --holes 0.02 --grazing 75 \\
      --pose-noise-deg 1 --pose-noise-frac 0.01"""

#: --small: the CI-sized capture (12 views, 160x120, a lighter fur ball).
SMALL_VIEWS = 12
SMALL_SIZE = (160, 120)
SMALL_STRANDS = 5000
#: --small: median-cut lights of the hair shading (32 at full size; each costs a shadow map).
SMALL_HAIR_ENV_LIGHTS = 8
#: Scenes with a --strands parameter.
FURRY_SCENES = ("furball", "furrybunny")


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"bad size {text!r}: use WIDTHxHEIGHT, e.g. 640x480") from None
    if w < 8 or h < 8 or w > 8192 or h > 8192:
        raise argparse.ArgumentTypeError(f"size {w}x{h} out of range (8..8192)")
    return w, h


def _floats(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"bad list {text!r}: use comma-separated numbers, e.g. 15,45") from None


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("name", help="scene: furball, plant, torus or furrybunny")
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder (new, or --overwrite)")
    p.add_argument("--views", type=int, default=None, help="number of views (default 36; --small: 12)")
    p.add_argument("--size", type=_size, default=None,
                   help="image size WIDTHxHEIGHT (default 640x480; --small: 160x120)")
    p.add_argument("--seed", type=int, default=0, help="seed of the geometry and of the noise (default 0)")
    p.add_argument("--small", action="store_true", help="CI-sized capture: 12 views at 160x120")
    p.add_argument("--strands", type=int, default=None,
                   help="furball / furrybunny: number of strands (default 20000; --small: 5000)")
    p.add_argument("--curly", action="store_true",
                   help="furball: the harder fur ball of the registration bench (datasets_synthetic/fur_variants.py "
                        "CURLY: tight strong curl, longer strands, 14 dark / light melanin patches); --curl, "
                        "--curl-turns and --patches override its values")
    p.add_argument("--curl", type=float, default=None, help="furball: amplitude of the strands' helical curl "
                   "(default 0.3; --curly 0.9)")
    p.add_argument("--curl-turns", type=float, default=None, help="furball: turns of the curl over a strand "
                   "(default 0.8; --curly 2.5)")
    p.add_argument("--patches", type=int, default=None, help="furball: dark and light melanin patches over the coat "
                   "(default 0; --curly 14)")
    p.add_argument("--coat", choices=["tabby", "uniform"], default=None,
                   help="furball: tabby (stripes and a cream belly, default) or uniform (one brown coat on a "
                        "spherical body, the same from every side at coarse scale: the near-symmetric hard case "
                        "of registration, datasets_synthetic/fur_variants.py UNIFORM)")
    p.add_argument("--elevations", type=_floats, default=(15.0,),
                   help="ring elevations in degrees, comma-separated (views are split evenly; default 15, the "
                        "rig of the evaluation captures)")
    p.add_argument("--fov", type=float, default=36.0, help="vertical field of view in degrees (default 36)")
    p.add_argument("--env", default="studio",
                   help="environment: studio, courtyard, forest, sunset, procedural, or a .exr/.hdr path")
    p.add_argument("--env-rotation", type=float, default=0.0, help="rotate the environment about +z (degrees)")
    p.add_argument("--relight-env", action="append", default=[], metavar="MAP",
                   help="also render every view under MAP (same scene, cameras, exposure) into relit/MAP/ "
                        "(repeatable; see above)")
    p.add_argument("--hair", choices=["chiang", "kajiya-kay"], default="chiang",
                   help="strand shading: chiang (R/TT/TRT lobes, default) or kajiya-kay (the older lobe)")
    p.add_argument("--synth-renderer", choices=["gl", "numpy"], default="gl",
                   help="gl (default): each strand segment drawn as the tube's facets that face the camera, the hair "
                        "lobes (visible points only) and the shadow lookups on the GPU (llvmpipe here); numpy: every "
                        "strand a whole tube of triangles and the lobes in numpy, the slow reference the gl renderer "
                        "is tested against (docs/synthetic.md)")
    p.add_argument("--lights", type=int, default=3, help="dominant lights casting shadows (0-4, default 3)")
    p.add_argument("--supersample", type=int, default=3, help="colour supersampling per axis (default 3)")
    p.add_argument("--pixel-filter", type=float, default=0.5, metavar="SIGMA",
                   help="film filter: Gaussian of SIGMA pixels in total, like a path tracer's (default 0.5, "
                        "pbrt-v4 / Mitsuba 3); 0 = a 1-pixel box")
    _add_surroundings_arguments(p)
    _add_sensor_arguments(p)
    _add_camera_trait_arguments(p)
    p.add_argument("--preview", action="store_true", help="also write DIR/preview.png (colour + depth contact sheet)")
    p.add_argument("--overwrite", action="store_true", help="replace DIR if it exists")
    p.add_argument("--debug", action="store_true", help="show tracebacks")


def _add_surroundings_arguments(p: argparse.ArgumentParser) -> None:
    """What is seen around the object (issue 20)."""
    p.add_argument("--background", choices=["black", "env", "clutter"], default="black",
                   help="what is seen behind the object: black (default, like a masked scan and like "
                        "furrow render's output), env (the environment map made visible) or clutter (a room of "
                        "coloured boxes on shelves over a tiled floor, out of the depth sensor's range)")
    p.add_argument("--support", choices=["none", "disc", "table"], default="none",
                   help="what the object stands on, in the colour AND in the depth: none (default), disc (a grey "
                        "turntable 1.6x the object's radius) or table (a 1.2 x 0.8 m wooden table top); with a "
                        "support the written bounds are derived from the depth, as a reader does for a real capture")
    p.add_argument("--background-frames", default=None, metavar="SPEC",
                   help="views that show the background and the support (slice spec, e.g. 0::2); the others are "
                        "over black with the object's depth only, as held-out views of the evaluation captures "
                        "(default: every view). The true matte is always written: masks/NAME.png, mask_path")


def _add_sensor_arguments(p: argparse.ArgumentParser) -> None:
    """Depth-sensor traits, pose noise and the depth files."""
    p.add_argument("--depth-noise", type=float, default=0.0, metavar="K",
                   help="depth noise sigma = K z^2 (metres of sigma at 1 m; e.g. 0.002)")
    p.add_argument("--holes", type=float, default=0.0, metavar="FRAC",
                   help="fraction of each depth image covered by random hole blobs (e.g. 0.02)")
    p.add_argument("--grazing", type=float, default=0.0, metavar="DEG",
                   help="drop depth seen more than DEG degrees from the surface normal (e.g. 75)")
    p.add_argument("--pose-noise-deg", type=float, default=0.0, metavar="D",
                   help="RMS rotation error of the recorded poses")
    p.add_argument("--pose-noise-frac", type=float, default=0.0, metavar="F",
                   help="RMS translation error of the recorded poses, fraction of the object size")
    p.add_argument("--depth-size", type=_size, default=None, metavar="WxH",
                   help="write the depth maps at this smaller size (nearest pixel), as a phone gives them (e.g. "
                        "256x192 for 1920x1440 colour); `furrow model` resamples them to the colour")
    p.add_argument("--sensor", default="d435", choices=["d435", "kinect-v1", "ideal"],
                   help="depth-sensor traits: z^2 noise, quantisation, flying pixels (default d435; ideal = exact)")
    p.add_argument("--flying", type=float, default=None, metavar="FRAC",
                   help="override the sensor's fraction of depth-edge pixels that fly (0 = none)")
    p.add_argument("--depth-format", choices=["png", "png-0.1mm", "exr"], default="png",
                   help="depth files: 16-bit PNG in millimetres (default), in 0.1 mm, or float EXR in metres")
    p.add_argument("--png-depth-unit", type=float, default=None, metavar="M",
                   help="metres per unit of --depth-format png (default 0.001 = millimetres)")
    p.add_argument("--board", action="store_true",
                   help="stand the object on a ChArUco board (for `furrow register --method board`); the board "
                        "is part of the geometry (gt/mesh.ply) and of gt/scene.json; the detector needs a steep view, "
                        "e.g. --elevations 50 --size 480x360")


def _add_camera_trait_arguments(p: argparse.ArgumentParser) -> None:
    """Real-camera traits (issue 21): auto exposure and lens distortion."""
    g = p.add_argument_group("real-camera traits (issue 21)")
    g.add_argument("--auto-exposure", type=float, nargs="?", const=0.35, default=None, metavar="SIGMA_EV",
                   help="jitter the exposure of the kept views (i %% --exposure-holdout == 0) by 2^N(0, SIGMA_EV) "
                        "(default 0.35 EV) and their white balance by --white-balance, in linear light before the "
                        "8-bit sRGB encoding (clipped); held-out views keep the true exposure; the true gains go "
                        "to gt/exposure.json")
    g.add_argument("--white-balance", type=float, default=0.06, metavar="SIGMA",
                   help="with --auto-exposure: per-channel white-balance gains exp(N(0, SIGMA)) (default 0.06)")
    g.add_argument("--exposure-holdout", type=int, default=2, metavar="K",
                   help="with --auto-exposure: jitter the views i %% K == 0 only, the ones `furrow eval --holdout K` "
                        "builds from (default 2; 1 = every view)")
    g.add_argument("--lens", choices=["opencv", "fisheye"], default=None,
                   help="render through a distorting lens and write camera_model OPENCV (k1=-0.12 k2=0.03 p1=8e-4 "
                        "p2=-5e-4) or OPENCV_FISHEYE (k1=0.03 k2=-0.01 k3=0.002 k4=-0.0005) to transforms.json")


def build_config(args):
    """SynthConfig from parsed arguments (errors are ValueError with a one-line reason)."""
    from datasets_synthetic.lighting import LightingConfig
    from datasets_synthetic.noise import NoiseConfig
    from datasets_synthetic.rig import TurntableRig
    from datasets_synthetic.scenes import SCENES
    from datasets_synthetic.sensor import sensor_preset
    from datasets_synthetic.synth import SynthConfig

    if args.name not in SCENES:
        raise ValueError(f"unknown scene {args.name!r}: choose one of {', '.join(SCENES)}")
    views = args.views if args.views is not None else (SMALL_VIEWS if args.small else 36)
    w, h = args.size if args.size is not None else (SMALL_SIZE if args.small else (640, 480))
    rings = len(args.elevations)
    if views < 1 or views % rings:
        raise ValueError(f"--views {views} must be a positive multiple of the number of rings ({rings})")
    rig = TurntableRig(views_per_ring=views // rings, elevations_deg=tuple(args.elevations), width=w, height=h,
                       fov_y_deg=args.fov)
    lighting = LightingConfig(env=args.env, lights=args.lights, rotation_deg=args.env_rotation, hair_model=args.hair,
                              **({"hair_env_lights": SMALL_HAIR_ENV_LIGHTS} if args.small else {}))
    noise = NoiseConfig(depth_sigma_at_1m=args.depth_noise, grazing_deg=args.grazing, holes_fraction=args.holes,
                        pose_rot_deg=args.pose_noise_deg, pose_trans_frac=args.pose_noise_frac)
    over = {}
    if args.flying is not None:
        over["flying_fraction"] = args.flying
    sensor = sensor_preset(args.sensor, **over)
    params = {}
    furry = args.name in FURRY_SCENES
    strands = args.strands if args.strands is not None else (SMALL_STRANDS if args.small and furry else None)
    if strands is not None:
        if not furry:
            raise ValueError(f"--strands applies to {' and '.join(FURRY_SCENES)} only")
        if strands < 1:
            raise ValueError(f"--strands must be >= 1, got {strands}")
        params["strands"] = strands
    params.update(_fur_variant(args))
    return SynthConfig(scene=args.name, seed=args.seed, rig=rig, lighting=lighting, noise=noise, sensor=sensor,
                       supersample=args.supersample, background=args.background, support=args.support,
                       background_frames=args.background_frames, scene_params=params,
                       pixel_filter_px=args.pixel_filter, lens=_lens(args),
                       renderer=getattr(args, "synth_renderer", "gl"))


def _lens(args):
    from datasets_synthetic.camera_traits import LENSES

    return LENSES[args.lens] if getattr(args, "lens", None) else None


def _auto_exposure(cap, args, cfg):
    """(capture with the kept views' exposure jittered, gt/exposure.json bytes) for --auto-exposure."""
    import dataclasses

    from datasets_synthetic.camera_traits import EXPOSURE_FILE, apply_exposure, exposure_gains, exposure_record

    n = len(cap.scanset.scans)
    gains = exposure_gains(n, args.auto_exposure, args.white_balance, cfg.seed, args.exposure_holdout)
    rec = exposure_record([s.name for s in cap.scanset.scans], gains, args.auto_exposure, args.white_balance,
                          args.exposure_holdout)
    return dataclasses.replace(cap, scanset=apply_exposure(cap.scanset, gains)), {EXPOSURE_FILE: rec}


def _fur_variant(args) -> dict:
    """Scene overrides of --curly / --coat / --curl / --curl-turns / --patches (furball only)."""
    from datasets_synthetic.fur_variants import CURLY, UNIFORM

    over = dict(CURLY) if getattr(args, "curly", False) else {}
    if getattr(args, "coat", None) == "uniform":
        over.update(UNIFORM)
    for flag, key in (("curl", "curl"), ("curl_turns", "curl_turns"), ("patches", "patches")):
        v = getattr(args, flag, None)
        if v is not None:
            over[key] = v
    if over and args.name != "furball":
        raise ValueError("--curly, --coat, --curl, --curl-turns and --patches apply to the furball only")
    if over.get("patches", 0) < 0:
        raise ValueError(f"--patches must be >= 0, got {over['patches']}")
    return over


def run(args, console) -> int:
    from capture.io import DEFAULT_PNG_DEPTH_UNIT
    from datasets_synthetic.lighting import resolve_env
    from datasets_synthetic.preview import contact_sheet_png_bytes
    from datasets_synthetic.relight import map_label, relight_images, relit_files
    from datasets_synthetic.synth import synthesize, write_capture
    from furrow.console import StageTimer, fail, track

    try:
        if args.png_depth_unit is not None and not 0 < args.png_depth_unit <= 0.01:
            raise ValueError(f"--png-depth-unit {args.png_depth_unit} out of range (0, 0.01] metres")
        cfg = build_config(args)
        for env in (cfg.lighting.env, *args.relight_env):
            resolve_env(env)  # fail early on a bad --env / --relight-env
        if args.lens and args.relight_env:
            raise ValueError("--lens and --relight-env together are not supported (the relit views are pinhole)")
        labels = [map_label(e) for e in args.relight_env]
        if len(set(labels)) != len(labels):
            raise ValueError(f"--relight-env maps must have distinct names, got {', '.join(labels)}")
    except (ValueError, FileNotFoundError) as e:
        fail(str(e))
        return 2
    if args.out.exists() and not args.overwrite:
        fail(f"{args.out}: already exists (use --overwrite to replace it)")
        return 1
    timer = StageTimer()
    scene = None
    if args.board:
        from datasets_synthetic.board import add_board
        from datasets_synthetic.scenes import build_scene

        scene, spec = add_board(build_scene(cfg.scene, cfg.seed, **cfg.scene_params))
        console.print(f"ChArUco board under the object: {spec.squares_x}x{spec.squares_y} squares of "
                      f"{spec.square_m} m, markers {spec.marker_m} m, {spec.dictionary}, at z = {spec.z_m:.4f} m "
                      f"(furrow register --board {spec.squares_x}x{spec.squares_y}:{spec.square_m}:{spec.marker_m}"
                      f" --board-z {spec.z_m:.5f})", highlight=False)
    with timer.stage(f"render {cfg.scene} ({cfg.rig.n_views} views, {cfg.rig.width}x{cfg.rig.height})"):
        cap = synthesize(cfg, scene=scene, progress=lambda it, label: track(it, label, total=len(it)))
    extra = {}
    if args.auto_exposure is not None:
        cap, files = _auto_exposure(cap, args, cfg)
        extra.update(files)
    unit = args.png_depth_unit if args.png_depth_unit is not None else DEFAULT_PNG_DEPTH_UNIT
    for env in args.relight_env:
        with timer.stage(f"relight under {map_label(env)}"):
            images, info = relight_images(cap, cfg, env, progress=lambda it, label: track(it, label, total=len(it)))
            extra.update(relit_files(cap, images, info, env, args.depth_format, unit))
        if info["clipped_fraction"] > 0.01:
            console.print(f"[yellow]relit under {map_label(env)}: {info['clipped_fraction']:.1%} of the foreground "
                          "clips at white with the capture's exposure[/]", highlight=False)
    if args.preview:
        with timer.stage("contact sheet"):
            extra["preview.png"] = contact_sheet_png_bytes(cap.scanset)
    with timer.stage("write"):
        path = write_capture(cap, args.out, depth_format=args.depth_format, overwrite=args.overwrite,
                             extra_files=extra, png_depth_unit=unit, depth_size=args.depth_size)
    st = cap.scene.stats
    console.print(f"wrote {path} ({len(cap.scanset)} views, {st['triangles']:,} triangles"
                  + (f", {st['strands']:,} strands" if "strands" in st else "")
                  + (f", {st['needles']:,} needles" if "needles" in st else "") + ")", highlight=False)
    if args.preview:
        console.print(f"preview: {args.out / 'preview.png'}", highlight=False)
    console.print(timer.table())
    return 0
