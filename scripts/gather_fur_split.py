"""Where gather's held-out error on a path-traced capture lies (issue 30: gather >= the point splatter + 2 dB
over black; the fur misses it by a quarter of a dB): the masked squared error of gather and of the point
splatter split by the held-out view's true alpha, a sweep of GatherConfig on gather's numpy twin, and the
Monte Carlo noise of the path-traced reference itself.

    python scripts/hide_mattes.py /work/cache/hardcases/fur_black_similar CAP
    furrow eval CAP --holdout 2 --methods gather,points --save-model MODEL -o E
    PYTHONPATH=. python scripts/gather_fur_split.py CAP MODEL [--sweep] \\
        [--noise VIEW | --converged [--cache DIR]] [--case fur_similar_bg --env-dir DIR --spp 128]

The renders are gather's numpy twin (render/gather/reference.py: the GL path's digits within 0.001 dB) and
the point splatter's (render/points/reference.py) from the saved model's kept views; the scores are furrow
eval's (render.metrics.compare: 8-bit sRGB, inside the union of the reference's and the render's non-black
pixels).  ``--noise VIEW`` renders held-out view VIEW again with Mitsuba (datasets_synthetic.pathtraced,
the case that made the capture): at the case's spp with another seed and at ``--spp``, and its two kept
neighbours at ``--spp``; it prints the reference's own noise, gather against the converged view, and
gather from converged kept views (docs/novel_views.md, "Gather on fur (issue 30)").
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np
from scipy.ndimage import binary_erosion

from capture.io import read_scanset
from render import metrics
from render.evaluate import reference_foreground
from render.gather import reference as g
from render.points import reference as pr

#: A held-out pixel of true alpha at least this is opaque.
OPAQUE = 0.99
#: Opaque pixels farther than this (pixels) from any partial or empty one are the interior.
INTERIOR_PX = 3
#: The classes of the split, in print order.
CLASSES = ("hole", "extra", "a<0.5", "0.5-0.99", "opaque edge", "interior")
#: GatherConfig variants of the sweep (field overrides of the default).
SWEEP = (dict(), dict(vis_sigma_m=0.0015), dict(vis_sigma_m=0.006), dict(vis_floor=0.0), dict(vis_floor=0.5),
         dict(vis_floor=1.0), dict(k_blend=1), dict(k_blend=3), dict(k_depth=1), dict(k_depth=4), dict(splat_px=1),
         dict(splat_px=3), dict(measured_first=False), dict(resample="cubic"))


def load_arrays(model_dir) -> dict:
    """The saved model's kept views as the twins read them."""
    from volume.model import load_model

    m = load_model(model_dir)
    r = m.rgbz
    return dict(cams=list(r.cameras), rgb=np.asarray(r.rgb, np.float32), depth=np.asarray(r.depth, np.float32),
                alpha=None if r.alpha is None else np.asarray(r.alpha, np.float32), measured=r.measured,
                centre=np.asarray(m.bounds, np.float64).mean(0))


def gather8(M: dict, eye, cfg=None, rgb=None) -> np.ndarray:
    """Gather's twin frame for ``eye`` as 8-bit sRGB over black (``rgb``: other straight colours of the views)."""
    cfg = cfg or g.GatherConfig()
    rgb = M["rgb"] if rgb is None else rgb
    one_zbuffer = M["measured"] is None or not cfg.measured_first
    clouds = pr.back_project(M["cams"], rgb, M["depth"]) if one_zbuffer else None
    col = g.gather_frame(eye, clouds, M["cams"], rgb, M["depth"], M["centre"], cfg, M["alpha"], M["measured"])[0]
    return metrics.as_srgb8(col)


def points8(M: dict, eye) -> np.ndarray:
    """The point splatter's twin frame for ``eye`` as 8-bit sRGB over black."""
    clouds = pr.back_project(M["cams"], M["rgb"], M["depth"], M["alpha"])
    return metrics.as_srgb8(pr.points_frame(eye, clouds, M["cams"], M["centre"])[0])


def classes(ref8: np.ndarray, out8: np.ndarray, true_alpha: np.ndarray) -> dict:
    """The scored region (union of both foregrounds) split by CLASSES: reference only (hole), render only
    (extra), both by the held-out true alpha; opaque pixels within INTERIOR_PX of a partial one are the edge."""
    rf, of = ref8.max(-1) > 0, out8.max(-1) > 0
    both = rf & of
    interior = binary_erosion(true_alpha >= OPAQUE, iterations=INTERIOR_PX)
    return {"hole": rf & ~of, "extra": of & ~rf, "a<0.5": both & (true_alpha < 0.5),
            "0.5-0.99": both & (true_alpha >= 0.5) & (true_alpha < OPAQUE),
            "opaque edge": both & (true_alpha >= OPAQUE) & ~interior, "interior": both & interior}


def split(held, frames) -> dict:
    """Per class over the views: (share of the scored pixels, share of the squared error, MSE per channel,
    mean signed error per channel) of ``frames`` (8-bit, one per held-out scan)."""
    acc = {k: np.zeros(5) for k in CLASSES}
    for (_, scan), out8 in zip(held, frames, strict=True):
        ref = scan.srgb8.astype(np.float64)
        diff = out8.astype(np.float64) - ref
        cls = classes(scan.srgb8, out8, np.asarray(scan.alpha, np.float64))
        n = sum(m.sum() for m in cls.values())
        for k, m in cls.items():
            acc[k] += (m.sum(), (diff[m] ** 2).sum(), n, diff[m].sum(), 0)
    tot = sum(a[1] for a in acc.values())
    return {k: (a[0] / a[2], a[1] / tot, a[1] / max(a[0], 1) / 3, a[3] / max(a[0], 1) / 3) for k, a in acc.items()}


def mean_scores(held, frames) -> dict:
    """furrow eval's means of masked PSNR, SSIM, sharpness and holes over the held-out views."""
    recs = [metrics.compare(scan.srgb8, out8, reference_foreground(scan)) for (_, scan), out8 in zip(held, frames)]
    return {k: float(np.nanmean([r[k] for r in recs])) for k in ("psnr_masked", "ssim_masked", "sharpness",
                                                                 "hole_fraction")}


def fmt(s: dict) -> str:
    return (f"{s['psnr_masked']:.3f} / {s['ssim_masked']:.4f} / {s['sharpness']:.3f}, "
            f"holes {100 * s['hole_fraction']:.2f} %")


def report_split(held, M) -> None:
    for name, fn in (("gather", lambda e: gather8(M, e)), ("points", lambda e: points8(M, e))):
        frames = [fn(scan.camera) for _, scan in held]
        print(f"{name}: {fmt(mean_scores(held, frames))}")
        for k, (share, err, mse, bias) in split(held, frames).items():
            print(f"  {k:12s} pixels {share:.3f}  error {err:.3f}  MSE {mse:6.1f}  mean error {bias:+6.1f}")


def report_sweep(held, M) -> None:
    for over in SWEEP:
        cfg = dataclasses.replace(g.GatherConfig(), **over)
        frames = [gather8(M, scan.camera, cfg) for _, scan in held]
        print(f"{over or 'default'}: {fmt(mean_scores(held, frames))}", flush=True)


def render_again(case: str, opts, views, runs) -> dict:
    """{(view, tag): linear premultiplied colour over black} of the capture's ``case`` rendered by Mitsuba as
    datasets_synthetic.pathtraced.render.render_views renders it (room turn, reconstruction filter), with
    ``runs`` ((tag, spp or 0 = the case's, seed offset added to the case's seed) each); ``opts``: the
    cases.Options the capture was made with (its env_dir, seed, room_map, room_rotation: :func:`case_options`)."""
    from datasets_synthetic.lighting import resolve_env
    from datasets_synthetic.pathtraced import cases
    from datasets_synthetic.pathtraced.film import render_view
    from datasets_synthetic.pathtraced.render import view_seed
    from datasets_synthetic.pathtraced.runtime import load_mitsuba
    from datasets_synthetic.pathtraced.scene import PathScene, Room, exposure_for

    load_mitsuba()
    spec = cases.case_spec(case, opts)
    obj = spec.build_object()
    cams = spec.cameras(obj)
    emap = resolve_env(spec.env)
    ex = exposure_for(emap, cases.Layout().key)
    out = {}
    with PathScene(obj, Room(emap, spec.env_rotation_deg, spec.support), spec.seed) as ps:
        for v in views:
            ps.turn(spec.room_turn(v, cams))  # a turntable turns the room with the camera (render.render_views)
            for tag, spp, off in runs:
                r = render_view(ps, cams[v], spp or spec.spp, view_seed(spec.seed + off, v), spec.lens, spec.max_depth,
                                spec.rfilter)
                out[v, tag] = np.asarray(r.black * ex, np.float32)
    return out


def report_noise(cap, M, view: int, case: str, opts, spp: int, holdout: int = 2) -> None:
    """The reference's own noise and gather against converged renders, for held-out view ``view``."""
    scans = read_scanset(cap).scans
    kept = [i for i in range(len(scans)) if i % holdout == 0]
    if len(kept) != len(M["cams"]):
        raise SystemExit(f"the model kept {len(M['cams'])} of the {len(kept)} kept frames: build it with --views all")
    scan = scans[view]
    nb = pr.nearest_views(scan.camera, M["cams"], M["centre"], g.GatherConfig().k_blend)[0]
    r = render_again(case, opts, [view], (("other", 0, 3), ("conv", spp, 7)))
    r.update(render_again(case, opts, [kept[i] for i in nb], (("conv", spp, 7),)))
    ref, other, conv = scan.srgb8, metrics.as_srgb8(r[view, "other"]), metrics.as_srgb8(r[view, "conv"])
    rgb = M["rgb"].copy()
    for i in nb:
        a = M["alpha"][i][..., None] if M["alpha"] is not None else np.ones_like(rgb[i][..., :1])
        rgb[i] = np.where(a > 0, np.clip(r[kept[i], "conv"] / np.maximum(a, 1e-6), 0, 1), rgb[i])
    frames = {"gather": gather8(M, scan.camera), "gather, kept neighbours converged": gather8(M, scan.camera, rgb=rgb),
              "points": points8(M, scan.camera), "the converged view itself": conv}
    U = reference_foreground(scan) | (frames["gather"].max(-1) > 0)
    mse = lambda a, b: float(np.mean((a.astype(np.float64) - b.astype(np.float64))[U] ** 2))
    print(f"view {view}: the reference against another render at its spp: {metrics.psnr(ref, other, U):.2f} dB; "
          f"that render against {spp} spp: {metrics.psnr(other, conv, U):.2f} dB")
    for name, f in frames.items():
        print(f"  {name:34s} vs reference {metrics.psnr(ref, f, U):6.2f} dB (MSE {mse(ref, f):6.1f}, sharpness "
              f"{metrics.sharpness_ratio(ref, f, U):.3f});  vs {spp} spp {metrics.psnr(conv, f, U):6.2f} dB "
              f"(MSE {mse(conv, f):6.1f}, sharpness {metrics.sharpness_ratio(conv, f, U):.3f})")


def report_converged(held, M, case: str, opts, spp: int, cache: Path | None) -> None:
    """Gather and the point splatter scored as furrow eval against every held-out view rendered again at
    ``spp`` (the truth up to 1/``spp`` of the noise) and against the capture's own views."""
    path = lambda i: (cache or Path(".")) / f"v{i:03d}_{spp}spp.npy"
    todo = [i for i, _ in held if cache is None or not path(i).is_file()]
    fresh = render_again(case, opts, todo, (("conv", spp, 7),)) if todo else {}
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
        for i in todo:
            np.save(path(i), fresh[i, "conv"])
    convs = [fresh[i, "conv"] if i in todo else np.load(path(i)) for i, _ in held]
    for name, fn in (("gather", lambda e: gather8(M, e)), ("points", lambda e: points8(M, e))):
        frames = [fn(scan.camera) for _, scan in held]
        own = mean_scores(held, frames)
        recs = [metrics.compare(metrics.as_srgb8(c), f, metrics.foreground(metrics.as_srgb8(c)))
                for c, f in zip(convs, frames, strict=True)]
        conv = {k: float(np.nanmean([r[k] for r in recs])) for k in own}
        print(f"{name}: against the capture's views {fmt(own)};  against {spp} spp {fmt(conv)}")
    recs = [metrics.compare(scan.srgb8, metrics.as_srgb8(c), reference_foreground(scan)) for (_, scan), c in
            zip(held, convs, strict=True)]
    print(f"the {spp}-spp views scored against the capture's: "
          f"{fmt({k: float(np.nanmean([r[k] for r in recs])) for k in own})}")


def case_options(a):
    """cases.Options of the capture's case from the command line (``--env-dir``, ``--seed``, ``--room-map``,
    ``--room-rotation``: those scripts/hardcases.py made it with)."""
    from datasets_synthetic.pathtraced import cases

    return cases.Options(out=Path("."), cache=Path("."), env_dir=a.env_dir, seed=a.seed, room_map=a.room_map,
                         room_rotation=a.room_rotation)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("capture", help="the capture furrow eval scored (its held-out views carry the true matte)")
    ap.add_argument("model", help="the model furrow eval --save-model wrote")
    ap.add_argument("--holdout", type=int, default=2)
    ap.add_argument("--sweep", action="store_true", help="GatherConfig variants on the twin (SWEEP)")
    ap.add_argument("--noise", type=int, metavar="VIEW", help="a held-out view rendered again by Mitsuba")
    ap.add_argument("--case", default="fur_similar_bg", help="the scripts/hardcases.py case of the capture")
    ap.add_argument("--env-dir", type=Path, help="scripts/hardcases.py --env-dir")
    ap.add_argument("--seed", type=int, default=0, help="scripts/hardcases.py --seed the capture was made with")
    ap.add_argument("--room-map", help="scripts/hardcases.py --room-map the capture was made with")
    ap.add_argument("--room-rotation", type=float, help="scripts/hardcases.py --room-rotation of the capture")
    ap.add_argument("--spp", type=int, default=128, help="samples per pixel of the converged renders")
    ap.add_argument("--converged", action="store_true", help="every held-out view rendered again at --spp: "
                    "gather and points scored against them")
    ap.add_argument("--cache", type=Path, help="folder keeping the --converged renders (read back when there)")
    a = ap.parse_args(argv)
    scans = read_scanset(a.capture).scans
    held = [(i, scans[i]) for i in range(len(scans)) if i % a.holdout]
    M = load_arrays(a.model)
    report_split(held, M)
    if a.sweep:
        report_sweep(held, M)
    if a.noise is not None:
        report_noise(a.capture, M, a.noise, a.case, case_options(a), a.spp, a.holdout)
    if a.converged:
        report_converged(held, M, a.case, case_options(a), a.spp, a.cache)


if __name__ == "__main__":
    main()
