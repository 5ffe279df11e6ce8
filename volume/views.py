"""Only the views and the resolution a method uses (issue 24).

**Views** (:func:`select_views`).  Every method that reads the photographs (gather, the
microfacets, the points) picks, per output pixel, the kept views nearest in viewing angle; a view
whose direction from the object (and distance) nearly repeats a kept one's adds nothing to that
choice.  Greedy farthest-point selection over the view directions seen from the object's centre:
the first view is kept, then the view farthest in angle from every kept one, while it is at least
``min_angle_deg`` away (``auto``), or until N views are kept (``N``); ``all`` keeps every view.
A view nearer or farther than every kept view of similar direction by more than DISTANCE_RATIO
adds scale and is kept too.  Every view gets its reason (kept: first / adds angle, with the
angle to the nearest kept view; dropped: a near-duplicate of view j).

**Resolution** (:func:`working_scale`).  The object needs as many pixels in a view as it will
cover in the output the user asks for (``--output-size WxH``): the output framing the object
at OUTPUT_FILL of its smaller side.  The factor is the needed footprint over the views' median
footprint (the largest side of the bounding box of their depth pixels), capped at 1 (never
upsampled) and rounded up to a multiple of SCALE_STEP.
"""

from __future__ import annotations

import numpy as np

from capture.sampling import mask_box

#: ``--views auto``: views closer than this in direction (seen from the object) are near-duplicates.
AUTO_MIN_ANGLE_DEG = 2.0
#: A view whose distance to the object differs from a near-duplicate's by more than this ratio is kept.
DISTANCE_RATIO = 1.25
#: ``--views auto`` that would keep one view of at least this many keeps them all instead, and says so: cameras
#: that all stand at one place looking one way are no capture of an object (poses inverted, world-to-camera where
#: camera-to-world belong, put a ring of views there), and the depth-agreement stage needs the views to say so.
COLLAPSE_MIN_VIEWS = 3
#: Fraction of the output's smaller side the object is assumed to fill.
OUTPUT_FILL = 0.9
#: Working scales are multiples of this (1 = full resolution).
SCALE_STEP = 0.125


def object_centre(cameras) -> np.ndarray:
    """(3,) the point nearest (least squares) to every camera's optical axis: what an orbit looks at."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for c in cameras:
        d = c.forward / np.linalg.norm(c.forward)
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ c.center
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.mean([c.center for c in cameras], axis=0)


def select_views(cameras, mode: str = "auto", centre=None) -> tuple[list[int], list[dict]]:
    """(kept indices in capture order, one reason dict per view) for ``mode`` 'auto', 'all' or an
    integer string N (module docstring)."""
    n = len(cameras)
    if mode == "all" or n <= 1:
        return list(range(n)), [{"view": i, "kept": True, "reason": "all views kept"} for i in range(n)]
    limit = None
    if mode != "auto":
        try:
            limit = int(mode)
        except ValueError:
            raise ValueError(f"--views must be auto, all or a number of views, got {mode!r}") from None
        if limit < 1:
            raise ValueError(f"--views N needs N >= 1, got {limit}")
    c = object_centre(cameras) if centre is None else np.asarray(centre, np.float64)
    off = np.array([cam.center - c for cam in cameras])
    dist = np.maximum(np.linalg.norm(off, axis=1), 1e-12)
    dirs = off / dist[:, None]
    cosang = np.clip(dirs @ dirs.T, -1, 1)
    ang = np.degrees(np.arccos(cosang))
    ratio = np.maximum(dist[:, None] / dist[None, :], dist[None, :] / dist[:, None])
    # a pair differing in scale counts as far apart
    eff = np.where(ratio > DISTANCE_RATIO, 180.0, ang)
    kept = [0]
    nearest = eff[0].copy()
    while len(kept) < (limit or n):
        j = int(np.argmax(np.where(np.isin(np.arange(n), kept), -1.0, nearest)))
        if j in kept or (limit is None and nearest[j] < AUTO_MIN_ANGLE_DEG):
            break
        kept.append(j)
        nearest = np.minimum(nearest, eff[j])
    kept_set = sorted(kept)
    if limit is None and len(kept_set) == 1 and n >= COLLAPSE_MIN_VIEWS:
        why = (f"all views kept: --views auto found every view a near-duplicate of view 0 (within "
               f"{AUTO_MIN_ANGLE_DEG} deg, seen from where their optical axes meet): cameras at one place looking one "
               "way are no capture of an object; are the poses camera-to-world?")
        return list(range(n)), [{"view": i, "kept": True, "reason": why, "collapsed": True} for i in range(n)]
    reasons = []
    for i in range(n):
        others = [k for k in kept_set if k != i]
        k = others[int(np.argmin(eff[i, others]))] if others else None
        a = float(ang[i, k]) if k is not None else 180.0
        if i in kept_set:
            why = "first view" if i == 0 else f"adds angle: {a:.1f} deg from the nearest kept view {k}"
        elif limit is not None:
            why = f"dropped: {limit} views asked, nearest kept view {k} at {a:.1f} deg"
        else:
            why = f"dropped: near-duplicate of view {k} ({a:.2f} deg < {AUTO_MIN_ANGLE_DEG} deg)"
        reasons.append({"view": i, "kept": i in kept_set, "reason": why, "angle_to_nearest_kept_deg": round(a, 3)})
    return kept_set, reasons


def footprint_px(depth: np.ndarray) -> int:
    """Largest side (pixels) of the bounding box of a depth map's pixels with depth (0 if none)."""
    box = mask_box(np.asarray(depth) > 0)
    return 0 if box is None else max(box[1] - box[0], box[3] - box[2])


def working_scale(footprints, output_size: tuple[int, int] | None) -> tuple[float, dict]:
    """(scale factor <= 1 for the views, report) from the views' object footprints (pixels) and
    the output size (W, H) asked for (None: full resolution)."""
    fp = [f for f in footprints if f > 0]
    med = float(np.median(fp)) if fp else 0.0
    if output_size is None or not med:
        return 1.0, {"scale": 1.0, "reason": "full resolution (no --output-size)" if output_size is None
                     else "full resolution (no object footprint)", "footprint_px": med}
    need = OUTPUT_FILL * min(output_size)
    s = min(1.0, np.ceil(need / med / SCALE_STEP) * SCALE_STEP)
    why = (f"object footprint {med:.0f} px (median over views), output {output_size[0]}x{output_size[1]} needs "
           f"{need:.0f} px" + (": full resolution" if s >= 1 else f": views scaled by {s:g}"))
    return float(s), {"scale": float(s), "reason": why, "footprint_px": med, "needed_px": need}


def scaled_scan(scan, s: float):
    """``scan`` resampled by ``s`` <= 1: colour (and alpha) by area averaging (OpenCV INTER_AREA),
    depth by the nearest source pixel (a measured value, never a blend across an edge), the
    camera by Camera.scaled (pixel centres exact)."""
    import cv2

    from capture.resample import nearest_depth
    from capture.scan import Scan

    if s >= 1:
        return scan
    cam = scan.camera.scaled(s)
    W, H = cam.width, cam.height
    rgb = cv2.resize(np.asarray(scan.rgb), (W, H), interpolation=cv2.INTER_AREA)
    depth = nearest_depth(scan.depth, W, H)
    alpha = None if scan.alpha is None else cv2.resize(np.asarray(scan.alpha, np.float32), (W, H),
                                                       interpolation=cv2.INTER_AREA)
    return Scan(rgb, depth, cam, scan.name, alpha)


def select_stage(refs, cfg) -> tuple[list[int], dict]:
    """The view-selection stage (cfg: ViewsConfig): (kept view indices, the report: mode, kept, of
    and every view's reason with its name), from the cameras alone (no image is read); frames of more than
    one image size are refused here (ValueError naming a frame of each)."""
    sizes = {}
    for r in refs:  # the RGBz stage stores one image size (volume.rgbz): refused here, before any work
        sizes.setdefault((r.camera.width, r.camera.height), r.name)
    if len(sizes) > 1:
        raise ValueError("the frames are not all one size: " + ", ".join(f"{w}x{h} ({n}, ...)" for (w, h), n in
                         sorted(sizes.items())) + "; furrow models one image size: resize them, or model each size "
                         "apart (--frames)")
    kept, reasons = select_views([r.camera for r in refs], cfg.mode)
    for r in reasons:
        r["name"] = refs[r["view"]].name
    if reasons and reasons[0].get("collapsed"):
        import logging

        logging.getLogger("furrow.capture").warning("view selection: %s", reasons[0]["reason"])
    return kept, {"mode": cfg.mode, "kept": len(kept), "of": len(reasons), "per_view": reasons}


def scale_view(view, ref, s: float):
    """One view resampled by ``s`` (:func:`scaled_scan`; a per-view step of the working-scale stage)."""
    return scaled_scan(view, s), None


def scale_stage(work, cfg, ctx):
    """The working-scale stage (cfg: ScaleConfig): the views' factor from their object footprint
    against ``cfg.output_size`` (:func:`working_scale`), every view scaled by it (never up)."""
    from dataclasses import replace

    s, rep = working_scale([footprint_px(x.depth) for x in work.scans], cfg.output_size)
    if s < 1:
        scans, _ = ctx.map_views(scale_view, work, s, "scale views")
        work = replace(work, scans=scans, metadata={**work.metadata, "working_scale": s})
    c = work.scans[0].camera
    return work.record("working scale", {**rep, "size": [c.width, c.height],
                                         "output_size": list(cfg.output_size) if cfg.output_size else None})
