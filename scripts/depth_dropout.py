"""A copy of a transforms.json capture whose depth lost a share of its pixels at random: a sensor that misses
needles (capture.matting_blind's EMPTY_PRIOR guard, docs/matting.md "A night park").

    PYTHONPATH=. .venv/bin/python scripts/depth_dropout.py CAPTURE OUT [--fraction 0.3] [--seed 0]

OUT gets a transforms.json whose ``depth_file_path`` points at OUT/depth_dropout/ (16-bit PNGs, each pixel set to 0,
no reading, with probability FRACTION; one seeded generator over the frames in order) and a symbolic link to every
other entry of CAPTURE (images, masks, gt).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np
from hide_mattes import write_copy  # scripts/ is the script's own folder on sys.path


def main(argv=None) -> Path:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("capture", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--fraction", type=float, default=0.3, help="share of depth pixels lost (default 0.3)")
    p.add_argument("--seed", type=int, default=0, help="seed of the generator (default 0)")
    a = p.parse_args(argv)
    src = a.capture / "transforms.json"
    if not src.is_file():
        raise SystemExit(f"{src}: no transforms.json")
    if not 0.0 <= a.fraction <= 1.0:
        raise SystemExit(f"--fraction {a.fraction}: must be in [0, 1]")
    t = json.loads(src.read_text())
    rng = np.random.default_rng(a.seed)
    (a.out / "depth_dropout").mkdir(parents=True, exist_ok=True)
    for fr in t["frames"]:
        path = a.capture / fr["depth_file_path"]
        d = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if d is None:
            raise SystemExit(f"{path}: not a readable depth image")
        d[rng.random(d.shape[:2]) < a.fraction] = 0
        rel = f"depth_dropout/{Path(fr['depth_file_path']).name}"
        tmp = a.out / (rel + ".tmp.png")
        cv2.imwrite(str(tmp), d)
        tmp.replace(a.out / rel)
        fr["depth_file_path"] = rel
    return write_copy(a.capture, a.out, t, own=("depth_dropout",))


if __name__ == "__main__":
    main()
