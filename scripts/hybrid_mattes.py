"""A copy of a capture whose kept frames (0::2) carry the estimated alpha of
scripts/matte_error_classes.py, with the true alpha in the named plate classes only, for `furrow
eval` (the given matte: F from the plate): which class's alpha costs the held-out dB (issue 30 fifth
round).

    PYTHONPATH=. .venv/bin/python scripts/hybrid_mattes.py CAPTURE DIAG_DIR OUT CLASSES

CLASSES: comma-separated indices into matte_error_classes.CLASSES (0 seen, 1 lines, 2 blown,
3 unknown) or 'none' (the estimated alpha everywhere: the control).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
from PIL import Image


def main(src: str, diag: str, out: str, classes: str) -> None:
    src_p, diag_p, out_p = Path(src), Path(diag), Path(out)
    take = [] if classes == "none" else [int(c) for c in classes.split(",")]
    (out_p / "hmasks").mkdir(parents=True, exist_ok=True)
    for e in src_p.iterdir():
        if e.name != "transforms.json" and not (out_p / e.name).exists():
            (out_p / e.name).symlink_to(e.resolve())
    t = json.loads((src_p / "transforms.json").read_text())
    for i, fr in enumerate(t["frames"]):
        if i % 2:
            continue
        d = np.load(diag_p / f"{i // 2:02d}.npz")
        truth = np.asarray(Image.open(src_p / fr["mask_path"]), np.float64) / 255.0
        a = np.where(np.isin(d["cls"], take), truth, d["alpha"].astype(np.float64))
        fr["mask_path"] = f"hmasks/{i:03d}.png"
        Image.fromarray(np.round(np.clip(a, 0, 1) * 255).astype(np.uint8)).save(out_p / fr["mask_path"])
    (out_p / "transforms.json").write_text(json.dumps(t, indent=1))
    print(out_p)


if __name__ == "__main__":
    main(*sys.argv[1:5])
