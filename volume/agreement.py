"""The depth-agreement stage of the pipeline (volume/pipeline/stages.py): before any model is built,
whether the views' depths agree with their poses (capture.depth_agreement), with their colour images
(capture.depth_registration) and with the capture's own mattes (capture.matte_io), said on the console when
they do not; the model record keeps the figures.  Where the depths agree with the poses at no scale or at another,
the poses are read in other conventions and the intrinsics in their common wrong ways; where they agree at a
scale, other focal lengths are tried (a focal length 0.7x its own reads as the scale 0.85), and a focal factor is
told from a depth camera's own field of view by the colour.  Nothing is changed, unless ``--depth-agreement fix``:
then the depth is scaled to the poses where it agrees best at another scale, moved (or drawn back and moved) onto
its colour, and inverted mattes are turned over; poses and intrinsics are never changed.  Off with
``--depth-agreement off`` (its config None)."""

from __future__ import annotations

import logging
import zlib
from dataclasses import asdict, replace

import numpy as np

from capture.colour_flip import EDGE_GAIN, edge_flips
from capture.depth_agreement import (
    MAX_PAIR_ANGLE,
    AgreementConfig,
    agreement,
    convention_check,
    focal_check,
    intrinsics_check,
    neighbours,
    units_check,
    verdict,
    view_sample,
)
from capture.depth_disparity import disparity_check, read_disparity
from capture.depth_pairing import pairing_data, pairing_verdict, pairing_views
from capture.depth_readings import FLIP_COLOUR_GAIN, READINGS, flip_sums, read_depth, reading_check
from capture.depth_registration import (
    OFFSET_RADIUS,
    edge_scores,
    offset_verdict,
    shifted_depth,
    zoom_sums,
    zoom_verdict,
    zoomed_depth,
)
from capture.depth_view_scales import view_scale_check
from capture.matte_io import matte_depth_shares, matte_verdict
from capture.view_map import PerView

#: The verdicts warned about again at the end of furrow model, and in a later stage's error ("before that, ...").
FAILED_AGREEMENT = ("scale", "none", "focal", "depth zoom", "convention", "intrinsics", "units", "depth reading",
                    "disparity", "view scales")
#: The colour's edges are held against the depth's in about this many views (a pseudo-random set, by name): a
#: capture's depth and colour come from one rig, so one offset is looked for; 72 views at 1280x960 spent 0.7 s
#: of the stage's 1.4 s on every view's edges.
EDGE_VIEWS = 24


def sample_view(scan, ref, arg):
    """Per view (capture.view_map): (None, (:func:`capture.depth_agreement.view_sample` of its depth,
    :func:`capture.depth_registration.edge_scores` of its colour and depth, or (None, 1) for a view not
    among those scored), both seeded by the view's name; capture.matte_io.matte_depth_shares of its given
    matte, or None; capture.depth_pairing.pairing_data of the views named, or None)); ``arg``: (the number of
    points, score the edges of the views whose name's CRC-32 is a multiple of this, the names of the views whose
    pairing data is needed)."""
    points, every, paired = arg
    seed = zlib.crc32(scan.name.encode())
    edges = edge_scores(scan.rgb, scan.depth, seed) if seed % every == 0 else (None, 1.0)
    matte = None if scan.alpha is None else matte_depth_shares(scan.alpha, scan.depth)
    pair = pairing_data(scan.rgb, scan.depth, seed) if scan.name in paired else None
    return None, (view_sample(scan.depth, scan.camera, points, seed), edges, matte, pair)


def agreement_stage(work, cfg: AgreementConfig, ctx):
    """The depth-agreement stage: each view's sample through ``ctx.map_views``; the share of points agreeing at
    each depth scale, the verdict warned unless it is ``agree`` and diagnosed further (:func:`_diagnosed`); the
    depth's edges against the colour's (capture.depth_registration), warned when they sit apart (not judged where
    the depth's edges sit zoomed from the colour's).  Record: the verdicts, the scales' shares (rounded), each
    view's own share, the further searches', the edges' offset and the config; None with fewer than 2 views,
    status ``no depth`` where no view has any (the fuse stage refuses such a capture, and says why), ``no pairs``
    where no two views are within MAX_PAIR_ANGLE of each other (the edges are still compared)."""
    if len(work.scans) < 2:
        return work.record("depth agreement", None)
    every = max(1, -(-len(work.scans) // EDGE_VIEWS))  # about EDGE_VIEWS views' edges: one offset for a capture
    scored = [k for k, r in enumerate(work.refs) if zlib.crc32(r.name.encode()) % every == 0]
    cand, need = pairing_views([r.camera for r in work.refs], scored) if len(work.refs) > 2 else ({}, [])
    paired = frozenset(work.refs[k].name for k in need)
    both = ctx.map_views(sample_view, work, (int(cfg.points), every, paired), "depth agreement")[1]
    samples = [b[0] for b in both]
    if sum(len(p) for p, _, _ in samples) == 0:  # no view has depth: the fuse stage's error says so
        return work.record("depth agreement", {"status": "no depth", "config": asdict(cfg)})
    log = logging.getLogger("furrow.capture")
    edges = [b[1][0] for b in both if b[1][0] is not None]
    scale = next((b[1][1] for b in both if b[1][0] is not None), 1.0)
    offset = offset_verdict(np.sum(edges, axis=0), len(edges), scale) if edges else {}
    if cand:  # capture.depth_pairing: each depth file its own frame's?
        offset = {**offset, **pairing_verdict({k: both[k][3] for k in need}, cand)}
    work, offset = _mattes(work, offset, [b[2] for b in both], cfg, ctx)
    cams = [s.camera for s in work.scans]
    if not (neighbours(cams, cfg.neighbours) >= 0).any():
        log.info("depth agreement: no two views within %g degrees of each other: nothing to compare", MAX_PAIR_ANGLE)
        work, offset = _offset(work, offset, cfg, ctx)
        return work.record("depth agreement", {**offset, "status": "no pairs", "config": asdict(cfg)})
    s, share, share_all, per_view, blind = agreement(samples, cams, cfg)
    rec = {**verdict(s, share, share_all), "scale_blind": round(blind, 4)}
    rec = _diagnosed(rec, samples, cams, cfg, work, every, ctx)
    rec = _colour_flip(rec, {k: both[k][3] for k in scored if both[k][3] is not None})
    if rec.get("colour_flip", {}).get("flipped"):  # the colour's edges then sit anywhere but at the depth's
        offset = {**offset, "colour_offset": False, "mispaired": False,
                  "colour_offset_note": "not judged: the colour and the depth sit flipped against each other"}
        offset.pop("colour_offset_message", None)
        offset.pop("pairing_message", None)
    flipped = rec["status"] == "depth reading" and not READINGS[rec["reading"]["reading"]][2]
    if (rec["status"] == "depth zoom" and offset.get("colour_offset")) or (flipped and offset):  # some shift peaks
        offset = {**offset, "colour_offset": False, "colour_offset_note": "not judged: the depth's edges sit "
                  + ("flipped" if flipped else "zoomed")}
        offset.pop("colour_offset_message", None)
    if (flipped or rec["status"] == "depth zoom") and offset.get("mispaired"):  # no depth's edges fit its colour
        offset = {**offset, "mispaired": False}
        offset.pop("pairing_message", None)
    work, rec = _offset(work, {**rec, **offset}, cfg, ctx)
    (log.info if rec["status"] == "agree" else log.warning)("depth agreement: %s", rec["message"])
    if rec.get("colour_flip", {}).get("flipped"):
        log.warning("depth agreement: %s", rec["colour_flip"]["message"])
    if cfg.fix and rec["status"] in ("scale", "units"):
        work, rec = _rescaled(work, rec, ctx)
    elif cfg.fix and rec["status"] == "depth zoom":
        work, rec = _unzoomed(work, rec, ctx)
    elif cfg.fix and rec["status"] == "depth reading":
        work, rec = _reread(work, rec, ctx)
    elif cfg.fix and rec["status"] == "disparity":
        work, rec = _from_disparity(work, rec, ctx)
    elif cfg.fix and rec["status"] == "view scales":
        work, rec = _view_rescaled(work, rec, ctx)
    elif cfg.fix and rec["status"] in ("focal", "convention", "intrinsics"):
        log.warning("depth agreement: --depth-agreement fix leaves the %s as the capture gives them (a depth scale "
                    "would not undo them; the held-out views keep the capture's cameras)",
                    "poses" if rec["status"] == "convention" else "intrinsics")
    rec["curve"] = {f"{x:.4g}": round(float(a), 4) for x, a in zip(s, share)}
    rec["per_view"] = {x.name: None if v != v else round(float(v), 4) for x, v in zip(work.scans, per_view)}
    return work.record("depth agreement", {**rec, "config": asdict(cfg)})


def _diagnosed(rec: dict, samples, cams, cfg: AgreementConfig, work, every: int, ctx) -> dict:
    """The scales' verdict ``rec`` diagnosed further: where it is ``none`` or ``scale``, the poses read in other
    conventions (status ``convention``), else the intrinsics' common misreadings (``intrinsics``); where it is
    ``agree`` or ``scale`` (and no convention was found), the focal lengths (``focal``), told from a depth camera's
    own field of view by the colour (``depth zoom``).  Before all, the depth maps read flipped (``depth reading``,
    :func:`_reading`); after all, read as distances along the rays, where none of these is found or where a focal
    factor is, with a smaller McNemar z than range's (a focal length 1.25x its own agrees better as range too, z 7.3
    against its own 30.7; the conifer's range depth, every other view, reads as a focal factor 1.5 and a depth zoom,
    z 47.8 against range's 64.4).  Last, each view's depth at its own factor (``view scales``, :func:`_view_scales`).
    Each search's record under its own key."""
    rec, ranged = _reading(rec, samples, cams, cfg, work, every, ctx)
    if rec["status"] == "depth reading":
        return rec
    rec = _explained(rec, samples, cams, cfg, work, every, ctx)
    if ranged is not None:
        z = rec["reading"]["tried"]["range"]["z"]
        if rec["status"] in ("agree", "scale", "none") or (  # a focal factor and range: the larger McNemar z
                rec["status"] in ("focal", "depth zoom") and z > rec["focal"].get("discordance_z", 0.0)):
            if "focal" in rec:
                rec["focal"]["superseded_by"] = "depth reading"
            return {**rec, "status": "depth reading", "message": ranged}
        rec["reading"]["superseded_by"] = rec["status"]
    return _view_scales(rec, samples, cams, cfg, [r.name for r in work.refs])


def _view_scales(rec: dict, samples, cams, cfg: AgreementConfig, names) -> dict:
    """``rec`` with ``view_scales`` (capture.depth_view_scales.view_scale_check, from the best scale) where the
    verdict is still ``agree``, ``scale``, ``none``, ``focal`` or ``depth zoom``; status ``view scales`` where each
    view's depth agrees far better at its own factor, over a focal factor where its McNemar z is the larger (the
    synthetic fur ball's drifting depth on every third view read as a focal factor; a focal length off moves every
    view alike, and the factors do not spread); the factors by view name (``names``, the samples' order)."""
    if rec["status"] not in ("agree", "scale", "none", "focal", "depth zoom"):
        return rec
    found = view_scale_check(samples, cams, cfg, float(rec["best_scale"]))
    if "factors" in found:  # by view name: a later fix may leave frames out (capture.depth_pairing)
        found["factors"] = dict(zip(names, found["factors"]))
    rec = {**rec, "view_scales": {k: v for k, v in found.items() if k != "message"}}
    if found["status"] != "view scales" or (
            rec["status"] in ("focal", "depth zoom") and found["z"] <= rec["focal"].get("discordance_z", 0.0)):
        return rec
    if "focal" in rec:
        rec["focal"]["superseded_by"] = "view scales"
    return {**rec, "status": "view scales", "message": found["message"]}


def _explained(rec: dict, samples, cams, cfg: AgreementConfig, work, every: int, ctx) -> dict:
    """The searches of :func:`_diagnosed` after the depth's flips: the poses' conventions, the intrinsics, the units,
    the depth read as disparity (capture.depth_disparity), the focal lengths and the depth's zoom."""
    if rec["status"] in ("none", "scale"):  # poses written in another convention read as a scale, or as nothing
        conv = convention_check(samples, cams, cfg, rec["best_share"])
        rec["convention"] = {k: v for k, v in conv.items() if k != "message"}
        if conv["status"] == "convention":
            return {**rec, "status": "convention", "message": conv["message"]}
        intr = intrinsics_check(samples, cams, cfg, rec["best_share"])
        rec["intrinsics"] = {k: v for k, v in intr.items() if k != "message"}
        if intr["status"] == "intrinsics":
            return {**rec, "status": "intrinsics", "message": intr["message"]}
        units = units_check(samples, cams, cfg, rec["best_share"])
        rec["units"] = {k: v for k, v in units.items() if k != "message"}
        if units["status"] == "units":
            return {**rec, "status": "units", "message": units["message"]}
        disp = disparity_check(samples, cams, cfg, float(rec["best_scale"]))  # capture.depth_disparity
        rec["disparity"] = {k: v for k, v in disp.items() if k != "message"}
        if disp["status"] == "disparity":
            return {**rec, "status": "disparity", "message": disp["message"]}
    if rec["status"] in ("agree", "scale"):  # a focal length off reads as a scale, or as nothing (module docstring)
        focal = focal_check(samples, cams, cfg)
        rec["focal"] = {k: v for k, v in focal.items() if k != "message"}
        if focal["status"] == "focal":
            rec = {**rec, "status": "focal", "message": focal["message"]}
            rec = _depth_zoom(work, rec, every, ctx)
    return rec


def _reading(rec: dict, samples, cams, cfg: AgreementConfig, work, every: int, ctx) -> dict:
    """(``rec`` with the depth read in other ways (capture.depth_readings.reading_check, at the best scale where the
    scales' verdict is ``agree`` or ``scale``, else 1) under ``reading``: status ``depth reading`` where a flip is
    found and the colour's edges sit at the flipped depth's at least as well as at the stored one's
    (``flip_colour_gain`` >= FLIP_COLOUR_GAIN, over the views whose edges are scored: :func:`flip_view`; where they
    do not, the reading's status says so and nothing is named: depth files of the next frame on a ring of three
    spheres agreed better flipped, z 56, the colour 0.65 times); the warning where the depth reads as range, else
    None)."""
    nb = neighbours(cams, cfg.neighbours)
    pairs = [(i, int(j)) for i in range(len(cams)) for j in nb[i] if j >= 0]
    scale = float(rec["best_scale"]) if rec["status"] in ("agree", "scale") else 1.0
    found = reading_check(samples, [(c.height, c.width) for c in cams], cams, pairs, scale, cfg.rel)
    rec = {**rec, "reading": {k: v for k, v in found.items() if k != "message"}}
    if found["status"] != "reading":
        return rec, None
    name, message = found["reading"], found["message"]
    if READINGS[name][2]:
        return rec, message
    sums = np.sum(ctx.map_views(flip_view, work, (name, every), "depth agreement: the depth's edges flipped")[1],
                  axis=0)
    gain = float(sums[1] / sums[0]) if sums[0] > 0 else 0.0
    rec["reading"]["flip_colour_gain"] = round(gain, 4)
    if gain < FLIP_COLOUR_GAIN:  # the colour's edges sit at the stored depth's: no flip of the depth alone
        rec["reading"]["status"] = "colour disagrees"
        return rec, None
    message += f" The colour's edges sit at the flipped depth's ({gain:.2f} times the gradient at the stored depth's)."
    return {**rec, "status": "depth reading", "message": message}, None


def _colour_flip(rec: dict, pair_data: dict) -> dict:
    """``rec`` with ``colour_flip``: the colour's edges at the depth's mirrored (capture.colour_flip.edge_flips, on
    ``pair_data``: view -> capture.depth_pairing.pairing_data), ``flipped`` and ``message`` where one fits EDGE_GAIN
    times better.  Judged only where the depth agrees with the poses (at some scale, focal factor, or read as range:
    a capture whose depth agrees with nothing has its warning, and the synthetic one with D435 noise, flying pixels
    and clutter fits the mirror 1.23 times); not where the depth reads flipped (capture.depth_readings names it)."""
    agreeing = ("agree", "scale", "focal", "depth zoom", "depth reading", "disparity", "view scales")
    if not pair_data or rec["status"] not in agreeing or (
            rec["status"] == "depth reading" and not READINGS[rec["reading"]["reading"]][2]):
        return rec
    edges = edge_flips(pair_data)
    name = edges["best"]
    out = {"edge_gains": edges["gains"], "flip": name, "flipped": edges["gains"][name] >= EDGE_GAIN}
    if out["flipped"]:
        out["message"] = (
            f"the depth's edges, mirrored ({name}), fit the colour images {edges['gains'][name]:.2f} times as well "
            "as stored: is the colour or the depth stored flipped (the colour, where the depth agrees with the "
            "poses)? The colour's shift from the depth is not judged.")
    return {**rec, "colour_flip": out}


def flip_view(scan, ref, arg):
    """Per view: (None, capture.depth_readings.flip_sums of its colour and depth for the views whose name's CRC-32
    is a multiple of ``every``, zeros for the others); ``arg``: (the reading, every)."""
    name, every = arg
    seed = zlib.crc32(scan.name.encode())
    return None, (flip_sums(scan.rgb, scan.depth, name, seed) if seed % every == 0 else np.zeros(2))


def reread_view(scan, ref, name):
    """Per view: the scan with its depth read as ``name`` says (capture.depth_readings.read_depth)."""
    return replace(scan, depth=read_depth(scan.depth, scan.camera, name)), None


def _reread(work, rec: dict, ctx):
    """(work with every view's depth read as the named reading says, its bounds found again from the depth where
    the capture gives none; the record with ``reading_applied``)."""
    name = rec["reading"]["reading"]
    work = _with_bounds(work, ctx.map_views(reread_view, work, name, "depth agreement: depth read again")[0])
    logging.getLogger("furrow.capture").warning(
        "depth agreement: every view's depth map read as %s (--depth-agreement fix)",
        "z-depth from the distance along its rays" if name == "range" else f"flipped {name}")
    return work, {**rec, "reading_applied": name}


def disparity_view(scan, ref, k: float):
    """Per view: the scan with its depth read as disparity, k / value (capture.depth_disparity.read_disparity)."""
    return replace(scan, depth=read_disparity(scan.depth, k)), None


def _from_disparity(work, rec: dict, ctx):
    """(work with every view's depth map read as disparity, its bounds found again from the depth where the capture
    gives none; the record with ``disparity_applied``: the constant)."""
    k = float(rec["disparity"]["constant"])
    work = _with_bounds(work, ctx.map_views(disparity_view, work, k, "depth agreement: depth from disparity")[0])
    logging.getLogger("furrow.capture").warning(
        "depth agreement: every view's depth map read as disparity, depth = %.4g / value (--depth-agreement fix)", k)
    return work, {**rec, "disparity_applied": k}


def repair_view(scan, ref, partner):
    """Per view: the scan with the depth of ``partner`` (the view whose depth file is this frame's; a spilled scan
    pickles as its file name)."""
    return replace(scan, depth=np.asarray(partner.depth, np.float32)), None


def _repaired(work, rec: dict, ctx):
    """(work with each frame given the depth file ``pairing_shift`` places on in the capture's order, the frames
    without one left out; the record with ``pairing_applied``: the shift and the frames left out)."""
    k, n = int(rec["pairing_shift"]), len(work.scans)
    keep = [j for j in range(n) if 0 <= j + k < n]
    out = replace(work, refs=tuple(work.refs[j] for j in keep), scans=tuple(work.scans[j] for j in keep))
    scans, _ = ctx.map_views(repair_view, out, PerView([work.scans[j + k] for j in keep]),
                             "depth agreement: depth files paired again")
    dropped = [work.refs[j].name for j in range(n) if j not in keep]
    logging.getLogger("furrow.capture").warning(
        "depth agreement: every frame given the depth file %+d frames on (--depth-agreement fix); left out without "
        "one: %s", k, ", ".join(dropped))
    return replace(out, scans=tuple(scans)), {**rec, "pairing_applied": {"shift": k, "left_out": dropped}}


def _offset(work, rec: dict, cfg: AgreementConfig, ctx):
    """(work, rec) with the colour's edges' offset warned where it is reported, and the depth moved onto the
    colour with ``fix``."""
    if rec.get("mispaired"):
        logging.getLogger("furrow.capture").warning("depth agreement: %s", rec["pairing_message"])
        if cfg.fix and rec.get("pairing_shift"):
            work, rec = _repaired(work, rec, ctx)
    if rec.get("colour_offset"):
        logging.getLogger("furrow.capture").warning("depth agreement: %s", rec["colour_offset_message"])
        if cfg.fix:
            return _shifted(work, rec, ctx)
    return work, rec


def _mattes(work, rec: dict, shares, cfg: AgreementConfig, ctx):
    """(work, rec with ``given_matte``: the given mattes against the depth, capture.matte_io.matte_verdict of the
    views' ``shares``), said on the console; inverted ones turned over with ``fix``.  Unchanged without mattes."""
    matte = matte_verdict(shares)
    if matte is None:
        return work, rec
    log = logging.getLogger("furrow.capture")
    (log.warning if matte["inverted"] else log.info)("depth agreement: %s", matte["message"])
    if matte["inverted"] and cfg.fix:
        scans, _ = ctx.map_views(invert_matte_view, work, None, "depth agreement: mattes inverted")
        work, matte = replace(work, scans=tuple(scans)), {**matte, "inverted_applied": True}
        log.warning("depth agreement: every given matte inverted (--depth-agreement fix)")
    return work, {**rec, "given_matte": matte}


def invert_matte_view(scan, ref, arg):
    """Per view: the scan with its given matte inverted (1 - alpha), or as it is without one."""
    if scan.alpha is None:
        return None, None
    return replace(scan, alpha=(1.0 - np.asarray(scan.alpha, np.float32)).astype(np.float32)), None


def shift_view(scan, ref, d):
    """Per view: the scan with its depth moved by ``d`` = (dx, dy) whole pixels."""
    return replace(scan, depth=shifted_depth(scan.depth, *d)), None


def _shifted(work, rec: dict, ctx):
    """(work with every view's depth moved onto its colour: by the reported offset of the colour's edges, in
    whole pixels; the record with ``colour_offset_applied``)."""
    d = tuple(int(round(v)) for v in rec["colour_offset_px"])
    scans, _ = ctx.map_views(shift_view, work, d, "depth agreement: depth moved onto the colour")
    logging.getLogger("furrow.capture").warning(
        "depth agreement: every view's depth moved by (%+d, %+d) px onto its colour (--depth-agreement fix)", *d)
    return replace(work, scans=tuple(scans)), {**rec, "colour_offset_applied": list(d)}


def rescale_view(scan, ref, s: float):
    """Per view: the scan with its depth times ``s``."""
    return replace(scan, depth=(np.asarray(scan.depth, np.float32) * np.float32(s)).astype(np.float32)), None


def _rescaled(work, rec: dict, ctx):
    """(work with every view's depth scaled by the best scale (or the units' factor), and its bounds found again
    from the depth where the capture gives none; the record with ``applied``).  The poses stay as they are, so
    that the model keeps the capture's frame: the held-out views of furrow eval, a camera path of the same poses."""
    s = float(rec["units"]["factor"] if rec["status"] == "units" else rec["best_scale"])
    work = _with_bounds(work, ctx.map_views(rescale_view, work, s, "depth agreement: depth rescaled")[0])
    logging.getLogger("furrow.capture").warning(
        "depth agreement: every view's depth scaled by %.4g to the poses (--depth-agreement fix)", s)
    return work, {**rec, "applied": round(s, 6)}


def _view_rescaled(work, rec: dict, ctx):
    """(work with every view's depth times its own factor (capture.depth_view_scales; 1 for a view without one),
    its bounds found again from the depth where the capture gives none; the record with ``view_scales_applied``)."""
    factors = rec["view_scales"]["factors"]
    f = PerView([float(factors.get(s.name, 1.0)) for s in work.scans])
    work = _with_bounds(work, ctx.map_views(rescale_view, work, f, "depth agreement: each view's depth rescaled")[0])
    v = np.array(list(factors.values()))
    logging.getLogger("furrow.capture").warning(
        "depth agreement: every view's depth scaled by its own factor, %.4g-%.4g (--depth-agreement fix)", v.min(),
        v.max())
    return work, {**rec, "view_scales_applied": True}


def _with_bounds(work, scans):
    """``work`` with ``scans``, its bounds found again from their depth where the capture gives none."""
    from capture.io import auto_bounds

    bounds = work.bounds if work.source.bounds is not None else auto_bounds(scans, str(work.source.path))
    return replace(work, scans=tuple(scans), bounds=bounds)


def zoom_view(scan, ref, arg):
    """Per view: (None, :func:`capture.depth_registration.zoom_sums` of its colour and depth at ``zoom``, for the
    views whose name's CRC-32 is a multiple of ``every``; zeros for the others); ``arg``: (zoom, every)."""
    zoom, every = arg
    seed = zlib.crc32(scan.name.encode())
    return None, (zoom_sums(scan.rgb, scan.depth, scan.camera.K[:2, 2], zoom, seed) if seed % every == 0
                  else np.zeros(1 + (2 * OFFSET_RADIUS + 1) ** 2))


def _depth_zoom(work, rec: dict, every: int, ctx) -> dict:
    """The record of a ``focal`` verdict told apart (capture.depth_registration.zoom_verdict): status ``depth zoom``
    where the colour's edges sit at the depth's drawn the focal factor closer to the principal point (and shifted
    by up to OFFSET_RADIUS working pixels: the depth from a camera with another field of view, standing beside the
    colour's), ``focal`` where they do not (both images' intrinsics off); the zoom's figures either way."""
    a = float(rec["focal"]["focal_factor"])
    sums = np.sum(ctx.map_views(zoom_view, work, (a, every), "depth agreement: the depth's edges zoomed")[1], axis=0)
    z = zoom_verdict(sums, a, work.scans[0].camera.width)
    rec = {**rec, **z}
    if z["depth_zoom"]:
        dx, dy = z["depth_zoom_shift_px"]
        rec["status"] = "depth zoom"
        rec["message"] = (
            f"the depth maps' edges sit {a:.3g} times as far from the principal point as the colour's"
            + (f" (the colour's ({dx:+.0f}, {dy:+.0f}) px from them drawn back)" if max(abs(dx), abs(dy)) >= 1 else "")
            + f" ({z['depth_zoom_gain']:.2f} times the colour's gradient there), and the depths agree with the poses "
            f"with the focal lengths times {a:.3g}: was the depth measured by a camera with its own field of view and "
            "not registered to the colour camera (the depth pixels over the colour pixels they measured)?")
    return rec


def unzoom_view(scan, ref, arg):
    """Per view: the scan with its depth drawn ``zoom`` times closer to its principal point, then moved by
    (dx, dy) whole pixels; ``arg``: (zoom, (dx, dy))."""
    zoom, (dx, dy) = arg
    z = zoomed_depth(scan.depth, scan.camera.K[:2, 2], scan.camera.width, zoom)
    return replace(scan, depth=shifted_depth(z, dx, dy) if dx or dy else z), None


def _unzoomed(work, rec: dict, ctx):
    """(work with every view's depth map drawn back onto its colour, the record with ``depth_zoom_applied``:
    the zoom and the shift)."""
    a = float(rec["focal"]["focal_factor"])
    d = tuple(int(round(v)) for v in rec["depth_zoom_shift_px"])
    scans, _ = ctx.map_views(unzoom_view, work, (a, d), "depth agreement: depth drawn onto the colour")
    logging.getLogger("furrow.capture").warning(
        "depth agreement: every view's depth map drawn %.4g times closer to its principal point and moved by "
        "(%+d, %+d) px, onto its colour (--depth-agreement fix)", a, *d)
    return replace(work, scans=tuple(scans)), {**rec, "depth_zoom_applied": [round(a, 6), list(d)]}
