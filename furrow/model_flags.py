"""The flags that change the model, shared by every command that builds one (``furrow model``,
``furrow eval``, ``furrow batch``, the benches): :func:`add_model_arguments` adds them to a parser,
:func:`pipeline_config` turns the parsed arguments into the pipeline's config
(volume/pipeline/config.py), :func:`pipeline_hooks` gives the runner the command's stage table and
progress bars, :func:`print_plan` prints the stages a configuration runs (``--plan``)."""

from __future__ import annotations

import argparse
from functools import partial


def _auto_off(g, flag: str, text: str) -> None:
    """An ``auto`` | ``off`` switch of the model flags (``auto`` by default); ``text``: its help."""
    g.add_argument(flag, choices=["auto", "off"], default="auto", help=text)


def _pow2(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if v < 8 or v & (v - 1) or v > 512:
        raise argparse.ArgumentTypeError(f"{v} must be a power of two between 8 and 512")
    return v


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not WxH (e.g. 1280x960)") from None
    if w < 1 or h < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: width and height must be positive")
    return w, h


def _colour(text: str) -> tuple[float, float, float]:
    """--backdrop COLOUR -> linear RGB in [0, 1], read like furrow render --background
    (render.composite.background.parse_colour: a colour name, #rrggbb, or an sRGB triple)."""
    from render.composite.background import parse_colour

    try:
        c = parse_colour(text.strip())
    except ValueError:
        c = None
    if c is None:
        raise argparse.ArgumentTypeError(f"bad colour {text!r}: use a colour name (black, white, grey), #rrggbb "
                                         "or r,g,b (0-255)")
    return tuple(float(v) for v in c)


def add_model_arguments(p: argparse.ArgumentParser, frames: bool = True) -> None:
    """Every flag that changes the model (``frames``: with --frames; furrow batch picks no frames)."""
    g = p.add_argument_group("the model (the same flags in furrow model, eval and batch; --plan lists the stages)")
    if frames:
        g.add_argument("--frames", default=None, metavar="SPEC",
                       help="frames to use, python-slice style: 0::2, 3, 1,4,7 (furrow eval: before the hold-out "
                            "split)")
    g.add_argument("--views", default="auto", metavar="auto|all|N",
                   help="views kept (volume/views.py): auto drops near-duplicates (direction from the object within "
                        "2 deg of a kept view at a similar distance), all keeps every view, N keeps the N most spread "
                        "out; the model report gives every view's reason (default auto)")
    g.add_argument("--output-size", type=_size, default=None, metavar="WxH",
                   help="size of the frames you will render: the views are scaled down so the object keeps the "
                        "pixels it will cover there (never up); default: full resolution")
    g.add_argument("--max-res", type=_pow2, default=256, help="L_max: finest resolution tried (default 256)")
    g.add_argument("--alpha", type=float, default=1.5, help="Eq. 1 tolerance alpha >= 1 (default 1.5)")
    g.add_argument("--t", type=float, default=0.01, help="Eq. 1 threshold t on N_i / L^3 (default 0.01)")
    g.add_argument("--sdf", choices=["consensus", "tsdf"], default="consensus",
                   help="fusion method (default consensus)")
    g.add_argument("--sphere-error", type=float, default=0.2, metavar="E",
                   help="target 1 - volume IoU of the occluder sphere set (default 0.2)")
    g.add_argument("--quorum", type=int, default=3,
                   help="consensus: scans that must agree for a depth sample to count (default 3; use 1-2 "
                        "when each surface point is seen by fewer views)")
    g.add_argument("--mesh-faces", type=int, default=60000,
                   help="decimate the mesh to this many triangles (default 60000)")
    g.add_argument("--mesh-level", type=_pow2, default=128,
                   help="fused level the baseline mesh is marched on (default 128, capped at --max-res)")
    g.add_argument("--spill", choices=["auto", "always", "never"], default="auto",
                   help="where the scans wait between stages (capture/scan_store.py): on disk in a temporary folder, "
                        "read back one view at a time, so that peak memory does not grow with the frames; auto "
                        "(default) spills when the frames would take over 128 MiB in memory (15 frames at "
                        "1280x960, 62 at 640x480); the model is the same either way")
    g.add_argument("--view-workers", type=int, default=None, metavar="N",
                   help="processes the views are worked on in, in parallel: reading, extent, matte, photometric "
                        "pairs, RGBz (default: the machine's cores when a view's work pays for starting them: "
                        "views of 1 M pixels or more, or a quarter of that with a matte to solve; else 1; "
                        "volume/pipeline/pool.py; 1 = all in this process; the model is the same)")
    g.add_argument("--reference-pipeline", action="store_true",
                   help="build with the slow reference paths (numpy fusion passes, mesh on the finest level with "
                        "pymeshlab decimation, Open3D ray cast, every level completed): for benchmarks and checks")
    _add_camera_arguments(p)
    _add_surroundings_arguments(p)


def _add_camera_arguments(p: argparse.ArgumentParser) -> None:
    from capture.lens import DEFAULT_UNDISTORT, UNDISTORT_HELP, UNDISTORT_MODES

    g = p.add_argument_group("real cameras: lens distortion and per-view exposure / white balance")
    g.add_argument("--undistort", choices=list(UNDISTORT_MODES), default=DEFAULT_UNDISTORT,
                   help="frames with lens distortion (camera_model OPENCV / OPENCV_FISHEYE, COLMAP radial models) "
                        "are undistorted once at read time to a pinhole camera: "
                        + "; ".join(f"'{m}'{' (default)' if m == DEFAULT_UNDISTORT else ''}: {h}"
                                    for m, h in UNDISTORT_HELP.items())
                        + " (docs/real_cameras.md)")
    g.add_argument("--depth-agreement", choices=("check", "fix", "off"), default="check",
                   help="whether the views' depths agree with their poses (each view's depth points projected into "
                        "its 2 nearest views at depth scales 1/4..4; capture/depth_agreement.py): 'check' (default) "
                        "warns when they agree best at another scale (a wrong depth unit, structure-from-motion poses "
                        "with metric depth) or at none (intrinsics, axes, files), when other focal lengths fit "
                        "(fl_x, fl_y of another image size), when the colour's edges sit "
                        "beside the depth's (depth not registered to the colour; capture/depth_registration.py), and "
                        "when the depth maps agree only flipped or read as distances along the rays "
                        "(capture/depth_readings.py) or as disparity, inverse depth (capture/depth_disparity.py), "
                        "and when each view's depth agrees far better at its own scale (a monocular network's; "
                        "capture/depth_view_scales.py); "
                        "'fix' also scales the depth to the poses (each view by its own factor where they drift), "
                        "moves it onto its colour, flips it back, reads "
                        "range as z-depth and disparity as depth (the model stays in the poses' "
                        "frame and unit; the intrinsics stay as given); 'off'")
    g.add_argument("--no-photometric", action="store_true",
                   help="do not align the views' exposure and white balance (default: a per-view, per-channel "
                        "gain in linear light estimated from what neighbouring views see of the same surface)")
    _auto_off(g, "--photometric-background",
              "where the background plate saw no exposure change but the object's cells ask for gains, "
              "ask the background too (capture/photometric_background.py: each view's background ring "
              "against the other views' prediction of it): auto (default: gains that make the rings "
              "less alike in most views are refused, the console says why; a fixed-exposure furry bunny "
              "orbit had been given 0.38 EV, 0.15 dB held out) or off (the cells decide alone)")
    g.add_argument("--photometric-reference", default="mean", metavar="NAME",
                   help="whose colour the aligned views keep: 'mean' (default: the mean of the views' log gains, "
                        "per channel, kept at 0), 'median' (the median view in each channel), or a view's name")


def _add_surroundings_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("the object apart from its surroundings (before fusion)")
    g.add_argument("--keep-support", action="store_true",
                   help="keep the support plane (table, turntable) the object stands on; by default it is found "
                        "by RANSAC in the depth and removed with far depth and clutter (capture/extent.py)")
    g.add_argument("--no-extent", action="store_true",
                   help="use the depth as captured: no support, far-depth or clutter removal at all")
    g.add_argument("--matte", choices=["auto", "given", "backdrop", "plate", "estimate", "off"], default="auto",
                   help="soft alpha matte per view and the object's colour under it (capture/matting.py): auto "
                        "(default: the capture's own matte, mask_path or RGBA alpha, its colour unmixed from the "
                        "background plate; else a plain backdrop, named or detected (a detected one only where it "
                        "predicts the view's background no worse than the plate: capture/matting_choice.py); else "
                        "the background plate "
                        "where it is known: C = a F + (1 - a) B solved with B, capture/matting_known.py; else "
                        "estimated from the depth by closed-form matting), given, backdrop, plate, estimate, or "
                        "off (the binary depth mask, as before)")
    g.add_argument("--plate", choices=["auto", "user", "fixed", "panorama", "off"], default="auto",
                   help="the background behind the object in every view, from the capture (capture/plate.py): "
                        "auto (default: --background-plates when given; else whichever of fixed and panorama "
                        "predicts the views' own background better), fixed (a camera that stood still while the "
                        "object turned: each pixel's robust mode over the frames), panorama (a moving camera: "
                        "the other views along each ray, with the support plane and the room's depth), user, or "
                        "off; each view's share of the matting band with a known background and the plate's "
                        "error on background pixels it was not built from go to the model report.  A view's "
                        "plate that predicts those pixels worse than the view's own background nearby (the "
                        "background changed between frames) is refused, in the whole view or on one side of it, "
                        "and its matte estimated without it; the console says which (capture/plate_gate.py)")
    g.add_argument("--background-plates", default=None, metavar="DIR",
                   help="plates you shot without the object (the same path, or a fixed camera): one image per "
                        "frame named like the frame's colour image, or one image for every frame "
                        "(capture/plate_io.py)")
    _auto_off(g, "--plate-denoise",
              "the frames' sensor noise, measured (capture/noise.py, at two scales so that a camera's "
              "demosaicing and JPEG do not hide it; a room's texture that stays put between frames is not "
              "noise): auto (default: where it is at least 1 8-bit step, the plate is made from the frames "
              "through a bilateral filter on the scale of the noise, unless 12 views' plates say the "
              "smoothed frames predict the held-back background worse (capture/noise_check.py); the matte "
              "still reads the photos; the figures in the plate record and on the console) or off")
    g.add_argument("--blurred-views", choices=["keep", "leave out", "off"], default="keep",
                   help="frames blurred where the others are sharp (a shaken camera), found by a fixed camera's "
                        "background plate (capture/blurred_views.py: the kernel that takes the plate to the photo "
                        "cuts the held-back error to 0.8 of the plate's own or less): keep (default: said on the "
                        "console and in the plate record, kept in the model), 'leave out' (left out of the model "
                        "while 60%% of the views stay: a conifer before a bright sky gained 3.4 dB held out, a fur "
                        "ball lost 1.1) or off (not tested)")
    _auto_off(g, "--vignetting",
              "a moving camera's lens vignetting (its image darker towards the corners), measured on the "
              "background the views share (capture/vignetting.py: the panorama plate's held-back pixels "
              "seen by two views at different radii): auto (default: taken out of every frame where it "
              "beats none on held-back pixels by 5 standard errors and changes the image by 3%% or more; "
              "half a stop cost a path-traced conifer orbit 1.1 dB held out, 0.4 taken out) or off (not "
              "measured; a fixed camera's frames are never measured: its background sits at the same "
              "pixels in every frame, and its turntable lost nothing to half a stop)")
    _auto_off(g, "--plate-shadow",
              "a fixed camera's plate lacks the shadow the object casts on its support (it turns with the "
              "object): auto (default; capture/plate_shadow.py: where at least 10%% of the support just "
              "beside the object is darker than 0.85 of its plate, the plate is lit as the frame is there "
              "and the frames' lines' estimates on the table count as unknown; fur on a table: alpha MSE "
              "0.0161 -> 0.0094 held out) or off")
    _auto_off(g, "--jpeg-chroma",
              "JPEG frames whose chroma is stored at half resolution (a phone's 4:2:0, read from each "
              "file's header; capture/jpeg_chroma.py): auto (default: the matte's alpha bound allows the "
              "chroma the decoder smeared beside every edge of colour; a path-traced JPEG conifer "
              "turntable +0.78 dB held out) or off (read as any frame)")
    g.add_argument("--matte-resolution", choices=["full", "working"], default="working",
                   help="where a solved matte (estimated from the depth, or with a known background: plate, "
                        "backdrop) is solved: working (default; capture/matting_scale.py: on a copy scaled so that "
                        "the object keeps 640 pixels and the image twice the depth's width, alpha brought back by a "
                        "guided filter on the full-size colour, the colour exact at full size where the background "
                        "is known; objects under 800 pixels, e.g. every 640x480 capture, are solved at full size "
                        "bit for bit; alpha MSE 0.0007-0.0015 against full size on phone frames: docs/speed.md) or "
                        "full (closed-form matting on every pixel, the reference)")
    g.add_argument("--matte-across", choices=["auto", "on", "off"], default="auto",
                   help="with a background plate, each partial pixel's colour from the lines of its 3D cell "
                        "across the views (volume/surroundings.py, capture/matting_cells.py): auto (default: "
                        "the rule in volume.surroundings.across_wanted, its reason in the matte record), on, or off")
    g.add_argument("--backdrop", type=_colour, default=None, metavar="COLOUR",
                   help="the plain backdrop behind the object: black, white, grey, #rrggbb or r,g,b (sRGB 0-255)")


def pipeline_config(args, **save):
    """The PipelineConfig of the model flags (:func:`add_model_arguments`); ``save``: the save
    stage's settings (``out``, the capture lighting)."""
    from capture.extent import ExtentConfig
    from capture.matting import MatteConfig
    from capture.photometric import PhotometricConfig
    from capture.plate import PlateConfig
    from capture.sources import ReadConfig, UndistortConfig
    from volume.fusion import FusionConfig
    from volume.mesh import MeshConfig
    from volume.pipeline.config import FuseConfig, PipelineConfig, SaveConfig, ScaleConfig, SpheresConfig, ViewsConfig
    from volume.pipeline.pool import AUTO_WORKERS
    from volume.pyramid import LoptConfig

    lopt = LoptConfig(max_res=args.max_res, alpha=args.alpha, t=args.t, min_res=min(8, args.max_res))
    cfg = PipelineConfig(
        read=ReadConfig(getattr(args, "frames", None)), undistort=UndistortConfig(args.undistort),
        views=ViewsConfig(str(args.views)), scale=ScaleConfig(args.output_size),
        agreement=_agreement(getattr(args, "depth_agreement", "check")),
        extent=None if args.no_extent else ExtentConfig(keep_support=args.keep_support),
        matte=MatteConfig(mode=args.matte, backdrop=args.backdrop, resolution=args.matte_resolution,
                                 across=getattr(args, "matte_across", "auto"),
                                 jpeg_chroma=getattr(args, "jpeg_chroma", "auto"),
                                 shadow=getattr(args, "plate_shadow", "auto")),
        plate=PlateConfig(mode=args.plate, plates_dir=args.background_plates,
                          denoise=getattr(args, "plate_denoise", "auto"),
                          blurred=getattr(args, "blurred_views", "keep"),
                          vignetting=getattr(args, "vignetting", "auto")),
        photometric=None if args.no_photometric else PhotometricConfig(
            reference=args.photometric_reference, background=getattr(args, "photometric_background", "auto")),
        fuse=FuseConfig(sdf=args.sdf, lopt=lopt, fusion=FusionConfig(quorum=args.quorum)),
        spheres=SpheresConfig(error=args.sphere_error), mesh=MeshConfig(target_faces=args.mesh_faces,
                                                                         level=args.mesh_level),
        save=SaveConfig(**save), spill=args.spill,
        workers=args.view_workers if args.view_workers is not None else AUTO_WORKERS)
    return cfg.reference() if args.reference_pipeline else cfg


def _agreement(mode: str):
    """The depth-agreement stage's config of ``--depth-agreement`` (None: off)."""
    from capture.depth_agreement import AgreementConfig

    return None if mode == "off" else AgreementConfig(fix=mode == "fix")


def pipeline_hooks(timer):
    """The runner's Hooks for a command: its StageTimer's rows (per-view rows quiet) and progress bars."""
    from furrow.console import track
    from volume.pipeline.work import Hooks

    return Hooks(row=timer.stage, view_row=partial(timer.stage, quiet=True), progress=track, add=timer.add)


def print_plan(console, cfg, source=None, title: str = "the pipeline") -> None:
    """The stages ``cfg`` runs, in order, one line each: on / off, kind, settings (``--plan``)."""
    from volume.pipeline.plan import plan_text

    if source is not None:
        console.print(f"source: {source.format}, {len(source)} frames ({source.path})", highlight=False)
    console.print(f"{title}: the stages in order (volume/pipeline/stages.py), on / off with these flags:",
                  highlight=False)
    console.print(plan_text(cfg), highlight=False, markup=False, soft_wrap=True)
