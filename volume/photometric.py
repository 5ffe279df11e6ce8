"""The photometric stage of the pipeline (volume/pipeline/stages.py): align the views' exposure and
white balance (capture.photometric) before fusion, so RGBz and every rendering method see
corrected colour; the alignment is applied only where held-back cells show it helps
(capture.photometric_check), and the console says which.  The background plate measures each
frame's exposure on the background around the object (a fixed camera's static background, or the
panorama's other views: capture.plate_exposure): where its held-back check took those gains, they
are the alignment (PLATE_EXPOSURE).  Off with ``--no-photometric`` (its config None)."""

from __future__ import annotations

import logging
from dataclasses import asdict, replace

import numpy as np

from capture.photometric import PhotometricResult, apply_gains, estimate_gains

#: Take a fixed camera's exposure from its plate where the plate's held-back check accepted it (the
#: conifer with auto exposure: 0.002 EV RMS against the true exposures, the object's cells 0.10 EV).
PLATE_EXPOSURE = True


def photometric_stage(work, cfg, ctx):
    """The photometric stage (cfg: capture.photometric.PhotometricConfig): a gain per view and
    channel estimated over the views' overlaps (cells of the capture's bounds) and applied when the
    check supports it (each corrected scan kept); record: the gains
    (capture.photometric.PhotometricResult.record, with the check) and the config; None with fewer
    than 2 views."""
    if len(work.scans) < 2:
        return work.record("photometric", None)
    plate = (work.records.get("background plate") or {}).get("exposure") or {}
    if PLATE_EXPOSURE and plate.get("chosen") == "plate" and len(plate.get("gains", ())) == len(work.scans):
        res = plate_result(work.scans, plate, cfg)
    else:
        res = estimate_gains(work.scans, cfg, ctx.progress, bounds=work.bounds, map_views=ctx.map_views)
        res = background_witness(res, plate, cfg)
    check = res.meta.get("check")
    if check:
        log = logging.getLogger("furrow.capture")
        (log.warning if check["chosen"] == "none" else log.info)("photometric alignment: %s", check["reason"])
    scans = apply_gains(work.scans, res.gains, ctx.keep, ctx.map_views)
    return replace(work, scans=scans).record("photometric", {**res.record(), "config": asdict(cfg)})


def background_witness(res: PhotometricResult, exposure: dict, cfg) -> PhotometricResult:
    """``res`` unless the background refuses its gains (capture.photometric_background: each frame's background
    ring against the other frames' prediction of it, ``exposure["ring_log2"]`` of the plate's exposure record),
    then the views kept as they are, the check saying why.  Asked only where the cells took gains and the plate's
    own exposure check took none, and ``cfg.background`` (capture.photometric.PhotometricConfig) is not 'off' (a
    fixed-exposure furry bunny orbit: 0.38 EV asked, 0.15 dB lost held out; docs/real_cameras.md)."""
    from capture.photometric_background import background_verdict

    check, ratios = res.meta.get("check") or {}, exposure.get("ring_log2")
    if cfg.background == "off" or check.get("chosen") in (None, "none") or exposure.get("chosen") == "plate" \
            or not ratios or len(ratios) != len(res.names):
        return res
    verdict = background_verdict(ratios, res.gains)
    if verdict is None:
        return res
    if not verdict["refused"]:
        return replace(res, meta={**res.meta, "background": verdict})
    why = (f"kept the views as they are: the gains the object's cells asked for ({check['reason']}) are not the "
           f"camera's: {verdict['reason']}")
    meta = {**res.meta, "background": verdict, "check": {**check, "chosen": "none", "cells_chose": check["chosen"],
                                                          "reason": why}}
    return replace(res, gains=np.ones_like(res.gains), meta=meta)


def plate_result(scans, exposure: dict, cfg) -> PhotometricResult:
    """The photometric result of the plate's accepted gains (``exposure``: the plate record's
    ``exposure``), in the gauge ``cfg.reference`` asks."""
    from capture.photometric import _gauge

    names = tuple(s.name for s in scans)
    x = _gauge(np.log(np.asarray(exposure["gains"], np.float64)), np.ones(len(names), bool), cfg.reference, names)
    check = {"chosen": "plate", "reason": f"exposure from the background plate: {exposure['reason']}"}
    return PhotometricResult(names, np.exp(x), 0, int(exposure["pixels"]), (), cfg.reference, 0.0,
                             {"appearance": "none", "appearance_share": 0.0, "source": "plate", "check": check})
