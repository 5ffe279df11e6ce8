"""A phone-sized synthetic capture, written in chunks of views so that its own memory stays bounded (issue 24).

``furrow synth`` holds every rendered view (float32 colour, clean depth and normals for gt/) before
it writes the capture: fine for tens of views, not for a Polycam / Record3D-like 200 frames at
1920x1440.  This script renders the same scene ``--chunk`` views at a time (SynthConfig.views:
noise seeds follow the view index, so the views equal furrow synth's) and writes each chunk's
images and depth straight away, the depth at the phone's ``--depth-size`` (nearest pixel centre,
as ``furrow synth --depth-size``).  No gt/ stacks and, unless ``--masks``, no true mattes: a
phone gives neither.

    python scripts/synth_phone.py -o out/phone200                      # 200 views, 1920x1440, depth 256x192
    python scripts/synth_phone.py -o out/phone24 --views 24 --rings 2  # a small one
    python scripts/synth_phone.py -o out/phone72_room_ae --views 72 --size 1280x960 --masks --background env \
        --synth-args "--background-frames 0::2 --auto-exposure"    # a room behind the kept views, auto exposure
    furrow model out/phone200 -o out/phone200_model
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np

from capture.atomic import atomic_dir
from capture.io import TRANSFORMS, _write_images, depth_format_spec, jsonable
from capture.matte_io import write_matte

#: Ring elevations (degrees) of the phone orbit, lowest first: a person walking round a pot plant
#: at three or four heights.
RING_ELEVATIONS = (10.0, 25.0, 40.0, 55.0)


def parse(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder (must not exist)")
    p.add_argument("--scene", default="plant", help="furrow synth scene (default plant)")
    p.add_argument("--views", type=int, default=200, help="views in all (default 200)")
    p.add_argument("--rings", type=int, default=4, help="rings of the orbit (views / rings each; default 4)")
    p.add_argument("--size", default="1920x1440", help="colour size WxH (default 1920x1440)")
    p.add_argument("--depth-size", default="256x192", help="depth size WxH (default 256x192)")
    p.add_argument("--support", default="table", choices=["none", "disc", "table"], help="support (default table)")
    p.add_argument("--background", default="black", choices=["black", "env", "clutter"],
                   help="background (default black)")
    p.add_argument("--chunk", type=int, default=20, help="views rendered at a time (default 20)")
    p.add_argument("--supersample", type=int, default=1,
                   help="colour supersampling per axis (default 1: a phone's own pixels; furrow synth's 3 takes "
                        "15 s a view at this size here)")
    p.add_argument("--masks", action="store_true", help="also write the true mattes (masks/; a phone has none)")
    p.add_argument("--synth-args", default="", metavar="ARGS",
                   help="more furrow synth arguments, one string (e.g. \"--background-frames 0::2 --auto-exposure\")")
    return p.parse_args(argv)


def synth_args(a: argparse.Namespace) -> argparse.Namespace:
    """furrow synth's arguments for the same capture (its defaults for everything else)."""
    from furrow.cmd_synth import add_arguments

    p = argparse.ArgumentParser()
    add_arguments(p)
    if a.views % a.rings:
        raise SystemExit(f"--views {a.views} must be a multiple of --rings {a.rings}")
    elev = ",".join(str(e) for e in RING_ELEVATIONS[:a.rings])
    return p.parse_args([a.scene, "-o", str(a.out), "--views", str(a.views), "--size", a.size,
                         "--elevations", elev, "--support", a.support, "--background", a.background,
                         "--supersample", str(a.supersample), *a.synth_args.split()])


def main(argv=None) -> int:
    from datasets_synthetic.scenes import build_scene
    from datasets_synthetic.synth import synthesize
    from furrow.cmd_synth import build_config
    from render.gl import gl_context

    a = parse(argv)
    sa = synth_args(a)
    if sa.relight_env or sa.board:
        raise SystemExit("synth_phone.py: --relight-env and --board are written by furrow synth only")
    cfg = build_config(sa)
    gains = None
    if sa.auto_exposure is not None:  # as furrow synth --auto-exposure: the kept views' gains, gt/exposure.json
        from datasets_synthetic.camera_traits import apply_exposure, exposure_gains

        gains = exposure_gains(cfg.rig.n_views, sa.auto_exposure, sa.white_balance, cfg.seed, sa.exposure_holdout)
    depth_size = tuple(int(v) for v in a.depth_size.lower().split("x"))
    ext, unit = depth_format_spec("png")
    frames, bounds, meta = [], None, {}
    t0 = time.perf_counter()
    scene = build_scene(cfg.scene, cfg.seed, **cfg.scene_params)  # once: every chunk renders the same object
    with atomic_dir(a.out) as tmp, gl_context() as ctx:
        for c0 in range(0, cfg.rig.n_views, a.chunk):
            idx = tuple(range(c0, min(c0 + a.chunk, cfg.rig.n_views)))
            cap = synthesize(dataclasses.replace(cfg, views=idx), ctx, scene)
            if gains is not None:
                cap = dataclasses.replace(cap, scanset=apply_exposure(cap.scanset, gains[list(idx)]))
            if bounds is None:
                bounds, meta = np.asarray(cap.scanset.bounds), dict(cap.scanset.metadata)
            for s in cap.scanset.scans:
                stem = Path(s.name).stem
                _write_images(s, tmp / f"images/{stem}.png", tmp / f"depth/{stem}.{ext}", ext, unit, depth_size)
                frames.append({"file_path": f"images/{stem}.png", "depth_file_path": f"depth/{stem}.{ext}",
                               **s.camera.to_nerfstudio(), **(write_matte(s, tmp, stem) if a.masks else {})})
            del cap
            print(f"{len(frames)}/{cfg.rig.n_views} views, {time.perf_counter() - t0:.0f} s", flush=True)
        out = {"camera_model": "PINHOLE", "depth_unit_scale_factor": unit, "frames": frames}
        if a.support == "none":  # as furrow synth: a capture with a support has no bounds (derived from the depth)
            out["furrow"] = {"bounds": bounds.tolist(), "metadata": jsonable(meta)}
        (tmp / TRANSFORMS).write_text(json.dumps(out, indent=1))
        if gains is not None:
            from datasets_synthetic.camera_traits import EXPOSURE_FILE, exposure_record

            (tmp / EXPOSURE_FILE).parent.mkdir(parents=True, exist_ok=True)
            (tmp / EXPOSURE_FILE).write_bytes(exposure_record([Path(f["file_path"]).name for f in frames], gains,
                                                              sa.auto_exposure, sa.white_balance, sa.exposure_holdout))
    print(f"wrote {a.out / TRANSFORMS}: {len(frames)} views {a.size}, depth {a.depth_size}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
