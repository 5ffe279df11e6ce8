"""The background plate stage as ``furrow model`` runs it, its time and a SHA-1 of its plates (issue 32, round 6).

The capture goes through the pipeline's stages up to the background plate (default flags); the
plate stage's call is timed (wall and CPU seconds, every thread) and every plate's background, known,
estimated and sigma arrays, its crop and the stage's record are hashed, so that two checkouts can be
held side by side: the same SHA-1 means the same plates bit for bit.

    PYTHONPATH=. .venv/bin/python scripts/plate_stage_sha.py /work/cache/phone72_1280 --frames 0::3
    PYTHONPATH=. .venv/bin/python scripts/plate_stage_sha.py /work/cache/phone_200 --frames $(cat frames60.txt)
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np


def plates_sha1(plates, rec) -> str:
    """SHA-1 over every plate's arrays and crop, and the record."""
    h = hashlib.sha1()
    for p in plates:
        for a in (p.background, p.known, p.estimated, p.sigma):
            h.update(b"none" if a is None else np.ascontiguousarray(a).tobytes())
        h.update(repr(p.frame).encode())
    h.update(json.dumps(rec, sort_keys=True).encode())
    return h.hexdigest()


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("capture", type=Path)
    ap.add_argument("--frames", default=None, help="furrow's --frames (default all)")
    args = ap.parse_args(argv)
    import volume.surroundings as su
    from capture.sources import ReadConfig, open_source
    from volume.pipeline import runner
    from volume.pipeline.config import PipelineConfig
    from volume.pipeline.stages import STAGES

    real, out = su.background_plates, {}

    def timed(views, cfg, plane, focus, user, crop=False):
        t, c = time.perf_counter(), time.process_time()
        plates, rec = real(views, cfg, plane, focus, user, crop=crop)
        out.update(wall=round(time.perf_counter() - t, 2), cpu=round(time.process_time() - c, 2),
                   sha1=plates_sha1(plates, rec), mode=rec.get("mode"))
        return plates, rec

    su.background_plates = timed
    upto = STAGES[: [s.name for s in STAGES].index("background plate") + 1]
    cfg = replace(PipelineConfig(), read=ReadConfig(args.frames))
    try:
        with runner.run_pipeline(open_source(args.capture), cfg, stages=upto):
            pass
    finally:
        su.background_plates = real
    print(json.dumps(out), flush=True)
    return out


if __name__ == "__main__":
    main()
