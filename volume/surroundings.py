"""The object apart from its surroundings, before fusion: the extent, background plate and matte
stages of the pipeline (volume/pipeline/stages.py; issues 20 and 30).

* **extent** (``capture.extent.remove_surroundings``): depth of the support plane, far depth and
  clutter set to 0, so that fusion, RGBz and every method see the object alone; the bounds shrink
  to what is left.  A whole-set stage: the plane and the floater grid need every view.  When a
  plate stage follows, the scans as captured (their depth of the table and the room) and the
  plane wait for it in ``work.parts`` (``captured``, ``support``).
* **background plate** (``capture.plate.background_plates``): the background behind the object in
  every view, from the other views (or the user's plates); a whole-set stage.  Each view's plate,
  cropped to where it is known, waits in ``work.parts["plates"]`` for the matte stage; a capture
  too large to hold at once gets its plates at a working scale (capture.plate_scale), brought to
  each view's size when the matte stage reads them.  Skipped
  (its record says so) when the matte mode reads no plate (off, estimate, backdrop) or, for the
  auto matte, when every view shows a plain backdrop (the backdrop path reads none).
* **matte** (``capture.matting.matte_scan``): each view gets a soft straight alpha matte and the
  object's straight colour under it, with its plate where there is one; the scan's colour becomes
  that foreground colour (float32 linear) and its ``alpha`` the matte, which
  ``volume.rgbz.build_rgbz`` stores in the model (``RgbzImages.rgb`` / ``RgbzImages.alpha``).
  Its views go through the runner's per-view map (:func:`matte_one`, picklable); pymatting's numba
  kernels are compiled once before the views (the "matte warm-up" row) so that the matte row's time
  is the matting's.  Mode 'off' keeps the binary depth mask as the only one: a capture's own matte
  is dropped.  With a plate, each view also hands back a bounded draw of its partial pixels' lines
  (the photo, the plate, the matte's alpha and colour, a 3D point from the depth:
  capture.matting_lines.line_samples, capture.matting_cells.fit_sample), and after the views every
  partial pixel gets the colour its 3D cell's lines cross at across the views, where they cross: the
  cubes fitted from the draws, then applied view by view in the per-view map, each view recomputing
  its own samples (:func:`cell_colour_passes`, the "matte colour across views" row; issue 30 seventh
  round: the same needles before different parts of the room; :func:`cell_colour_stage` the
  all-at-once reference).  ``--matte-across auto`` (the default) skips it, the views drawing no
  lines, where the plate says the lines cannot cross (:func:`across_skipped`: a dark room behind the
  object, as on the phone captures; its own row in the stage table and its reason in the record).

Each reports its own numbers (the model report's ``surroundings``).
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace

import numpy as np

from capture.extent import remove_surroundings
from capture.matting import matte_scan, warm_up
from capture.matting_cap import BLOWN_VIEW_SHARE, blown_partial
from capture.matting_cells import fit_cap
from capture.noise import noise_frames, noise_note, noise_parts, smooth_frame, smoothing
from capture.plate import background_plates
from capture.plate_scale import grow_plate, plate_scale, shrink_scan
from capture.scan import Scan
from capture.scan_store import scan_has_alpha
from capture.view_map import PerView
from volume.matte_sources import sources_coverage

#: Matte modes that read no plate: the plate stage is skipped for them.
NO_PLATE_MATTES = ("off", "estimate", "backdrop")


def extent_stage(work, cfg, ctx):
    """The extent stage (cfg: capture.extent.ExtentConfig): the surroundings out of the depth (module docstring)."""
    ss, rep = remove_surroundings(work.scanset, cfg, ctx.keep, ctx.map_views)
    out = work.with_scanset(ss).record("extent", rep.record())
    if _plates_wanted(ctx.config):
        out = out.made(captured=work.scans, support=(rep.plane, (rep.focus_center, rep.focus_radius)))
    return out


#: Blurred views are left out only where at least this share of the views stays (else kept, and said).
BLURRED_KEEP = 0.6


def _plates_wanted(config) -> bool:
    return config.plate is not None and config.plate.mode != "off" and config.matte.mode not in NO_PLATE_MATTES


def plate_stage(work, cfg, ctx):
    """The background plate stage (cfg: capture.plate.PlateConfig; module docstring): each view's
    plate in ``work.parts["plates"]`` (view index -> cropped capture.plate.Plate), the record."""
    if not _plates_wanted(ctx.config):
        return work.record("background plate", {"mode": "unused", "matte": ctx.config.matte.mode})
    if ctx.config.matte.mode == "auto" and cfg.plates_dir is None and _all_plain(work.scans):
        return work.record("background plate", {"mode": "unused", "matte": "auto: a plain backdrop in every view"})
    from capture.plate_io import read_user_plates

    captured = work.parts.get("captured") or work.scans
    plane, focus = work.parts.get("support") or (None, None)
    user = None if cfg.plates_dir is None else read_user_plates(cfg.plates_dir, work.scans)
    scale = plate_scale(len(work.refs), *work.scans[0].depth.shape[:2]) if user is None and work.scans else 1.0
    noise, parts = float("nan"), None  # the frames' sensor noise (capture.noise), measured on a few of them
    if user is None and cfg.denoise == "auto":
        picks = [work.scans[i] for i in noise_frames(len(work.scans))]
        noise, *parts = noise_parts([s.rgb for s in picks], [s.depth for s in picks])
    smooth, check = smoothing(noise), None
    if smooth > 0:  # capture.noise_check: the smoothed frames' plate against the frames' own, on a few views
        check = _smoothing_check(work.scans, captured, scale, smooth, (plane, focus, cfg))
        smooth = smooth if check["smoothed"] else 0.0
    views = _plate_views(work.scans, captured, scale, smooth)
    plates, rec = background_plates(views if user is None else list(views), cfg, plane, focus, user, crop=True)
    if scale < 1.0:
        rec = {**rec, "working_scale": round(scale, 4)}
    if np.isfinite(noise):  # capture.noise: the frames' noise and the smoothing the plate read them with
        rec = {**rec, "frame_noise": round(noise, 3), "frame_smoothing": round(smooth, 3),
               "frame_detail": round(parts[0], 3)}
        if check is not None:
            rec = {**rec, "smoothing_check": check}
        if np.isfinite(parts[1]):  # the noise between frames: where it is the one taken, the detail was texture
            rec = {**rec, "frame_noise_between": round(parts[1], 3), "frame_texture": bool(noise < parts[0])}
    note = noise_note(noise, [s.name for s in picks]) if user is None and cfg.denoise == "auto" else None
    if note:  # not measured, or read on JPEG frames: the record and the console say so
        rec = {**rec, "frame_noise": rec.get("frame_noise"), "frame_noise_note": note}
    if "per_view" in rec:  # each view's record names its frame (the console names refused views by it)
        rec = {**rec, "per_view": [{"name": ref.name, **r} for ref, r in zip(work.refs, rec["per_view"], strict=True)]}
    work, plates, rec = _without_blurred(work, plates, rec, cfg.blurred == "leave out")
    if (rec.get("vignetting") or {}).get("applied"):  # the plates' frames were divided by v: so are the scans
        work = _devignetted(work, rec["vignetting"], ctx)
    store = dict(zip((ref.index for ref in work.refs), plates, strict=True))
    return work.made(plates=store, captured=None).record("background plate", rec)


def _without_blurred(work, plates: list, rec: dict, leave_out: bool = True):
    """(work, plates, rec) without the views capture.blurred_views calls blurred, with ``leave_out`` (--blurred-views
    'leave out') and where at least BLURRED_KEEP of the views are left; the record's ``blurred_left_out`` names them,
    or ``blurred_kept`` (kept: by default, or too many); the warning says which."""
    blurred = [i for i, r in enumerate(rec.get("per_view", [])) if (r.get("blur") or {}).get("blurred")]
    if not blurred:
        return work, plates, rec
    names = [work.refs[i].name for i in blurred]
    log = logging.getLogger("furrow.capture")
    if not leave_out or len(work.refs) - len(blurred) < BLURRED_KEEP * len(work.refs):
        log.warning("background plate: %d of %d views blurred where the others are sharp (%s): kept (%s)",
                    len(blurred), len(work.refs), ", ".join(names),
                    "too many to leave out" if leave_out else "--blurred-views 'leave out' leaves them out")
        return work, plates, {**rec, "blurred_kept": names}
    keep = [i for i in range(len(work.refs)) if i not in blurred]
    log.warning("background plate: %d view(s) blurred where the others are sharp, left out (%s; capture.blurred_views)",
                len(blurred), ", ".join(names))
    work = replace(work, refs=tuple(work.refs[i] for i in keep), scans=tuple(work.scans[i] for i in keep))
    return work, [plates[i] for i in keep], {**rec, "blurred_left_out": names}


def _devignetted(work, vig: dict, ctx):
    """``work`` with every scan's linear colour divided by the lens's vignetting (capture.vignetting; ``vig``: the
    plate record's), each new scan kept (``ctx.keep``), said on the console's log."""
    from capture.view_map import PerView, or_serial
    from capture.vignetting import devignette_view

    logging.getLogger("furrow.capture").warning("background plate: the lens darkens the corners: %s; taken out of "
                                                "every frame (--vignetting off leaves them)", vig["reason"])
    coef = np.asarray(vig["coefficients"], np.float64)
    scans = or_serial(ctx.map_views, ctx.keep)(devignette_view, list(work.scans), PerView((coef,) * len(work.scans)),
                                               "vignetting")[0]
    return replace(work, scans=tuple(scans))


def _smoothing_check(scans, captured, scale: float, smooth: float, setting) -> dict:
    """capture.noise_check.smoothing_check on its views (check_frames), each read once and taken both ways (as read,
    smoothed on ``smooth``) at the plate's ``scale`` (:func:`_plate_views`' views);
    ``setting``: (plane, focus, PlateConfig) as the plate stage's."""
    from capture.noise_check import check_frames, smoothing_check
    from capture.plate_threads import thread_map

    idx = check_frames(len(scans))

    def both(i):  # each view read once (a spilled view is a file), shrunk as read and smoothed
        s, c = scans[i], captured[i]
        rgb, depth, captured_depth = s.rgb, s.depth, c.depth  # as _plate_views passes them
        return tuple(shrink_scan(s.camera, x, depth, captured_depth, scale) for x in (rgb, smooth_frame(rgb, smooth)))

    raw, smoothed = zip(*thread_map(both, idx)) if idx else ((), ())
    return smoothing_check(list(raw), list(smoothed), *setting)


def _plate_views(scans, captured, scale: float, smooth: float = 0.0):
    """The plate stage's views, read a few at a time side by side (a generator; capture.plate_threads),
    float16 colour, shrunk to ``scale`` (the working scale of capture.plate_scale: below 1 when all the
    views at full size would pass its memory budget; never for user plates, which are at the views' size),
    the colour smoothed first on the colour scale ``smooth`` (capture.noise.smooth_frame; 0: as read)."""
    from capture.plate_threads import thread_map

    def one(sc):
        s, c = sc
        rgb = smooth_frame(s.rgb, smooth)  # the frames' sensor noise (capture.noise)
        return shrink_scan(s.camera, rgb, s.depth, c.depth, scale)  # shrink_view's view (SHRINK_FAST)

    # read a few views ahead side by side (the plate stage's own threads take them as they come)
    return thread_map(one, zip(scans, captured, strict=True))


def _all_plain(scans) -> bool:
    """Whether every view shows a plain backdrop (capture.matting.detect_backdrop) that no plate can beat
    (capture.matting_choice.exact_backdrop): the auto matte then takes the backdrop path and reads no plate."""
    from capture.matting import depth_trimap, detect_backdrop
    from capture.matting_choice import exact_backdrop

    return all(s.alpha is None and exact_backdrop(s.linear_rgb, s.depth, detect_backdrop(s.linear_rgb,
                                                                                         depth_trimap(s.depth)))
               for s in scans)


def matte_stage(work, cfg, ctx):
    """The matte stage (cfg: capture.matting.MatteConfig): its warm-up row, then every view through
    :func:`matte_one` with its plate (module docstring), then the record (:func:`matte_record`).
    The views' config carries the depth's measured width (:func:`matte_given`)."""
    cfg = matte_given(cfg, work)
    with ctx.row("matte warm-up"):
        matte_warm_up(cfg)
    plates = work.parts.get("plates") or {}
    skipped = across_skipped(cfg, work.records.get("background plate")) if plates else None
    if skipped is not None:
        cfg = replace(cfg, across="off")  # the views draw no lines
        logging.getLogger("furrow.capture").info("matte colour across views skipped: %s", skipped)
        with ctx.row("matte colour across views: skipped"):  # the stage table says so (why: the record)
            pass
    cfg, sources = sources_coverage(cfg, work, plates, ctx)
    cap = fit_cap(len(work.refs))
    per_view = PerView([(_for_frame(cfg, ref), plates.get(ref.index), cap, k)  # its plate only
                        for k, ref in enumerate(work.refs)])
    with ctx.row("matte"):
        scans, notes = ctx.map_views(matte_one, work, per_view, "matting")
    fits = [None if n is None else n.pop("lines", None) for n in notes]
    cells = None if skipped is None else {"skipped": skipped}
    if any(x is not None for x in fits):
        with ctx.row("matte colour across views"):
            sa = [None if n is None else (n.get("colour") or {}).get("sigma_alpha") for n in notes]
            ev = (work.records.get("background plate") or {}).get("gains_ev")
            gains = 2.0 ** np.asarray(ev, np.float64) if ev is not None and len(ev) == len(fits) else None
            photos = [plates.get(ref.index) for ref in work.refs], work.scans
            scans, cells = cell_colour_passes(scans, photos, fits, sa, gains, ctx.map_views)
    out = matte_record(replace(work, scans=scans).made(plates=None), {"matte": notes}, cfg)
    out = out if sources is None else out.record("matte", {**out.records["matte"], "sources": sources})
    return out if cells is None else out.record("matte", {**out.records["matte"], "cells": cells})


def across_skipped(cfg, plate_record: dict | None) -> str | None:
    """Why the matte stage gives no partial pixel its 3D cell's colour across the views, or None when it
    does (``cfg``: the MatteConfig, ``across`` on / off / auto; ``plate_record``: the background plate
    stage's).  Auto skips it where the views' mean share of the matting band with a seen, lit
    background (capture.matting_cells.band_crossing, the record's ``band_crossing_mean``) is under
    capture.matting_cells.MIN_CROSSING: there the lines cannot cross and the unmixed colour's
    premultiplied error (a - a_true) B is small (measured: docs/speed.md, round 7)."""
    from capture.matting_cells import MIN_CROSSING

    if cfg.across == "off":
        return "off (--matte-across off)"
    share = (plate_record or {}).get("band_crossing_mean")
    if cfg.across == "on" or share is None or share >= MIN_CROSSING:
        return None
    return (f"auto: {share:.3f} of the matting band has a background a frame saw, brighter than the object, "
            f"under {MIN_CROSSING} (capture.matting_cells.MIN_CROSSING): the lines cannot cross")


def cell_colour_passes(scans, photos, fits, sigma_alpha, gains, map_views):
    """Every view's partial pixels given their 3D cell's colour from the lines across the views, in
    bounded memory (capture.matting_cells): the cubes' table from the views' fit samples (``fits``,
    capture.matting_cells.fit_sample or None), then each view through :func:`cell_colour_one` in the
    per-view map ``map_views``, which recomputes its samples from ``photos`` (each view's plate or
    None, the scans before the matte: the photos) and the matted ``scans``.  ``sigma_alpha``,
    ``gains``: as :func:`cell_colour_stage` (the reference, all the views' samples at once, which
    gives the same colours where nothing is drawn).  (The scans, the record.)"""
    from capture.matting_cells import fit_cells
    from capture.matting_contrast import pooled_alpha_errors

    table, rec = fit_cells(fits, gains)
    if table is None:
        if rec.get("reason"):  # a gate or too few lines: say so (the record keeps it too)
            logging.getLogger("furrow.capture").info("matte colour across views: every view keeps its own colour: %s",
                                                     rec["reason"])
        return tuple(scans), rec
    plates, originals = photos
    g = [None] * len(fits) if gains is None else list(np.asarray(gains, np.float64))
    # as cell_colours: a view without its own alpha error borrows the views' median (capture.matting_contrast)
    sigma_alpha, rec["alpha_error_pooled"] = pooled_alpha_errors(sigma_alpha, [f is not None for f in fits])
    items = [None if f is None or plates[k] is None else (plates[k], originals[k], table, sigma_alpha[k], g[k], k)
             for k, f in enumerate(fits)]
    out, notes = map_views(cell_colour_one, tuple(scans), PerView(items), "colour across views")
    have = [n for n in notes if n is not None]
    for key, name in (("crossed", "crossed"), ("coloured", "coloured"), ("global", "global_coloured"),
                      ("filled", "filled_coloured"), ("across", "across")):
        rec[name] = rec.get(name, 0) + sum(int(n.get(key, 0)) for n in have)
    blind = sum(int(n["blind"]) for n in have)
    if blind:
        rec["views_without_alpha_error"] = blind
    if not rec["crossed"]:
        rec["reason"] = "the lines cross in no cell (too few, or the backgrounds behind them too alike)"
    return out, rec


def cell_colour_one(view, ref, arg):
    """One matted view's partial pixels given their cube's colour (:func:`cell_colour_passes`; ``arg``:
    None, or (its plate, its photo's scan, the cubes' table, its alpha error or None, its gain or None, its
    position)):
    (the scan or None when unchanged, the counts: crossed, coloured, blind)."""
    if arg is None:
        return None, None
    from capture.matting_cells import apply_cells
    from capture.matting_lines import line_samples

    plate, photo, table, sa, gain, v = arg
    plate = grow_plate(plate, *view.depth.shape[:2])
    s = line_samples(view.camera, photo.linear_rgb, plate.background, plate.known, view.alpha, view.rgb,
                     view.depth, plate.estimated, plate.sigma)
    c, counts = apply_cells(s, table, sa, gain, view=v)
    counts["blind"] = s is not None and sa is None
    if c is None:
        return None, counts
    return with_cell_colours(view, c), counts


def with_cell_colours(scan: Scan, c) -> Scan:
    """``scan`` with its cube colours ``c`` (flat indices, colours (n, 3), implied alphas (n,):
    capture.matting_lines.cell_colours) put in (the alphas too where CELL_ALPHA)."""
    from capture.matting_lines import CELL_ALPHA

    rgb = np.array(scan.rgb, np.float32)
    rgb.reshape(-1, 3)[c[0]] = c[1]
    alpha = scan.alpha
    if CELL_ALPHA:
        alpha = np.array(alpha, np.float32)
        alpha.reshape(-1)[c[0]] = c[2]
    return Scan(rgb, scan.depth, scan.camera, scan.name, alpha)


def cell_colour_stage(scans, samples, sigma_alpha, gains, keep):
    """The reference of :func:`cell_colour_passes`, every view's samples at once: every view's partial
    pixels given their 3D cell's colour from the lines across the views where it is expected to beat
    the unmixed colour (capture.matting_lines.cell_colours; ``samples``: each view's line samples or
    None, ``sigma_alpha``: each view's alpha error from its colour record or None, ``gains``: the
    plate's exposure gains (V, 3) or None): (the scans, the record)."""
    from capture.matting_lines import cell_colours

    colours, rec = cell_colours(samples, sigma_alpha, gains)
    out = list(scans)
    for k, c in enumerate(colours):
        if c is not None:
            out[k] = keep(with_cell_colours(out[k], c))
    return tuple(out), rec


def _for_frame(cfg, ref):
    """The matte config for the view of ``ref`` (capture.sources.FrameRef): ``subsampled`` where its colour file
    is a JPEG with subsampled chroma (capture.jpeg_chroma)."""
    from capture.jpeg_chroma import subsampled_chroma
    from capture.sources import resolve_file

    if cfg.mode == "off" or cfg.jpeg_chroma == "off" or ref is None or ref.rgb is None:
        return cfg
    try:
        path = resolve_file(ref.rgb, "colour image", ref.where)
    except ValueError:  # ScanIOError: the read stage has said so already
        return cfg
    return replace(cfg, subsampled=True) if subsampled_chroma(path) else cfg


def matte_one(view, ref, arg):
    """:func:`matte_view` of one view with its plate (``arg``: (MatteConfig, the view's Plate or None[,
    the most lines it hands back for the fit, the draw's seed])."""
    cfg, plate, *fit = arg
    if plate is not None:
        plate = grow_plate(plate, *view.depth.shape[:2])
    return matte_view(view, ref, cfg, plate, *fit)


def matte_warm_up(cfg) -> None:
    """Before the matte stage's views: pymatting's kernels compiled (nothing for mode 'off')."""
    if cfg.mode != "off":
        warm_up()


def matte_given(cfg, work):
    """The matte config the views get: with the width the depth was measured at (the scan set's
    ``depth_size``) when it is known and the views' working resolution may use it."""
    size = (work.metadata or {}).get("depth_size")
    plane, focus = (getattr(work, "parts", None) or {}).get("support") or (None, None)
    if plane is not None and focus is not None:  # capture.plate_shadow: the object's shadow on its support
        cfg = replace(cfg, support=tuple(float(x) for x in (*np.asarray(plane)[:4], *np.asarray(focus[0]), focus[1])))
    if cfg.resolution != "working" or not size:
        return cfg
    return replace(cfg, depth_width=int(size[0]))


def matte_view(view, ref, cfg, plate=None, cap=None, seed=0):
    """The matte stage for one view (cfg: capture.matting.MatteConfig; ``plate``: its background
    plate or None): (the scan with its foreground colour and matte, note: method, seconds, unknown
    and partial fractions); mode 'off': the scan without a matte, no note.  With a plate, the note's
    ``lines``: the partial pixels' line samples, at most ``cap`` of them drawn by ``seed``
    (capture.matting_cells.fit_sample; None: all of them, for the reference cell_colour_stage)."""
    if cfg.mode == "off":
        return (Scan(view.rgb, view.depth, view.camera, view.name) if scan_has_alpha(view) else view), None
    t0 = time.perf_counter()
    m = matte_scan(view, view.depth, cfg, plate)
    note = {"method": m.method, "seconds": time.perf_counter() - t0, "unknown": m.unknown_fraction, "scale": m.scale,
            "partial": float(np.mean((m.alpha > 0) & (m.alpha < 1))), "subsampled_chroma": cfg.subsampled}
    for key in ("blind_prior", "colour", "opaque_sources", "fringe", "interior", "unseen_blown", "rim",
                "clipped_channels", "shadow", "backdrop_refused", "dark_backdrop"):
        if m.notes.get(key):
            note[key] = m.notes[key]
    if plate is not None:  # the partial pixels before a blown-out plate: a fill, not a measurement
        note["blown"] = blown_partial(m.alpha, plate.background, plate.known)
    if plate is not None and m.method.startswith("plate"):
        from capture import matting_lines as ml

        if ml.CELLS and cfg.across != "off":  # the partial pixels' lines for the colour across the views
            # (popped by matte_stage)
            lines = ml.line_samples(view.camera, view.linear_rgb, plate.background, plate.known, m.alpha,
                                    m.foreground, view.depth, plate.estimated, plate.sigma)
            if cap is not None:
                from capture.matting_cells import fit_sample

                lines = fit_sample(lines, cap, seed)
            note["lines"] = lines
    return Scan(m.foreground, view.depth, view.camera, view.name, m.alpha), note


def _share(part: int, whole: int) -> float | None:
    """``part`` / ``whole`` to 4 places, None when ``whole`` is 0."""
    return round(part / whole, 4) if whole else None


def matte_record(work, notes: dict, cfg):
    """The matte stage's record from its views' notes (``notes["matte"]``)."""
    if cfg.mode == "off":
        return work.record("matte", {"mode": "off"})
    n = [x for x in notes["matte"] if x is not None]
    methods = [x["method"] for x in n]
    sec = [x["seconds"] for x in n]
    bp = [x["blind_prior"] for x in n if "blind_prior" in x]
    blind = {"views": len(bp), "used": sum(b["used"] for b in bp),
             "reasons": sorted({b["reason"] for b in bp if not b["used"]}),
             "r2": [b["r2"] for b in bp if "r2" in b], "blind_pixels": sum(b["blind"] for b in bp),
             "weak_pixels": sum(b.get("weak", 0) for b in bp if b["used"]),  # those the prior went to
             "unseen_pixels": sum(b.get("unseen", 0) for b in bp if b["used"]),  # UNSEEN_PRIOR: no B, photo not blown
             "empty_pixels": sum(b.get("empty", 0) for b in bp),  # EMPTY_PRIOR: coverage refused, weak, no depth near
             "empty_views": sum(bool(b.get("empty")) for b in bp),
             "empty_refused_pixels": sum(b.get("empty_refused", 0) for b in bp),  # EMPTY_MAX_HOLES: depth with holes
             "empty_refused_views": sum(bool(b.get("empty_refused")) for b in bp),
             "prior_pixels": sum(b.get("prior", 0) for b in bp),  # IDENTITY_PRIOR: the coverage given
             "prior_views": sum(bool(b.get("prior")) for b in bp),
             "empty_refused_reasons": sorted({b["empty_reason"] for b in bp if "empty_reason" in b}),
             "depth_holes": [b["depth_holes"] for b in bp if "depth_holes" in b],
             "weak_share": _share(sum(b.get("weak", 0) for b in bp), sum(b.get("band", 0) for b in bp)),
             "guided_views": sum(bool(b.get("guided")) for b in bp)}  # capture.matting_guide: guide brightened
    col = [x["colour"] for x in n if "colour" in x]
    counts = ("estimated", "unmixed", "filled", "seen_filled")
    colour = {"views": len(col), **{k: sum(c.get(k, 0) for c in col) for k in counts},
              "reasons": sorted({c["reason"] for c in col if "reason" in c}),
              "sigma_fill": [c["sigma_fill"] for c in col], "sigma_alpha": [c.get("sigma_alpha") for c in col]}
    opq = [x["opaque_sources"] for x in n if "opaque_sources" in x]
    fringe = [x["fringe"] for x in n if "fringe" in x]  # capture.matting_fringe
    inner = [x["interior"] for x in n if "interior" in x]  # capture.matting_interior
    unseen = [x["unseen_blown"] for x in n if "unseen_blown" in x]
    rim = [x["rim"] for x in n if "rim" in x]
    refused = [x["backdrop_refused"] for x in n if "backdrop_refused" in x]  # capture.matting_choice
    cch = [x["clipped_channels"] for x in n if "clipped_channels" in x]
    blown = [(i, x["blown"]) for i, x in enumerate(notes["matte"]) if x is not None and "blown" in x]
    shares = {i: b / p for i, (b, p) in blown if p}
    named = [i for i in sorted(shares) if shares[i] >= BLOWN_VIEW_SHARE]
    refs = getattr(work, "refs", None) or ()
    return work.record("matte", {"blind_prior": blind, "colour": colour,
        "opaque_sources": {"views": len(opq), "pixels": int(sum(opq))},
        "fringe": {"views": len(fringe), "pixels": int(sum(fringe))},
        "interior": {"views": len(inner), "pixels": int(sum(inner))},
        "unseen_blown": {"views": len(unseen), "pixels": int(sum(unseen))},
        "dark_backdrop_views": sum(bool(x.get("dark_backdrop")) for x in n),  # capture.matting.DARK_BACKDROP
        "rim": {"views": len(rim), "pixels": int(sum(rim))},
        "backdrop_refused": {"views": len(refused), "backdrop_rmse": [r["backdrop_rmse"] for r in refused],
                             "plate_rmse": [r["plate_rmse"] for r in refused]},
        "clipped_channels": {"views": len(cch), "pixels": int(sum(cch))},
        "blown_background": {"pixels": int(sum(b for _, (b, _) in blown)),  # capture.matting_cap.blown_partial
                             "views": named, "shares": [round(shares[i], 3) for i in named],
                             "names": [refs[i].name if i < len(refs) else str(i) for i in named]},
        "mode": cfg.mode, "backdrop": cfg.backdrop, "methods": {k: methods.count(k) for k in sorted(set(methods))},
        "resolution": cfg.resolution, "scale_mean": round(float(np.mean([x.get("scale", 1.0) for x in n])), 4),
        "shadow_views": sum(bool(x.get("shadow")) for x in n),  # capture.plate_shadow
        "shadow_lines_dropped": sum((x.get("shadow") or {}).get("lines_dropped", 0) for x in n),
        "subsampled_chroma_views": sum(bool(x.get("subsampled_chroma")) for x in n),  # capture.jpeg_chroma
        "seconds_per_view": round(float(np.mean(sec)), 4), "seconds_per_view_max": round(float(np.max(sec)), 4),
        "unknown_fraction_mean": round(float(np.mean([x["unknown"] for x in n])), 5),
        "partial_fraction_mean": round(float(np.mean([x["partial"] for x in n])), 5)})
