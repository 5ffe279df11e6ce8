"""The model build's photometric stage: align the views' exposure and white balance
(capture.photometric) before fusion, so RGBz and every rendering method see corrected colour."""

from __future__ import annotations

import contextlib
from dataclasses import asdict, replace

from capture.photometric import PhotometricConfig, apply_gains, estimate_gains
from capture.scan import ScanSet

#: Scan-set metadata key that turns the stage off (``furrow eval --no-photometric``): the
#: colours are known to be aligned already.
OFF_KEY = "photometric"
STAGE = "photometric"


def align_views(scanset: ScanSet, cfg: PhotometricConfig | None, stage=None, progress=None, keep=None):
    """(scan set with corrected colours, JSON record of the gains or None when off); ``keep`` takes
    each corrected scan (capture.scan_store)."""
    if cfg is None or scanset.metadata.get(OFF_KEY) == "off" or len(scanset.scans) < 2:
        return scanset, None
    stage = stage or (lambda name: contextlib.nullcontext())
    with stage(STAGE):
        res = estimate_gains(scanset.scans, cfg, (lambda it, d: progress(it, d)) if progress else None)
        scans = apply_gains(scanset.scans, res.gains, keep)
    return replace(scanset, scans=scans), {**res.record(), "config": asdict(cfg)}
