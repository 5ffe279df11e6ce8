"""Twins of conifer_room_table_ae_lens from its own cached 16 spp renders (no rendering): the same
samples, lens and table-lit light, with the room and the auto exposure switched on and off one at a
time, so that a held-out score's loss can be split by cause (docs/matting.md, issue 30 fourth round).

    PYTHONPATH=. .venv/bin/python scripts/hardcase_twins.py CACHE OUT [NAME ...]

CACHE: the hard cases' render cache (e.g. /work/cache/hardcases/_renders; only read: its view files are
linked into OUT/_renders); OUT: where the captures go; NAME of t16_black (every view over black),
t16_black_ae (over black, the kept views' auto exposure), t16_room (room and table on the kept views,
fixed exposure), t16_room_ae (the hard case itself, bit for bit but for its name); default all four.
--env-dir: the folder of courtyard.exr (Blender's studio lights, as scripts/hardcases.py).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from datasets_synthetic.pathtraced.assemble import Layout
from datasets_synthetic.pathtraced.cases import AUTO_EXPOSURE, ROOM_FRAMES, Options, _render, _write, case_spec

#: Twin name -> how its renders become a capture.
LAYOUTS = {"t16_black": Layout(None), "t16_black_ae": Layout(None, auto_exposure=AUTO_EXPOSURE),
           "t16_room": Layout(ROOM_FRAMES), "t16_room_ae": Layout(ROOM_FRAMES, auto_exposure=AUTO_EXPOSURE)}
ENV_DIR = "/work/main/build/blender-data/usr/share/blender/datafiles/studiolights/world"


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("cache", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("names", nargs="*", default=list(LAYOUTS))
    p.add_argument("--env-dir", type=Path, default=Path(ENV_DIR))
    a = p.parse_args(argv)
    opts = Options(out=a.out, cache=a.out / "_renders", env_dir=a.env_dir)
    spec = case_spec("conifer_room_table_ae_lens", opts)
    mine = opts.cache / spec.key()  # the cache's views linked, so that nothing is written beside them
    mine.mkdir(parents=True, exist_ok=True)
    for f in sorted((a.cache / spec.key()).glob("view_*.npz")):
        if not (mine / f.name).exists():
            (mine / f.name).symlink_to(f.resolve())
    got = _render(spec, opts, lambda s: None)
    for name in a.names:
        _write(name, f"{name}: conifer_room_table_ae_lens's renders (scripts/hardcase_twins.py)", spec,
               LAYOUTS[name], got, opts, log=print)


if __name__ == "__main__":
    main()
