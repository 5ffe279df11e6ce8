"""Time to a model's first frame, as a user gets it: ``furrow render MODEL`` for one camera, whole process (issue 24).

The camera is the model's middle view scaled to ``--size`` (default 1280x960), written as a
one-frame transforms.json; the command is timed from start to exit (Python start-up, imports,
model load, GL context, the uploads and the frame), and the render's own stage table is printed.

    PYTHONPATH=. .venv/bin/python scripts/first_frame.py out/phone200_model
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> int:
    from volume.model import load_model

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("model", type=Path)
    p.add_argument("--size", default="1280x960", help="frame size WxH (default 1280x960)")
    p.add_argument("--method", default="gather")
    a = p.parse_args(argv)
    W, H = (int(v) for v in a.size.lower().split("x"))
    cams = load_model(a.model).rgbz.cameras
    c = cams[len(cams) // 2]
    eye = c.scaled(W / c.width)
    if (eye.width, eye.height) != (W, H):
        raise SystemExit(f"{a.size}: not the aspect of the model's views ({c.width}x{c.height})")
    with tempfile.TemporaryDirectory() as tmp:
        tj = Path(tmp) / "transforms.json"
        tj.write_text(json.dumps({"camera_model": "PINHOLE", "frames": [{"file_path": "first.png",
                                                                          **eye.to_nerfstudio()}]}))
        cmd = [sys.executable, "-m", "furrow", "render", str(a.model), "--cameras", str(tj), "-o", str(Path(tmp) / "o"),
               "--method", a.method]
        t0 = time.perf_counter()
        r = subprocess.run(cmd, env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True)
        wall = time.perf_counter() - t0
    print((r.stdout + r.stderr)[-3000:])
    print(json.dumps({"model": str(a.model), "views": len(cams), "size": [W, H], "method": a.method,
                      "exit": r.returncode, "wall_s": round(wall, 2)}))
    return r.returncode


if __name__ == "__main__":
    sys.exit(main())
