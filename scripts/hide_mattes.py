"""A copy of a transforms.json capture whose kept frames carry no matte, for `furrow eval --holdout K`
as a user without mattes would run it (issue 30: the evaluation captures supply none), while the
held-out frames keep their true matte for the composite and alpha scores.

    PYTHONPATH=. .venv/bin/python scripts/hide_mattes.py CAPTURE OUT [--holdout K]

OUT gets a transforms.json without ``mask_path`` on the frames i % K == 0 (the frames `furrow eval
--holdout K` keeps) and a symbolic link to every other entry of CAPTURE (images, depth, masks, gt).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from capture.atomic import write_json


def main(argv=None) -> Path:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("capture", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--holdout", type=int, default=2, help="K of furrow eval --holdout K (default 2)")
    a = p.parse_args(argv)
    src = a.capture / "transforms.json"
    if not src.is_file():
        raise SystemExit(f"{src}: no transforms.json")
    t = json.loads(src.read_text())
    for i, fr in enumerate(t["frames"]):
        if i % a.holdout == 0:
            fr.pop("mask_path", None)
    return write_copy(a.capture, a.out, t)


def write_copy(capture: Path, out: Path, transforms: dict, own: tuple = ()) -> Path:
    """OUT with ``transforms`` as its transforms.json and a symbolic link to every other entry of ``capture`` but the
    names in ``own`` (what the copy writes itself); prints and returns OUT."""
    out.mkdir(parents=True, exist_ok=True)
    for entry in capture.iterdir():
        link = out / entry.name
        if entry.name != "transforms.json" and entry.name not in own and not link.exists():
            link.symlink_to(entry.resolve())
    write_json(out / "transforms.json", transforms)
    print(out)
    return out


if __name__ == "__main__":
    main()
