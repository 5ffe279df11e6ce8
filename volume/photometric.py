"""The photometric stage of the pipeline (volume/pipeline/stages.py): align the views' exposure and
white balance (capture.photometric) before fusion, so RGBz and every rendering method see
corrected colour; the alignment is applied only where held-back cells show it helps
(capture.photometric_check), and the console says which.  Off with ``--no-photometric`` (its
config None)."""

from __future__ import annotations

import logging
from dataclasses import asdict, replace

from capture.photometric import apply_gains, estimate_gains


def photometric_stage(work, cfg, ctx):
    """The photometric stage (cfg: capture.photometric.PhotometricConfig): a gain per view and
    channel estimated over the views' overlaps (cells of the capture's bounds) and applied when the
    check supports it (each corrected scan kept); record: the gains
    (capture.photometric.PhotometricResult.record, with the check) and the config; None with fewer
    than 2 views."""
    if len(work.scans) < 2:
        return work.record("photometric", None)
    res = estimate_gains(work.scans, cfg, ctx.progress, bounds=work.bounds, map_views=ctx.map_views)
    check = res.meta.get("check")
    if check:
        log = logging.getLogger("furrow.capture")
        (log.warning if check["chosen"] == "none" else log.info)("photometric alignment: %s", check["reason"])
    scans = apply_gains(work.scans, res.gains, ctx.keep, ctx.map_views)
    return replace(work, scans=scans).record("photometric", {**res.record(), "config": asdict(cfg)})
