"""``furrow model SCANS -o MODEL``: scan set -> signed distance pyramid, RGBz, spheres, mesh."""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

HELP = "build the model (SDF pyramid up to L_opt, RGBz images, occluder spheres, mesh) from a scan set"
DESCRIPTION = """Fuse the depth maps of a posed scan set into signed distance volumes (consensus fusion in
the spirit of Wheeler-Sato-Ikeuchi, or Open3D's TSDF as the peer), choose the resolution L_opt
by the paper's Eq. 1 (docs/methods.md §1.1), keep every power-of-two level up to it with its surface
voxels, project the geometry into every camera as cleaned RGBz images (docs/methods.md §1.4), fit an
occluder sphere set to an error target (docs/methods.md §3) and extract a decimated mesh for the
baseline renderer (marched on --mesh-level).  The finest level's distance transforms are done
only when something uses that level.  The closing table gives wall and CPU seconds and peak
resident memory per stage.  The model folder is written atomically (temporary folder + rename).

Real cameras: frames with lens distortion are undistorted when read (--undistort), and the views'
exposure and white balance are aligned before fusion (a gain per view and channel in linear light,
stored in model.json params.photometric and printed as EV and white balance per view;
--no-photometric turns it off, --photometric-reference picks whose colour is kept).

Only what the scene needs (issue 24): the views are worked one at a time on the object's footprint;
the RGBz images are stored as per-view crops around the object (8-bit sRGB and alpha, 16-bit
depth, compressed, read view by view); L_max is judged by Eq. 1 on a sample before it is fused;
--views drops near-duplicate views and --output-size scales the views to the pixels the object
will cover (both choices, per view, in --json and model.json).

--capture-env MAP (an equirect .exr/.hdr or a bundled name), --capture-env-fisheye IMG or
--capture-env-mirrorball IMG stores the lighting the scans were taken under, with the rig's up
axis, so that `furrow render --relight` can relight the model (issue 15); a model without it
cannot be relit.

examples:
  furrow model out/furball_scan -o out/furball_model
  furrow model out/furball_scan -o out/m64 --frames 0::2 --max-res 64 --sdf tsdf --json
  furrow model out/furball_scan -o out/furball_model --capture-env forest
  furrow model out/plant_room -o out/plant_model --matte estimate      (support and room removed, matte estimated)

Before fusion the object is set apart from its surroundings (issue 20): the support plane under
it (RANSAC in the depth), far depth and clutter outside the region the cameras look at are
removed from the depth (--keep-support, --no-extent), and each view gets a soft alpha matte
and the object's colour under it (--matte, --backdrop), stored in the model's RGBz images.
Both stages print what they did and have a row in the stage table."""


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


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scans", type=Path, help="scan set: transforms.json, a folder holding one, or a plain folder")
    p.add_argument("-o", "--out", type=Path, required=True,
                   help="model folder to write (an existing model is replaced only with --overwrite)")
    p.add_argument("--frames", default=None, metavar="SPEC", help="frames to use, python-slice style: 0::2, 3, 1,4,7")
    p.add_argument("--views", default="auto", metavar="auto|all|N",
                   help="views kept (volume/views.py): auto drops near-duplicates (direction from the object within "
                        "2 deg of a kept view at a similar distance), all keeps every view, N keeps the N most spread "
                        "out; the model report gives every view's reason (default auto)")
    p.add_argument("--output-size", type=_size, default=None, metavar="WxH",
                   help="size of the frames you will render: the views are scaled down so the object keeps the "
                        "pixels it will cover there (never up); default: full resolution")
    p.add_argument("--max-res", type=_pow2, default=256, help="L_max: finest resolution tried (default 256)")
    p.add_argument("--alpha", type=float, default=1.5, help="Eq. 1 tolerance alpha >= 1 (default 1.5)")
    p.add_argument("--t", type=float, default=0.01, help="Eq. 1 threshold t on N_i / L^3 (default 0.01)")
    p.add_argument("--sdf", choices=["consensus", "tsdf"], default="consensus",
                   help="fusion method (default consensus)")
    p.add_argument("--sphere-error", type=float, default=0.2, metavar="E",
                   help="target 1 - volume IoU of the occluder sphere set (default 0.2)")
    p.add_argument("--quorum", type=int, default=3,
                   help="consensus: scans that must agree for a depth sample to count (default 3; use 1-2 "
                        "when each surface point is seen by fewer views)")
    p.add_argument("--mesh-faces", type=int, default=60000,
                   help="decimate the mesh to this many triangles (default 60000)")
    p.add_argument("--mesh-level", type=_pow2, default=128,
                   help="fused level the baseline mesh is marched on (default 128, capped at --max-res)")
    p.add_argument("--spill", choices=["auto", "always", "never"], default="auto",
                   help="where the scans wait between stages (capture/scan_store.py): on disk in a temporary folder, "
                        "read back one view at a time, so that peak memory does not grow with the frames; auto "
                        "(default) spills when the frames would take over 128 MiB in memory (15 frames at "
                        "1280x960, 62 at 640x480); the model is the same either way")
    p.add_argument("--reference-pipeline", action="store_true",
                   help="build with the slow reference paths (numpy fusion passes, mesh on the finest level with "
                        "pymeshlab decimation, Open3D ray cast, every level completed): for benchmarks and checks")
    add_camera_arguments(p)
    p.add_argument("--overwrite", action="store_true", help="replace MODEL if it exists (only a furrow model folder)")
    p.add_argument("--json", action="store_true", help="print a machine-readable summary on stdout")
    g = p.add_argument_group("capture lighting (for furrow render --relight)")
    x = g.add_mutually_exclusive_group()
    x.add_argument("--capture-env", default=None, metavar="MAP",
                   help="the scans' lighting: an equirect .exr/.hdr or a bundled name (studio, courtyard, forest, "
                        "sunset)")
    x.add_argument("--capture-env-fisheye", type=Path, default=None, metavar="IMG",
                   help="the scans' lighting as an HDR angular fisheye photo looking up (square, .exr/.hdr)")
    x.add_argument("--capture-env-mirrorball", type=Path, default=None, metavar="IMG",
                   help="the scans' lighting as an HDR mirror-ball photo taken level (square crop, .exr/.hdr)")
    from furrow.relight_flags import add_map_orientation_arguments

    add_map_orientation_arguments(g, "the capture lighting (--capture-env*)", prefix="capture-env")
    g.add_argument("--capture-env-fov", type=float, default=185.0, metavar="DEG",
                   help="field of view of --capture-env-fisheye (default 185)")
    g = p.add_argument_group("the object apart from its surroundings (before fusion)")
    g.add_argument("--keep-support", action="store_true",
                   help="keep the support plane (table, turntable) the object stands on; by default it is found "
                        "by RANSAC in the depth and removed with far depth and clutter (capture/extent.py)")
    g.add_argument("--no-extent", action="store_true",
                   help="use the depth as captured: no support, far-depth or clutter removal at all")
    g.add_argument("--matte", choices=["auto", "given", "backdrop", "estimate", "off"], default="auto",
                   help="soft alpha matte per view and the object's colour under it (capture/matting.py): auto "
                        "(default: the capture's own matte, mask_path or RGBA alpha; else a plain backdrop, named "
                        "or detected; else estimated from the depth by closed-form matting), given, backdrop, "
                        "estimate, or off (the binary depth mask, as before)")
    g.add_argument("--backdrop", type=_colour, default=None, metavar="COLOUR",
                   help="the plain backdrop behind the object: black, white, grey, #rrggbb or r,g,b (sRGB 0-255)")
    p.add_argument("--debug", action="store_true", help="show tracebacks")


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


def _prepare(args):
    """PrepareConfig of the extent / matte flags."""
    from capture.extent import ExtentConfig
    from capture.matting import MatteConfig
    from volume.prepare import PrepareConfig

    return PrepareConfig(extent=not args.no_extent, extent_cfg=ExtentConfig(keep_support=args.keep_support),
                         matte=MatteConfig(mode=args.matte, backdrop=args.backdrop))


def run(args, console) -> int:
    import dataclasses

    from furrow.console import StageTimer, track
    from volume.build import ModelConfig, build_model
    from volume.fusion import FusionConfig
    from volume.mesh import MeshConfig
    from volume.model import save_model
    from volume.pyramid import LoptConfig

    kw = dict(sdf=args.sdf, photometric=photometric_config(args),
              lopt=LoptConfig(max_res=args.max_res, alpha=args.alpha, t=args.t, min_res=min(8, args.max_res)),
              fusion=FusionConfig(quorum=args.quorum), sphere_error=args.sphere_error, prepare=_prepare(args))
    if args.reference_pipeline:
        cfg = ModelConfig.reference(**kw)
        cfg = replace(cfg, mesh=replace(cfg.mesh, target_faces=args.mesh_faces))
    else:
        cfg = ModelConfig(mesh=MeshConfig(target_faces=args.mesh_faces, level=args.mesh_level), **kw)
    out = Path(args.out)
    if out.exists() and not (out / "model.json").is_file() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"{out}: exists and is not a furrow model folder; choose another output")
    if out.exists() and (out / "model.json").is_file() and not args.overwrite:
        raise ValueError(f"{out}: model already exists (use --overwrite to replace it)")
    timer = StageTimer()

    def progress(it, desc="working"):
        return track(it, desc)

    t0, c0 = time.perf_counter(), time.process_time()
    capture_env = _capture_env(args)  # before the long build: a bad map fails at once
    with timer.stage("read scans"):
        scanset, views, spill = _read_views(args, progress=lambda it, d: track(it, d))
    try:  # the spilled scans and crops (capture.scan_store) are needed until the model is written
        keep = spill.keep if spill is not None else None
        res = _working_resolution(scanset, args, timer, keep)
        scanset = res.pop("scanset")
        model, summary = build_model(scanset, cfg, stage=timer.stage, progress=progress,
                                     provenance={"source": str(args.scans), "frames": args.frames}, keep=keep,
                                     work_dir=spill.path if spill is not None else None)
        summary.update(spill="disk" if spill is not None else "memory", views=views, resolution=res)
        model = dataclasses.replace(model, params={**model.params, "views": views, "resolution": res})
        if capture_env is not None:
            model = _with_capture_env(model, capture_env, scanset, args)
            summary["capture_env"] = model.capture_env.record()
        with timer.stage("write"):
            save_model(model, out)
    finally:
        if spill is not None:
            spill.close()
    summary["seconds"] = {k: round(v, 3) for k, v in timer.seconds.items()}
    summary["seconds_total"] = round(time.perf_counter() - t0, 3)
    summary["cpu_seconds"] = {k: round(v, 3) for k, v in timer.cpu_seconds.items()}
    summary["cpu_seconds_total"] = round(time.process_time() - c0, 3)
    summary["peak_mb"] = {k: round(v, 1) for k, v in timer.peak_mb.items()}
    summary["peak_mb_total"] = round(max(timer.peak_mb.values(), default=0.0), 1)
    summary["output"] = str(out)
    console.print(timer.table("furrow model: stage timings"))
    h = summary["holes"]
    if h:
        hb = [x["holes_before"] for x in h]
        ha = [x["holes_after"] for x in h]
        console.print(f"RGBz hole fraction per view (min / mean / max over {len(h)} views): before "
                      f"{min(hb):.4f} / {sum(hb) / len(hb):.4f} / {max(hb):.4f}, after closing "
                      f"{min(ha):.4f} / {sum(ha) / len(ha):.4f} / {max(ha):.4f}  (per view: --json)", highlight=False)
    _print_surroundings(console, summary["surroundings"])
    if summary.get("photometric"):
        console.print(photometric_table(summary["photometric"]))
        if summary["photometric"]["unaligned"]:
            console.print(f"[yellow]photometric: {len(summary['photometric']['unaligned'])} views share no usable "
                          "surface with a neighbour and keep their colour[/]", highlight=False)
    console.print(f"views: {views['kept']} of {views['of']} kept (--views {views['mode']}; reasons per view: "
                  f"--json / model.json); resolution: {res['reason']}", highlight=False)
    console.print(f"L_opt = {summary['l_opt']}  levels {summary['levels']}  "
                  f"surface voxels {summary['surface_voxels']}  "
                  f"spheres {summary['spheres']} (1 - IoU {summary['sphere_error']})  -> {out}", highlight=False)
    if args.json:
        print(json.dumps(summary))
    return 0


def add_camera_arguments(p: argparse.ArgumentParser) -> None:
    """--undistort, --no-photometric, --photometric-reference (shared with furrow eval)."""
    g = p.add_argument_group("real cameras: lens distortion and per-view exposure / white balance")
    g.add_argument("--undistort", choices=["crop", "full"], default="crop",
                   help="frames with lens distortion (camera_model OPENCV / OPENCV_FISHEYE, COLMAP radial models) "
                        "are undistorted at read time: 'crop' (default, as nerfstudio: every pixel valid, corners "
                        "lost) or 'full' (every source pixel kept, black corners without depth)")
    g.add_argument("--no-photometric", action="store_true",
                   help="do not align the views' exposure and white balance (default: a per-view, per-channel "
                        "gain in linear light estimated from what neighbouring views see of the same surface)")
    g.add_argument("--photometric-reference", default="median", metavar="NAME",
                   help="whose colour the aligned views keep: 'median' (default: the median view in each channel), "
                        "'mean', or a view's name")


def photometric_config(args):
    """The PhotometricConfig of the command line, or None with --no-photometric."""
    from capture.photometric import PhotometricConfig

    return None if args.no_photometric else PhotometricConfig(reference=args.photometric_reference)


def photometric_table(rec: dict):
    """Rich table of the per-view gains of a photometric record (EV and white balance)."""
    from rich.table import Table

    t = Table(title=f"photometric alignment ({rec['pairs']} view pairs, {rec['samples']} samples, "
                    f"reference {rec['reference']}, residual {rec['residual_log']:.4f} log, appearance / exposure "
                    f"variance {rec.get('appearance_to_exposure', 0):.3g})")
    for c in ("view", "EV", "WB r", "WB g", "WB b"):
        t.add_column(c, justify="right")
    for v in rec["views"]:
        t.add_row(v["name"], f"{v['ev']:+.3f}", *(f"{x:.3f}" for x in v["wb"]))
    return t


def _read_views(args, progress):
    """(ScanSet of the kept views, views report, ScanSpill or None): the cameras are read first
    where the format allows (transforms.json), so dropped views' images are never read, and the
    scans go to disk as they are read when the frames are many (--spill, capture.scan_store)."""
    from capture.io import read_cameras, read_scanset
    from capture.scan import select_indices
    from capture.scan_store import spill_for
    from volume.views import select_views

    try:
        cams = read_cameras(args.scans, args.undistort)
    except Exception:  # another format: read everything, then choose
        cams = None
    if cams is not None:
        idx = select_indices(args.frames, len(cams))
        kept, reasons = select_views([cams[i].camera for i in idx], args.views)
        spec = ",".join(str(idx[k]) for k in kept)
        spill = spill_for(sum(cams[idx[k]].camera.width * cams[idx[k]].camera.height for k in kept), args.spill)
        try:
            scanset = read_scanset(args.scans, spec, progress=progress, undistort=args.undistort,
                                   keep=spill.keep if spill is not None else None)
        except BaseException:
            if spill is not None:
                spill.close()
            raise
        names = [cams[i].name for i in idx]
    else:  # another format is read whole; the later stages' scans go to disk when they are many
        full = read_scanset(args.scans, args.frames, progress=progress, undistort=args.undistort)
        kept, reasons = select_views(full.cameras, args.views)
        scanset = type(full)(tuple(full.scans[k] for k in kept), full.bounds, full.metadata)
        names = [s.name for s in full.scans]
        spill = spill_for(sum(c.width * c.height for c in scanset.cameras), args.spill)
    for r in reasons:
        r["name"] = names[r["view"]]
    return scanset, {"mode": args.views, "kept": len(kept), "of": len(reasons), "per_view": reasons}, spill


def _working_resolution(scanset, args, timer, keep=None) -> dict:
    """The working scale from the object's footprint against --output-size; the scaled scans
    under "scanset" (volume.views; each passed through ``keep``)."""
    from volume.views import footprint_px, scaled_scanset, working_scale

    s, rep = working_scale([footprint_px(x.depth) for x in scanset.scans], args.output_size)
    if s < 1:
        with timer.stage("scale views"):
            scanset = scaled_scanset(scanset, s, keep)
    c = scanset.scans[0].camera
    return {**rep, "size": [c.width, c.height], "output_size": list(args.output_size) if args.output_size else None,
            "scanset": scanset}


def _capture_env(args):
    """The EnvMap of the --capture-env* flags, or None."""
    if args.capture_env is None and args.capture_env_fisheye is None and args.capture_env_mirrorball is None:
        return None
    from render.shading.capture_env import capture_envmap

    return capture_envmap(args.capture_env, args.capture_env_fisheye, args.capture_env_mirrorball,
                          fov_deg=args.capture_env_fov, convention=args.capture_env_convention)


def _with_capture_env(model, env, scanset, args):
    """``model`` with the capture lighting ``env`` stored, its up axis the rig's."""
    import dataclasses

    from capture.orbit import estimate_up
    from volume.model import CaptureLighting

    src = args.capture_env or f"{'fisheye' if args.capture_env_fisheye else 'mirror ball'} " \
                              f"{args.capture_env_fisheye or args.capture_env_mirrorball}"
    up = estimate_up([s.camera for s in scanset.scans])
    return dataclasses.replace(model, capture_env=CaptureLighting(env.data, up, args.capture_env_rotation, src))


def _print_surroundings(console, rec: dict) -> None:
    """The extent and matte stages' numbers, one line each."""
    ex = rec.get("extent")
    if ex:
        r = ex["removed_fraction"]
        plane = "no support plane" if ex["plane"] is None else \
            (f"support plane n = {ex['plane'][:3]}, d = {ex['plane'][3]:+.4f} m ({ex['plane_inlier_fraction']:.1%} of "
             f"the focus points){' kept' if ex['kept_support'] else ''}")
        console.print(f"extent: {plane}; depth removed: support {r['support']:.2%}, far {r['far']:.2%}, "
                      f"outside {r['outside']:.2%}, floaters {r.get('floaters', 0.0):.2%}", highlight=False)
    m = rec.get("matte", {})
    if m.get("mode") not in (None, "off"):
        console.print(f"matte ({m['mode']}): {m['methods']}, {m['seconds_per_view']:.2f} s per view (max "
                      f"{m['seconds_per_view_max']:.2f}), unknown {m['unknown_fraction_mean']:.2%}, partial alpha "
                      f"{m['partial_fraction_mean']:.2%} of the pixels", highlight=False)
