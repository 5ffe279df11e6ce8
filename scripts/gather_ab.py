"""Gather's held-out scores on one saved model under several GatherConfig settings, side by side.

    PYTHONPATH=. .venv/bin/python scripts/gather_ab.py CAPTURE MODEL ARM [ARM ...] [--twin [--views N]] [--json OUT]
    PYTHONPATH=. .venv/bin/python scripts/gather_ab.py CAPTURE MODEL ARM [ARM ...] --sheet OUT.jpg [--view K]

CAPTURE: the capture `furrow eval CAPTURE --holdout K --save-model MODEL` was run on (its held-out frames carry the
true matte); MODEL: that saved model; each ARM: GatherConfig fields as ``name=value,name=value`` ("" or "default":
the defaults), e.g. ``fine_depth=off fine_depth=on`` (docs/novel_views.md "Fine depth").  Renders the held-out
views with the GL renderer (`furrow eval`'s settings), or with ``--twin`` with gather's numpy twin
(render.gather.reference.gather_frame, the first ``--views`` held-out views; the coverage pull needs the GL path's
excess, so the twin leaves it off), and prints per arm the mean over the views of the masked PSNR / SSIM /
sharpness over black, PSNR over white and over dark, alpha MSE (render.evaluate.score_view) and the pull given."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

KEYS = ("psnr_masked", "ssim_masked", "sharpness", "psnr_white", "psnr_dark", "alpha_mse")


def parse_arm(text: str):
    """The GatherConfig of an ARM (module docstring): fields of type str taken as written, the rest as numbers."""
    from render.gather.reference import GatherConfig

    kinds = {f.name: f.type for f in dataclasses.fields(GatherConfig)}
    kw = {}
    for item in filter(None, (s.strip() for s in ("" if text == "default" else text).split(","))):
        k, _, v = item.partition("=")
        if k not in kinds:
            raise SystemExit(f"gather_ab: {k!r} is not a GatherConfig field ({', '.join(kinds)})")
        kw[k] = v if kinds[k] == "str" else (v == "True" if kinds[k] == "bool" else float(v) if "." in v else int(v))
    return GatherConfig(**kw)


def _held(capture: Path, holdout: int):
    from capture.sources import open_source
    from furrow import cmd_eval
    from furrow.model_flags import pipeline_config
    from render import evaluate as ev

    p = argparse.ArgumentParser()
    cmd_eval.add_arguments(p)
    args = p.parse_args([str(capture), "--holdout", str(holdout), "--methods", "gather"])
    cfg = pipeline_config(args, out=None)
    held = ev.source_holdout(open_source(capture, cfg.undistort.mode), holdout, cfg, None, None).held
    return held, cmd_eval.render_options(args, ("gather",))


def _twin_frames(model, held, cfg):
    from render.frame import Frame, FrameStats
    from render.gather import reference as gr
    from render.points import reference as pr

    r = model.rgbz
    cams, rgb, dep = list(r.cameras), np.asarray(r.rgb, np.float32), np.asarray(r.depth, np.float32)
    alpha = None if r.alpha is None else np.asarray(r.alpha, np.float32)
    clouds = pr.back_project(cams, rgb, dep) if r.measured is None else None
    twin_cfg = dataclasses.replace(cfg, alpha_mass="off")
    for scan in held:
        col, a, z, _ = gr.gather_frame(scan.camera, clouds, cams, rgb, dep, model.bounds.mean(0), twin_cfg, alpha,
                                       r.measured)
        yield scan, Frame(col, a, z, FrameStats(0.0, 0.0, supersample=1))


def scores(capture: Path, model_dir: Path, arms, holdout: int = 2, twin: bool = False, views: int = 6) -> dict:
    """{arm text: the mean of KEYS over the held-out views, and ``pulls`` (per view)} for each arm."""
    from render import evaluate as ev
    from render.gather.gl import GatherRenderer
    from render.gl import gl_context
    from volume.model import load_model

    held, options = _held(capture, holdout)
    model = load_model(model_dir)
    out = {}
    with gl_context() as ctx:
        for arm in arms:
            cfg = parse_arm(arm)
            if twin:
                rows = [{**ev.score_view(s, fr), "pull": 0.0} for s, fr in _twin_frames(model, held[:views], cfg)]
            else:
                with GatherRenderer.from_model(ctx, model, options, config=cfg) as r:
                    rows = []
                    for scan in held:
                        fr = r.render(scan.camera)
                        rows.append({**ev.score_view(scan, fr), "pull": fr.stats.alpha_pull or 0.0})
            out[arm] = {**{k: float(np.nanmean([x[k] for x in rows])) for k in KEYS},
                        "pulls": [x["pull"] for x in rows]}
    return out


def sheet(capture: Path, model_dir: Path, arms, view: int, out: Path, holdout: int = 2) -> None:
    """A JPEG of held-out view ``view`` over white (sRGB 235, render.evaluate.COMPOSITE_BACKDROPS): the true composite
    (the photo over black plus (1 - true alpha) x white), then each arm's (GL), cropped to the object; below each arm,
    ERROR_GAIN x its absolute error."""
    import cv2

    from capture.scan import srgb_to_linear
    from render import evaluate as ev
    from render import metrics
    from render.gather.gl import GatherRenderer
    from render.gl import gl_context
    from volume.model import load_model

    held, options = _held(capture, holdout)
    scan, model = held[view], load_model(model_dir)
    white = float(srgb_to_linear(np.float32(ev.COMPOSITE_BACKDROPS["white"] / 255)))
    t = np.asarray(scan.alpha, np.float32)
    ref = metrics.as_srgb8(srgb_to_linear(scan.srgb8.astype(np.float32) / 255) + (1 - t)[..., None] * white)
    with gl_context() as ctx:
        frames = []
        for arm in arms:
            with GatherRenderer.from_model(ctx, model, options, config=parse_arm(arm)) as r:
                frames.append((arm or "default", r.render(scan.camera)))
    ys, xs = np.nonzero((t > 0) | np.any([f.alpha > 0 for _, f in frames], axis=0))
    m = 8
    box = (slice(max(ys.min() - m, 0), ys.max() + m + 1), slice(max(xs.min() - m, 0), xs.max() + m + 1))
    top, bottom = [ev.labelled(np.ascontiguousarray(ref[box]), "reference over white")], [np.zeros_like(ref[box])]
    for name, f in frames:
        im = metrics.as_srgb8(f.rgb + (1 - f.alpha)[..., None] * white)[box]
        err = np.clip(np.abs(im.astype(np.float32) - ref[box].astype(np.float32)) * ev.ERROR_GAIN, 0, 255)
        top.append(ev.labelled(np.ascontiguousarray(im), name))
        bottom.append(ev.labelled(np.ascontiguousarray(err.astype(np.uint8)), f"{ev.ERROR_GAIN:g} x |error|"))
    img = np.concatenate([np.concatenate(top, 1), np.concatenate(bottom, 1)], 0)
    scale = max(1, int(round(720 / img.shape[0])))
    img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp.jpg")
    cv2.imwrite(str(tmp), cv2.cvtColor(img, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 90])
    tmp.replace(out)


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("capture", type=Path)
    p.add_argument("model", type=Path)
    p.add_argument("arms", nargs="+", help="GatherConfig fields per arm: name=value,name=value ('default': none)")
    p.add_argument("--holdout", type=int, default=2)
    p.add_argument("--twin", action="store_true", help="gather's numpy twin instead of the GL renderer")
    p.add_argument("--views", type=int, default=6, help="held-out views the twin draws (default 6)")
    p.add_argument("--json", type=Path, help="write every arm's numbers here")
    p.add_argument("--sheet", type=Path, help="instead: a JPEG of one held-out view over white, reference and arms")
    p.add_argument("--view", type=int, default=0, help="the held-out view of --sheet (default 0)")
    a = p.parse_args(argv)
    if a.sheet:
        sheet(a.capture, a.model, a.arms, a.view, a.sheet, a.holdout)
        return {}
    out = scores(a.capture, a.model, a.arms, a.holdout, a.twin, a.views)
    for arm, r in out.items():
        s = np.array(r["pulls"])
        print(f"{arm or 'default':32s} over black {r['psnr_masked']:.3f} / {r['ssim_masked']:.4f} / "
              f"{r['sharpness']:.3f}; over white {r['psnr_white']:.2f}; over dark {r['psnr_dark']:.2f}; alpha MSE "
              f"{r['alpha_mse']:.4f}; pull {s.min():.3f}-{s.max():.3f}")
    if a.json:
        from capture.atomic import write_json

        write_json(a.json, out)
    return out


if __name__ == "__main__":
    main()
