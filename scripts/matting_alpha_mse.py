"""Alpha MSE of the matte against a synthetic capture's true matte (mask_path), and of the binary
depth mask, per kept view after the extent stage; seconds per view (issue 20 measurements).

    PYTHONPATH=. .venv/bin/python scripts/matting_alpha_mse.py CAPTURE [MODE] [FRAMES]

MODE: estimate (default), auto, backdrop (needs no flag: black), given, plate (the default plate
stage first: capture.plate.background_plates as `furrow model` runs it; issue 30); FRAMES default 0::2.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from capture.extent import remove_surroundings
from capture.io import read_scanset
from capture.matting import MatteConfig, matte_scan, warm_up
from capture.plate import PlateConfig, PlateView, background_plates
from capture.scan import Scan


def _plates(ss, out, rep, mode: str) -> list:
    """Each kept view's background plate (mode 'plate' or 'auto'), else None per view."""
    if mode not in ("plate", "auto"):
        return [None] * len(ss.scans)
    views = [PlateView(o.camera, o.linear_rgb, o.depth, s.depth) for s, o in zip(ss.scans, out.scans, strict=True)]
    plates, rec = background_plates(views, PlateConfig(), rep.plane, (rep.focus_center, rep.focus_radius))
    print("plate", rec["mode"], "band known", rec["band_known_mean"], "error", rec.get("error_median"))
    return plates


def main(path: str, mode: str = "estimate", frames: str = "0::2") -> None:
    warm_up()
    ss = read_scanset(path, frames)
    out, rep = remove_surroundings(ss)
    print("extent", rep.record()["removed_fraction"], rep.record()["plane"])
    backdrop = (0.0, 0.0, 0.0) if mode == "backdrop" else None
    plates = _plates(ss, out, rep, mode)
    mb, me, ts = [], [], []
    for s, o, plate in zip(ss.scans, out.scans, plates, strict=True):
        t = time.perf_counter()
        plain = s if mode == "given" else Scan(s.rgb, s.depth, s.camera, s.name)  # hide the true matte
        m = matte_scan(plain, o.depth, MatteConfig(mode=mode, backdrop=backdrop), plate)
        ts.append(time.perf_counter() - t)
        mb.append(np.mean(((o.depth > 0) - s.alpha) ** 2))
        me.append(np.mean((m.alpha - s.alpha) ** 2))
    print(f"{path} {mode}: binary MSE {np.mean(mb):.4f}  matte MSE {np.mean(me):.4f} ({m.method})  "
          f"s/view {np.mean(ts):.3f} (max {np.max(ts):.3f})")


if __name__ == "__main__":
    main(*sys.argv[1:])
