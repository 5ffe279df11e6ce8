"""Gather's second depth layer (docs/novel_views.md, "A second depth layer"): where it changes a held-out
view's alpha, and what it costs a frame.

    PYTHONPATH=. python scripts/gather_layers.py split CAPTURE MODEL [--solid-front]
    PYTHONPATH=. python scripts/gather_layers.py time MODEL [--size 960x720] [--views 24] [--repeat 3] [--passes]

``split``: the held-out views (odd frames) of CAPTURE (with its true mattes) rendered by gather's numpy twin from
MODEL (``furrow model CAPTURE_hidden --frames 0::2``) without and with the second layer; the alpha's squared error
summed over the pixels it changes, by the front's alpha.  ``--solid-front off``: the first version, which counted
the layer behind by its own solidity alone (the docs' table); ``on`` (default): the rule as built.
``time``: median GPU frame times (no read-back) of the two configs, interleaved, on the capture's orbit around MODEL;
``--passes``: instead, the second layer's passes 1b and 2a alone, and 2a with its depth test off.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

#: The front's alpha bins of ``split``.
BINS = (0.0, 0.2, 0.4, 0.6, 0.8, 0.9, 0.95, 1.01)


def split(capture: str, model_dir: str, first_version: bool) -> None:
    from capture.io import read_scanset
    from render.gather import reference as g
    from volume.model import load_model

    scans = read_scanset(capture).scans
    r = load_model(model_dir).rgbz
    cams, rgb, dep = list(r.cameras), np.asarray(r.rgb, np.float32), np.asarray(r.depth, np.float32)
    al, meas = np.asarray(r.alpha, np.float32), r.measured
    centre = np.concatenate([c.depth_to_points(d)[0] for c, d in zip(cams, dep)]).mean(0)
    cfg = g.GatherConfig()
    if first_version:
        g.under_back = _first_version(g)
    acc = np.zeros((len(BINS) - 1, 3))
    for h in range(1, len(scans), 2):
        eye, t = scans[h].camera, np.asarray(scans[h].alpha, np.float64)
        a0 = g.gather_frame(eye, None, cams, rgb, dep, centre, dataclasses.replace(cfg, back_gap_m=0.0), al, meas)[1]
        a1 = g.gather_frame(eye, None, cams, rgb, dep, centre, cfg, al, meas)[1]
        changed = np.abs(a1 - a0) > 1e-6
        for k in range(len(BINS) - 1):
            m = changed & (a0 >= BINS[k]) & (a0 < BINS[k + 1])
            acc[k] += (m.sum(), ((a0 - t) ** 2)[m].sum(), ((a1 - t) ** 2)[m].sum())
    print("| front alpha | pixels changed | alpha SSE without -> with |\n|---|---|---|")
    for k in range(len(BINS) - 1):
        lo, hi = BINS[k], min(BINS[k + 1], 1.0)
        print(f"| {lo:.2f}-{hi:.2f} | {int(acc[k, 0]):,} | {acc[k, 1]:.0f} -> {acc[k, 2]:.0f} |")


def _first_version(g):
    def under_back(col, alpha, col_b, alpha_b, threshold):
        gb = g.solid(alpha_b, threshold)
        scale = np.where(alpha_b > 0, gb / np.where(alpha_b > 0, alpha_b, 1.0), 0.0)
        return col + ((1.0 - alpha) * scale)[..., None] * col_b, alpha + (1.0 - alpha) * gb
    return under_back


def frame_times(model_dir: str, size: str, views: int, repeat: int) -> None:
    from render.gather import reference as g
    from render.gather.gl import GatherRenderer

    ctx, m, eyes = _eyes(model_dir, size, views)
    configs = {"one layer": g.GatherConfig(back_gap_m=0.0), "two layers": g.GatherConfig()}
    ren = {k: GatherRenderer.from_model(ctx, m, config=c) for k, c in configs.items()}
    times = {k: [] for k in ren}
    for _ in range(repeat):
        for e in eyes:
            for k, r in ren.items():
                r.render(e, read=False)  # loads the views
                ctx.finish()
                t = time.perf_counter()
                r.render(e, read=False)
                ctx.finish()
                times[k].append(time.perf_counter() - t)
    for k, v in times.items():
        print(f"{k}: median {1e3 * np.median(v):.1f} ms over {len(v)} frames")
    print(f"ratio {np.median(times['two layers']) / np.median(times['one layer']):.2f}")
    for r in ren.values():
        r.release()


def pass_times(model_dir: str, size: str, views: int, repeat: int) -> None:
    """Median ms of pass 1b (mark), pass 2a behind its depth test and pass 2a with the test off."""
    from render.gather.gl import GatherRenderer, fill_offset
    from render.owner import near_far

    ctx, m, eyes = _eyes(model_dir, size, views)
    ren = GatherRenderer.from_model(ctx, m)
    times = {"mark": [], "under": [], "under, test off": []}

    def timed(key, draw):
        ctx.finish()
        t = time.perf_counter()
        draw()
        ctx.finish()
        times[key].append(time.perf_counter() - t)

    for _ in range(repeat):
        for e in eyes:
            dc, bl, w = ren.views(e)
            ren.load(np.concatenate([dc, bl]))
            near, far = near_far(e, ren.bounds)
            off = fill_offset(far)
            ren._under_pass(e, ren._depth_pass(e, dc, near, far, off), bl, w, off, timed)
    for k, v in times.items():
        print(f"pass {'1b' if k == 'mark' else '2a'} {k}: median {1e3 * np.median(v):.1f} ms over {len(v)} frames")
    ren.release()


def _eyes(model_dir: str, size: str, views: int):
    """(GL context, model, ``views`` eyes on the capture's orbit (capture.orbit.orbit_cameras) at ``size``)."""
    from capture.orbit import orbit_cameras
    from render.gl import create_context
    from volume.model import load_model

    m = load_model(model_dir)
    W, H = (int(x) for x in size.split("x"))
    cams = orbit_cameras(m.rgbz.cameras, views, center=np.asarray(m.bounds, float).mean(axis=0))
    if W * cams[0].height != H * cams[0].width:
        raise SystemExit(f"--size {size}: not the capture's aspect ({cams[0].width}x{cams[0].height})")
    return create_context(), m, [c.scaled(W / c.width) for c in cams]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("split")
    s.add_argument("capture")
    s.add_argument("model")
    s.add_argument("--solid-front", choices=("on", "off"), default="on",
                   help="off: the first version (g = solid(a_b) alone)")
    t = sub.add_parser("time")
    t.add_argument("model")
    t.add_argument("--size", default="960x720")
    t.add_argument("--views", type=int, default=24)
    t.add_argument("--repeat", type=int, default=3)
    t.add_argument("--passes", action="store_true", help="the second layer's passes alone")
    a = ap.parse_args()
    if a.cmd == "split":
        split(a.capture, a.model, a.solid_front == "off")
    else:
        (pass_times if a.passes else frame_times)(a.model, a.size, a.views, a.repeat)


if __name__ == "__main__":
    main()
