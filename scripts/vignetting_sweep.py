"""Each capture through the pipeline up to the background plate (default flags), and what capture.vignetting made of
it: the plate's mode, the stage's seconds, and the vignetting record (applied, corner, z, pairs, pixels, reason), or
"not measured" (a fixed camera).  docs/real_cameras.md, "Vignetting".

    PYTHONPATH=. .venv/bin/python scripts/vignetting_sweep.py CAPTURE[@FRAMES] ...
"""

from __future__ import annotations

import contextlib
import io
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))


def main(argv=None) -> None:
    import plate_stage_sha

    import capture.vignetting as cv

    got, real = {}, cv.vignetting_check

    def kept(ps):
        coef, rec = real(ps)
        got["rec"] = rec
        return coef, rec

    cv.vignetting_check = kept
    for arg in sys.argv[1:] if argv is None else argv:
        cap, _, frames = arg.partition("@")
        got.clear()
        with contextlib.redirect_stdout(io.StringIO()):
            out = plate_stage_sha.main([cap] + (["--frames", frames] if frames else []))
        r = got.get("rec")
        said = "not measured" if r is None else (f"applied={r['applied']} corner={r.get('corner')} z={r.get('z')} "
                                                 f"pairs={r.get('pairs')} pixels={r.get('pixels')} | {r['reason']}")
        print(f"{arg:60s} {out.get('mode')!s:9s} {out.get('wall')} s  {said}", flush=True)


if __name__ == "__main__":
    main()
