"""The depth-agreement stage's verdicts on captures, as ``furrow model`` reaches them (capture/depth_agreement.py,
volume/agreement.py), one line each: the scales' verdict and best scale, then the focal-length search's factor, the
points agreeing as given and at that factor, the view pairs better / worse, the depth's best scale there; or the
pose convention or the intrinsics' misreading the depths agree with (and each reading's share).

    PYTHONPATH=. .venv/bin/python scripts/agreement_verdicts.py CAPTURE [CAPTURE ...]

docs/capture_formats.md ("A focal length that is off") was measured with it, on the copies that
``scripts/broken_captures.py`` makes.
"""

from __future__ import annotations

import sys
import time
import zlib

from capture.depth_agreement import (
    AgreementConfig,
    agreement,
    convention_check,
    focal_check,
    intrinsics_check,
    units_check,
    verdict,
    view_sample,
)
from capture.io import read_scanset


def line(path: str) -> str:
    """One capture's verdicts (module docstring)."""
    scans = read_scanset(path).scans
    t = time.perf_counter()
    cfg = AgreementConfig()
    samples = [view_sample(s.depth, s.camera, cfg.points, zlib.crc32(s.name.encode())) for s in scans]
    cams = [s.camera for s in scans]
    rec = verdict(*agreement(samples, cams, cfg)[:3])
    conv = convention_check(samples, cams, cfg, rec["best_share"]) if rec["status"] in ("none", "scale") else {}
    if conv.get("status") == "convention":
        return (f"{path.rstrip('/').split('/')[-1]:>28} convention (scales: {rec['status']}, best share "
                f"{rec['best_share']:.1%}) poses read as '{conv['convention']}': {conv['tried']}")
    intr = intrinsics_check(samples, cams, cfg, rec["best_share"]) if conv else {}
    if intr.get("status") == "intrinsics":
        return (f"{path.rstrip('/').split('/')[-1]:>28} intrinsics (scales: {rec['status']}, best share "
                f"{rec['best_share']:.1%}) read as '{intr['intrinsics']}' x {intr['factor']:.3g}: {intr['tried']}")
    units = units_check(samples, cams, cfg, rec["best_share"]) if conv else {}
    if units.get("status") == "units":
        return (f"{path.rstrip('/').split('/')[-1]:>28} units (scales: {rec['status']}, best share "
                f"{rec['best_share']:.1%}) depth x {units['factor']:g}: {units['tried']}")
    f = focal_check(samples, cams, cfg) if rec["status"] in ("agree", "scale") else {}
    status = "focal" if f.get("status") == "focal" else rec["status"]
    focal = (f"focal x {f['focal_factor']:.4g}: {f['share_as_given']:.1%} -> {f['focal_share']:.1%}, pairs "
             f"{f['pairs_better']}/{f['pairs_worse']}, depth scale there {f.get('depth_scale_at_focal', '-')}"
             if f else "focal not searched")
    return (f"{path.rstrip('/').split('/')[-1]:>28} {status:6} (scales: {rec['status']}, best {rec['best_scale']:.4g}) "
            f"{focal}  {time.perf_counter() - t:.2f} s")


if __name__ == "__main__":
    for p in sys.argv[1:]:
        try:
            print(line(p), flush=True)
        except ValueError as e:  # the reader's refusal (ScanIOError): said, and the next capture
            print(f"{p.rstrip('/').split('/')[-1]:>28} refused: {e}", flush=True)
