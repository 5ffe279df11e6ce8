"""``furrow model SCANS -o MODEL``: scan set -> signed distance pyramid, RGBz, spheres, mesh."""

from __future__ import annotations

import argparse
import json
import math
import time
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
Both stages print what they did and have a row in the stage table.

Every stage, in order, is one list (volume/pipeline/stages.py); --plan prints it with the settings
these flags give (and which stages are on) and exits without writing anything.  furrow eval and
furrow batch take the same model flags and build the same model.

  furrow model out/plant_room -o out/plant_model --matte off --plan"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    from furrow.model_flags import add_model_arguments

    p.add_argument("scans", type=Path,
                   help="scan set: transforms.json, a folder holding one, a plain folder or a COLMAP folder")
    p.add_argument("-o", "--out", type=Path, required=True,
                   help="model folder to write (an existing model is replaced only with --overwrite)")
    p.add_argument("--plan", action="store_true",
                   help="print the stages in order with their settings (on / off with these flags) and exit; "
                        "nothing is written")
    add_model_arguments(p)
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
    p.add_argument("--debug", action="store_true", help="show tracebacks")


def _check_out(out: Path, overwrite: bool) -> None:
    """A bad output folder fails before any work."""
    if out.exists() and not (out / "model.json").is_file() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"{out}: exists and is not a furrow model folder; choose another output")
    if out.exists() and (out / "model.json").is_file() and not overwrite:
        raise ValueError(f"{out}: model already exists (use --overwrite to replace it)")


def _save_settings(args) -> dict:
    """The save stage's settings: the output folder and the --capture-env* lighting (loaded here: a
    bad map fails before the long build)."""
    save = {"out": Path(args.out)}
    if args.capture_env is None and args.capture_env_fisheye is None and args.capture_env_mirrorball is None:
        return save
    from render.shading.capture_env import capture_envmap

    env = capture_envmap(args.capture_env, args.capture_env_fisheye, args.capture_env_mirrorball,
                         fov_deg=args.capture_env_fov, convention=args.capture_env_convention)
    src = args.capture_env or f"{'fisheye' if args.capture_env_fisheye else 'mirror ball'} " \
                              f"{args.capture_env_fisheye or args.capture_env_mirrorball}"
    return {**save, "capture_env": env, "capture_env_rotation": args.capture_env_rotation, "capture_env_source": src}


def run(args, console) -> int:
    from capture.sources import open_source
    from furrow.console import StageTimer
    from furrow.model_flags import pipeline_config, pipeline_hooks, print_plan
    from volume.pipeline.runner import run_pipeline

    out = Path(args.out)
    if args.plan:  # nothing is read but the cameras, nothing is written
        cfg = pipeline_config(args, out=out)
        print_plan(console, cfg, open_source(args.scans, args.undistort), "furrow model")
        return 0
    _check_out(out, args.overwrite)
    cfg = pipeline_config(args, **_save_settings(args))
    timer = StageTimer()
    t0, c0 = time.perf_counter(), time.process_time()
    with run_pipeline(open_source(args.scans, args.undistort), cfg, pipeline_hooks(timer)) as done:
        summary = done.summary()
    summary["seconds"] = {k: round(v, 3) for k, v in timer.seconds.items()}
    summary["seconds_total"] = round(time.perf_counter() - t0, 3)
    summary["cpu_seconds"] = {k: round(v, 3) for k, v in timer.cpu_seconds.items()}
    summary["cpu_seconds_total"] = round(time.process_time() - c0, 3)
    summary["peak_mb"] = {k: round(v, 1) for k, v in timer.peak_mb.items()}
    summary["peak_mb_total"] = round(max(timer.peak_mb.values(), default=0.0), 1)
    summary["output"] = str(out)
    console.print(timer.table("furrow model: stage timings"))
    print_report(console, summary, out)
    if args.json:
        print(json.dumps(summary))
    return 0


def print_report(console, summary: dict, out) -> None:
    """The closing lines of furrow model: holes, surroundings, photometric, views, levels, and the depth-agreement
    check's finding where the views' depths and poses are at odds."""
    h = summary["holes"]
    if h:
        hb = [x["holes_before"] for x in h]
        ha = [x["holes_after"] for x in h]
        console.print(f"RGBz hole fraction per view (min / mean / max over {len(h)} views): before "
                      f"{min(hb):.4f} / {sum(hb) / len(hb):.4f} / {max(hb):.4f}, after closing "
                      f"{min(ha):.4f} / {sum(ha) / len(ha):.4f} / {max(ha):.4f}  (per view: --json)", highlight=False)
    _print_surroundings(console, summary["surroundings"])
    if summary.get("photometric"):
        console.print(photometric_report(summary["photometric"]), highlight=False)
        if summary["photometric"]["unaligned"]:
            console.print(f"[yellow]photometric: {len(summary['photometric']['unaligned'])} views share no usable "
                          "surface with a neighbour and keep their colour[/]", highlight=False)
    views, res = summary["views"], summary["resolution"]
    console.print(f"views: {views['kept']} of {views['of']} kept (--views {views['mode']}; reasons per view: "
                  f"--json / model.json); resolution: {res['reason']}", highlight=False)
    console.print(f"L_opt = {summary['l_opt']}  levels {summary['levels']}  "
                  f"surface voxels {summary['surface_voxels']}  "
                  f"spheres {summary['spheres']} (1 - IoU {summary['sphere_error']})  -> {out}", highlight=False)
    from volume.agreement import FAILED_AGREEMENT

    agree = summary.get("depth_agreement") or {}
    if agree.get("status") in FAILED_AGREEMENT:  # capture.depth_agreement, volume/agreement.py
        msg = agree["message"] if agree["message"].endswith("?") else agree["message"] + "."
        console.print(f"[yellow]depth agreement: {msg}{_reread_said(agree)} This model may be wrong (model.json "
                      "params.depth_agreement).[/]", highlight=False)
    if (agree.get("given_matte") or {}).get("inverted"):  # capture.matte_io.matte_verdict
        console.print(f"[yellow]depth agreement: {agree['given_matte']['message']}[/]", highlight=False)
    if agree.get("mispaired"):  # capture.depth_pairing
        done = agree.get("pairing_applied")
        done = (f" (paired again, {done['shift']:+d} frames; left out: {', '.join(done['left_out'])}: "
                "--depth-agreement fix)") if done else ""
        console.print(f"[yellow]depth agreement: {agree['pairing_message']}{done}[/]", highlight=False)
    flip = agree.get("colour_flip") or {}
    if flip.get("flipped"):  # capture.colour_flip
        console.print(f"[yellow]depth agreement: {flip['message']}[/]", highlight=False)
    if agree.get("colour_offset"):  # capture.depth_registration
        done = " (moved back: --depth-agreement fix)" if agree.get("colour_offset_applied") else ""
        console.print(f"[yellow]depth agreement: {agree['colour_offset_message']}{done}[/]", highlight=False)
    target = summary.get("sphere_target")
    if target is not None and summary["sphere_error"] > target:  # volume.spheres.fit_spheres: its best, reported
        console.print(f"[yellow]spheres: 1 - IoU {summary['sphere_error']:.3f} misses the target {target:g} "
                      "(--sphere-error): the occluder spheres the shadows use cover the solid coarsely "
                      "(volume/spheres.py)[/]", highlight=False)


def _print_blurred(console, pl: dict) -> None:
    """The frames capture.blurred_views found blurred where the others are sharp: left out, or kept (the default)."""
    for key, done in (("blurred_left_out", "left out of the model (--blurred-views 'leave out')"),
                      ("blurred_kept", "kept ('leave out' leaves them out: a conifer before a bright sky gained "
                                       "3.4 dB held out, a fur ball lost 1.1)")):
        if pl.get(key):
            console.print(f"[yellow]background plate: {len(pl[key])} frame(s) blurred where the others are sharp "
                          f"({', '.join(pl[key][:8])}{', ...' if len(pl[key]) > 8 else ''}): {done}[/yellow]",
                          highlight=False)


def _reread_said(agree: dict) -> str:
    """What --depth-agreement fix did to the depth maps' reading (volume/agreement.py), for the closing line."""
    applied = agree.get("reading_applied")
    if agree.get("disparity_applied") is not None:
        return (f" The depth maps were read as disparity, depth = {agree['disparity_applied']:.4g} / value "
                "(--depth-agreement fix).")
    if agree.get("view_scales_applied"):
        return " Each view's depth was scaled by its own factor (model.json; --depth-agreement fix)."
    if not applied:
        return ""
    return (" The depth maps were read as z-depth (--depth-agreement fix)." if applied == "range" else
            f" The depth maps were flipped back ({applied}; --depth-agreement fix).")


#: The photometric record's per-view table is printed up to this many views; past it, or where no alignment was
#: applied (every row EV 0, WB 1), one line says the gains' range and the table stays in model.json.
PHOTOMETRIC_TABLE_ROWS = 24


def photometric_report(rec: dict):
    """The photometric record for the report: its per-view table (:func:`photometric_table`), or one line where
    the alignment was not applied or the views are more than PHOTOMETRIC_TABLE_ROWS."""
    chosen = (rec.get("check") or {}).get("chosen")
    if chosen != "none" and len(rec["views"]) <= PHOTOMETRIC_TABLE_ROWS:
        return photometric_table(rec)
    head = (f"photometric alignment ({rec['pairs']} view pairs, {rec['samples']} samples, residual "
            f"{rec['residual_log']:.4f} log)")
    if chosen == "none":
        return f"{head}: none applied, every view keeps its colour (the check's reason above; model.json)"
    ev = [v["ev"] for v in rec["views"]]
    wb = " ".join(f"{min(v['wb'][c] for v in rec['views']):.3f}-{max(v['wb'][c] for v in rec['views']):.3f}"
                  for c in range(3))
    return (f"{head}, applied: {chosen or 'all'}: EV {min(ev):+.3f} to {max(ev):+.3f} over {len(ev)} views, "
            f"WB r g b {wb} (per view: model.json)")


def photometric_table(rec: dict):
    """Rich table of the per-view gains of a photometric record (EV and white balance)."""
    from rich.table import Table

    app = (f"appearance / exposure variance {rec['appearance_to_exposure']:.3g}" if "appearance_to_exposure" in rec
           else f"share of the EV spread taken for appearance {rec.get('appearance_share', 0):.2f}")
    applied = f"; applied: {rec['check']['chosen']}" if rec.get("check") else ""
    t = Table(title=f"photometric alignment ({rec['pairs']} view pairs, {rec['samples']} samples, "
                    f"reference {rec['reference']}, residual {rec['residual_log']:.4f} log, {app}{applied})")
    for c in ("view", "EV", "WB r", "WB g", "WB b"):
        t.add_column(c, justify="right")
    for v in rec["views"]:
        t.add_row(v["name"], f"{v['ev']:+.3f}", *(f"{x:.3f}" for x in v["wb"]))
    return t


def _print_matte_inputs(console, m: dict) -> None:
    """The matte record's lines on what its inputs needed or lacked: the object's shadow put into a fixed camera's
    plate (capture.plate_shadow), a blown-out background (capture.matting_cap.blown_partial), JPEG frames'
    subsampled chroma (capture.jpeg_chroma)."""
    if m.get("shadow_views"):
        lines = m.get("shadow_lines_dropped", 0)
        lines = (f", and {lines} pixels the frames' lines had estimated there (the shadow turns with the object) "
                 "counted as unknown") if lines else ""
        console.print(f"matte: in {m['shadow_views']} view(s) the object's shadow on its support was not in the "
                      f"plate; the plate was lit as the frame is there{lines} (--plate-shadow off leaves it)",
                      highlight=False)
    bb = m.get("blown_background") or {}
    if bb.get("views"):  # capture.matting_cap.blown_partial: a clipped background holds no colour
        names = bb.get("names") or [str(v) for v in bb["views"]]
        share = ", ".join(f"{v} ({s:.0%})" for v, s in zip(names, bb["shares"], strict=True))
        console.print(f"[yellow]matte: views {share} have that share of their partial pixels before a blown-out "
                      "background: their colour is a fill from the nearest measured colours, not a measurement (a "
                      "back-lit fringe loses its glow); a shorter exposure of those views would keep it[/yellow]",
                      highlight=False)
    if m.get("subsampled_chroma_views"):
        console.print(f"matte: {m['subsampled_chroma_views']} view(s) are JPEGs with subsampled chroma (a phone's "
                      "4:2:0); their alpha bound allows the chroma's error beside edges of colour", highlight=False)


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
    pl = rec.get("plate", {})
    if pl.get("mode") not in (None, "off", "unused"):
        err = "none held back" if pl["error_median"] is None else f"{pl['error_median']:.4f} linear"
        rms = pl.get("tried_rmse") or {}
        if len(rms) > 1:  # why this path: the paths' RMS on the held-back rings (capture.plate.choose_mode)
            err += " (chosen by RMS: " + ", ".join(f"{m} {v:.4f}" for m, v in rms.items() if v is not None) + ")"
        scale = f"; made at {pl['working_scale']:.2f} x the views' size (memory)" if "working_scale" in pl else ""
        est = pl.get("band_estimated_mean", 0.0)
        lines = f", {est:.1%} of it solved from the frames' lines (no frame saw it clean)" if est else ""
        scale += _noise_words(console, pl)
        console.print(f"background plate ({pl['mode']}): known behind {pl['band_known_mean']:.1%} of the matting "
                      f"band (least {pl['band_known_min']:.1%}){lines}; error on held-back background {err}{scale}",
                      highlight=False)
        gone = pl.get("refused") or []
        if gone:  # capture.plate_gate: a plate that loses to the view's own nearby background is not used
            name = [v.get("name", f"view {i}") for i, v in enumerate(pl["per_view"])]
            why = "; ".join(f"{name[i]}: {pl['per_view'][i]['refused']}" for i in gone[:3])
            why += "; ..." if len(gone) > 3 else ""
            lent = " they lent the other views nothing (those plates drawn again);" if pl.get("dropped_sources") else ""
            console.print(f"[yellow]background plate refused in {len(gone)} of {len(pl['per_view'])} view(s), their "
                          f"matte estimated without it (the background changed between frames?);{lent} {why}[/yellow]",
                          highlight=False)
        part = [i for i, v in enumerate(pl.get("per_view") or []) if (v.get("gate") or {}).get("sectors_refused")
                and i not in gone]
        if part:  # capture.plate_gate.SECTOR_GATE: a plate dropped where one side of the ring disagrees
            names = [pl["per_view"][i].get("name", str(i)) for i in part[:8]]
            console.print(f"[yellow]background plate dropped in part of {len(part)} view(s) where the ring disagrees "
                          f"with it on one side ({', '.join(names)}{', ...' if len(part) > 8 else ''})[/yellow]",
                          highlight=False)
        _print_blurred(console, pl)
        if (pl.get("vignetting") or {}).get("applied"):  # capture.vignetting: a moving camera's lens
            console.print(f"[yellow]background plate: the lens darkens the corners ({pl['vignetting']['reason']}): "
                          "taken out of every frame (--vignetting off leaves them)[/yellow]", highlight=False)
        ex = pl.get("exposure") or {}
        if ex.get("taken"):  # capture.plate_exposure.VIEW_GAINS: some views' own gains, the others' at 1
            ev = [sum(math.log2(g) for g in ex["gains"][i]) / 3 for i in ex["taken"]]
            console.print(f"exposure from the background: views {', '.join(map(str, ex['taken']))} taken alone "
                          f"({', '.join(f'{e:+.2f}' for e in ev)} EV; their own gains explain them), the other "
                          f"{ex['views'] - len(ex['taken'])} kept as they are", highlight=False)
    m = rec.get("matte", {})
    if m.get("mode") not in (None, "off"):
        console.print(f"matte ({m['mode']}): {m['methods']}, {m['seconds_per_view']:.2f} s per view (max "
                      f"{m['seconds_per_view_max']:.2f}), unknown {m['unknown_fraction_mean']:.2%}, partial alpha "
                      f"{m['partial_fraction_mean']:.2%} of the pixels", highlight=False)
    _print_matte_inputs(console, m)
    opq = m.get("opaque_sources") or {}
    if opq.get("views"):  # capture.matting_known.OPAQUE_SOURCES
        console.print(f"[yellow]matte: in {opq['views']} view(s) the background was known behind too few sure "
                      f"pixels; {opq['pixels']} pixels before a blown-out or unseen background took the colour of "
                      "the nearest opaque pixels (capture.matting_known.OPAQUE_SOURCES)[/yellow]", highlight=False)
    rim = m.get("rim") or {}
    if rim.get("views"):  # capture.matting_rim: the depth's opaque pixels of thin branches before a seen background
        console.print(f"matte: {rim['pixels']} depth-opaque pixels of thin branches in {rim['views']} view(s) solved "
                      "against the background the other views saw behind them (capture.matting_rim)", highlight=False)
    _print_matte_data(console, m)
    cells = m.get("cells") or {}
    if cells.get("across"):  # capture.matting_cells.KEEP_ACROSS: the photo's part across each pixel's line kept
        console.print(f"colour across views: {cells['across']} partial pixels given a cube's or the object's colour "
                      "kept the photo's part across their line: whole where a frame saw the background, shrunk "
                      "by the plate's uncertainty where not (capture.matting_cells.across_line)", highlight=False)
    _print_mean_check(console, cells.get("global") or {})


def _print_mean_check(console, g: dict) -> None:
    """The object's colour against the matte's mean (capture.matting_global.MEAN_CHECK, MEAN_BIAS_CHECK): one line
    where the mean was taken, or where it was far but the less sure of the two."""
    for rec_pass in (g.get("recross", {}).get("first") or {}, g):
        mean = rec_pass.get("mean") or {}
        far = (f"colour across views: the lines' crossing {_rgb(rec_pass.get('colour'))} lay {mean.get('gap', 0):.2f} "
               f"(relative) from the matte's own mean colour {_rgb(mean.get('colour'))}")
        if mean.get("taken"):  # the crossing too far from the matte's mean colour
            console.print(f"[yellow]{far}: the mean taken for the object's colour[/yellow]", highlight=False)
            break
        if "mean_error" in mean:  # far, but the mean's error from the alpha's above the crossing's sigma
            console.print(f"{far}, but the mean's error from the alpha's ({mean['mean_error']:.3f}: a background "
                          f"this bright) is above the crossing's sigma ({rec_pass.get('sigma', 0):.3f}): the crossing "
                          "kept (capture.matting_global.MEAN_BIAS_CHECK)", highlight=False)
            break


def _print_backdrop_refused(console, m: dict) -> None:
    """The matte record's line on the backdrops its plates beat (capture.matting_choice)."""
    br = m.get("backdrop_refused") or {}
    if br.get("views"):  # a dark, textured room is not a backdrop
        console.print(f"matte: a plain backdrop was detected in {br['views']} view(s), but their background plate "
                      f"predicts the held-back background better (RMS {min(br['plate_rmse']):.4f}-"
                      f"{max(br['plate_rmse']):.4f} against the backdrop's {min(br['backdrop_rmse']):.4f}-"
                      f"{max(br['backdrop_rmse']):.4f}): matted against the plate (capture.matting_choice)",
                      highlight=False)


def _print_sources(console, m: dict) -> None:
    """The matte record's line on the colour sources' measured coverage (capture.matting_sources)."""
    src = m.get("sources") or {}
    if src.get("coverage") is not None:
        console.print(f"matte: the depth's opaque pixels let the background through (their colour follows the plate "
                      f"behind them, median slope {src['median_slope']:.2f} over the views): their colour was unmixed "
                      f"at coverage {src['coverage']:.2f}, not taken as opaque (capture.matting_sources)",
                      highlight=False)


def _print_matte_data(console, m: dict) -> None:
    """The matte record's lines on where its data term came from (capture.matting_choice, capture.matting_channels,
    capture.matting_blind)."""
    if m.get("dark_backdrop_views"):  # capture.matting.DARK_BACKDROP
        console.print(f"[yellow]matte: {m['dark_backdrop_views']} view(s) matted against a black backdrop: over black "
                      "a faint strand's alpha and colour are known only as their product, and the matte takes the "
                      "colour of the body beside it; a lit fringe brighter than the body comes out too opaque "
                      "(path-traced fur: the kept views' alpha 1.5-1.8 x the truth at 0.1-0.5, held out over white "
                      "2.2 dB under the true matte). Over black the object is exact; for lighter backgrounds, shooting "
                      "before the room measured the fringe (the same bunny: alpha within 10 % at 0.1-0.9, over white "
                      "0.7 dB under the true matte; docs/matting.md)[/yellow]", highlight=False)
    fr = m.get("fringe") or {}
    if fr.get("views"):  # capture.matting_fringe
        console.print(f"matte: {fr['pixels']} partial pixels before a blown-out background in {fr['views']} view(s) "
                      "took the colour the view measured on its fringe, not its body's (capture.matting_fringe)",
                      highlight=False)
    inner = m.get("interior") or {}
    if inner.get("views"):  # capture.matting_interior
        console.print(f"matte: {inner['pixels']} pixels of the object's interior before a blown-out background in "
                      f"{inner['views']} view(s) kept their photo's colour (opaque over the camera's spread: "
                      "capture.matting_interior)", highlight=False)
    un = m.get("unseen_blown") or {}
    if un.get("views"):  # capture.matting_interior.unseen_fill
        console.print(f"matte: {un['pixels']} opaque pixels in {un['views']} view(s) whose background no frame saw, "
                      "beside a blown-out one, were brighter than the object around them (the window's light): "
                      "they took its colour (capture.matting_interior.unseen_fill)", highlight=False)
    _print_backdrop_refused(console, m)
    _print_sources(console, m)
    cch = m.get("clipped_channels") or {}
    if cch.get("views"):  # capture.matting_channels: the channels a clipped pixel keeps
        console.print(f"matte: {cch['pixels']} pixels clipped in some channels, not all, in {cch['views']} view(s): "
                      "their data term came from the channels clipped in neither (capture.matting_channels)",
                      highlight=False)
    bp = m.get("blind_prior") or {}
    if bp.get("weak_pixels"):  # capture.matting_blind.WEAK_PRIOR: the background about the object's colour
        console.print(f"matte: {bp['weak_pixels']} pixels before a background of nearly their own colour took the "
                      "depth coverage's alpha beside their weak data term (capture.matting_blind.WEAK_PRIOR)",
                      highlight=False)
    if bp.get("prior_pixels"):  # capture.matting_blind.IDENTITY_PRIOR: the depth's own coverage as alpha's prior
        r2 = bp.get("r2") or [0.0]
        console.print(f"matte: in {bp['prior_views']} view(s) {bp['prior_pixels']} pixels with a weak or no data term "
                      "took the depth's own coverage as their alpha's prior, weighed by how well it predicts the "
                      f"view's surer pixels (R^2 {min(r2):.2f}-{max(r2):.2f}; capture.matting_blind.IDENTITY_PRIOR)",
                      highlight=False)
    if bp.get("empty_pixels"):  # capture.matting_blind.EMPTY_PRIOR: no coverage prior, the depth saw nothing there
        console.print(f"matte: {bp['empty_pixels']} pixels in {bp['empty_views']} view(s) before a background of "
                      "nearly their own colour, with no object depth beside them, were pulled towards alpha 0: the "
                      "depth's coverage did not predict their view's surer pixels (capture.matting_blind.EMPTY_PRIOR)",
                      highlight=False)
    if bp.get("empty_refused_pixels"):  # capture.matting_blind.EMPTY_MAX_HOLES: a depth that may miss needles
        from capture.matting_blind import EMPTY_MAX_HOLES

        h = [x for x in bp.get("depth_holes") or [] if x > EMPTY_MAX_HOLES]
        why = (f"the depth has holes ({min(h):.0%}-{max(h):.0%} of its interior, more than "
               "capture.matting_blind.EMPTY_MAX_HOLES)" if h else "too little depth to check it")
        if h and "too little depth to check it" in (bp.get("empty_refused_reasons") or []):
            why += " or too little depth to check it"
        console.print(f"matte: in {bp['empty_refused_views']} view(s) {why}: where it saw nothing may be needles, so "
                      f"{bp['empty_refused_pixels']} weak pixels were not pulled towards alpha 0 and the Laplacian "
                      "alone decides them", highlight=False)
    if bp.get("unseen_pixels"):  # capture.matting_blind.UNSEEN_PRIOR: no background known, the photo not blown out
        console.print(f"matte: {bp['unseen_pixels']} pixels whose background no frame showed took the depth "
                      "coverage's alpha as their data term (capture.matting_blind.UNSEEN_PRIOR)", highlight=False)
    from capture.matting_guide import WEAK_GATE  # the share from which the Laplacian's guide is brightened too

    if bp.get("guided_views"):  # capture.matting_guide: views whose own weak share reached WEAK_GATE
        console.print(f"matte: the matting Laplacian's guide was brightened in {bp['guided_views']} of {bp['views']} "
                      f"view(s), where at least {WEAK_GATE:.0%} of the view's band had a weak data term "
                      "(capture.matting_guide)", highlight=False)

    # measured shares: 0.24-0.36 before a dark forest, 0.18 on the courtyard orbit, 0.002-0.05 on the courtyard
    # turntables and fur_similar_bg (docs/matting.md, stop 63)
    if (bp.get("weak_share") or 0.0) >= WEAK_GATE:  # the data term cannot tell the object from its background
        console.print(f"[yellow]matte: {bp['weak_share']:.0%} of the matting band is before a background of nearly "
                      "the object's own colour: there the data barely tells the object from the background, and the "
                      "alpha (the depth coverage's and the matting Laplacian's) comes out soft. Held out, conifers "
                      "before a dark forest scored sharpness 0.78-0.88 and SSIM 0.06-0.10 under their black twins "
                      "(docs/matting.md, stop 63). A backdrop of another colour than the object's helps[/yellow]",
                      highlight=False)


def _noise_words(console, pl: dict) -> str:
    """The plate line's words on the frames' noise (capture.noise, capture.noise_check); the warnings printed."""
    said = ""
    if pl.get("frame_texture") and pl.get("frame_detail", 0) >= 1.0:  # capture.noise.TEXTURE_RATIO
        said += (f"; the frames' fine detail ({pl['frame_detail']:.1f} 8-bit steps) is the room's texture, "
                 f"the noise between frames {pl['frame_noise']:.1f}")
    chk = pl.get("smoothing_check") or {}
    if chk and not chk["smoothed"]:  # capture.noise_check: the smoothed frames' plate lost to the frames' own
        console.print(f"[yellow]background plate: the frames' noise measured {pl['frame_noise']:.1f} 8-bit steps, "
                      f"but a plate from them smoothed predicted {chk['views']} views' held-back background worse "
                      f"(RMS {chk['rms_smoothed']:.4f} against {chk['rms_raw']:.4f}): made from them as they are "
                      "(a room's texture?)[/yellow]", highlight=False)
    if pl.get("frame_smoothing"):  # capture.noise: noisy frames, read smoothed by the plate stage
        said += (f"; the frames' noise {pl['frame_noise']:.1f} 8-bit steps: made from them smoothed "
                 "(bilateral filter" + (f"; held-back RMS on {chk['views']} views {chk['rms_raw']:.4f} -> "
                                        f"{chk['rms_smoothed']:.4f})" if chk.get("rms_raw") is not None
                                        and chk.get("rms_smoothed") is not None else ")"))
    if pl.get("frame_noise_note"):  # capture.noise.noise_note: the frames' noise not measured or maybe low
        console.print(f"[yellow]background plate: the frames' noise {pl['frame_noise_note']}[/yellow]",
                      highlight=False)
    return said


def _rgb(c) -> str:
    return "?" if not c else "(" + ", ".join(f"{x:.3f}" for x in c) + ")"
