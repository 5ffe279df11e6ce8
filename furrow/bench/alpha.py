"""``furrow bench alpha``: the render side of soft alpha, isolated from matting -- gather with and
without the TRUE matte in the model, on synthetic captures (issue 20).

Per scene (``furrow synth`` in process, over black; the true matte of every view is the
rasteriser's coverage, filtered like the colour): a model of the frames i % 2 == 0 from the exact
geometry (render.gt_model), once without a matte (today: the photos' colour, opaque where depth)
and once with the kept views' true matte (straight colour = photo / alpha).  The other frames are
scored as ``furrow eval`` does: over black (masked PSNR / SSIM, sharpness) and composited with the
frame's alpha over white (sRGB 235) and a dark backdrop against the true composite, alpha MSE /
SAD against the true matte (render.evaluate.composite_scores); frame time is the median of
``--repeat`` draws per view.  With ``--picture FILE``: one held-out view composited over a bright
map (``--map``), binary mask | soft alpha | truth, cropped to the object.

    furrow bench alpha --scenes furball,plant --size 320x240 --views 24 [--picture docs/images/x.png]
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from capture.atomic import write_json
from furrow.bench import OUT_ROOT
from furrow.bench._common import print_result

#: Scores reported per variant (render.evaluate.score_view keys).
SCORES = ("psnr_masked", "ssim_masked", "sharpness", "psnr_white", "psnr_dark", "alpha_mse", "alpha_sad")
#: Margin of the picture's crop around the object (share of its box side).
CROP_MARGIN = 0.15


def synth_with_matte(synth_args: list[str]):
    """(ScanSet whose scans carry their true matte, the scene) of ``furrow synth SYNTH_ARGS`` (its
    defaults: over black, d435 depth, 0.5 px film filter) made in process.  ``datasets_synthetic.synth``
    gives every scan its true matte itself (the renderer's coverage under the colour's film filter);
    this bench used to record it by subclassing a rasteriser the synthesiser no longer uses."""
    import datasets_synthetic.synth as synth
    from furrow.cmd_synth import add_arguments, build_config

    ap = argparse.ArgumentParser()
    add_arguments(ap)
    cfg = build_config(ap.parse_args(synth_args + ["-o", "unused"]))
    cap = synth.synthesize(cfg)
    if any(s.alpha is None for s in cap.scanset.scans):  # pragma: no cover - the synthesiser always sets it
        raise RuntimeError("furrow bench alpha: the synthetic capture came without its true mattes")
    return cap.scanset, cap.scene


def models(kept, scene, l_max: int):
    """(model without a matte, model with the kept views' true matte) from the exact geometry."""
    from render.gt_model import model_from_geometry
    from volume.model import RgbzImages

    m = model_from_geometry(kept, scene.mesh.vertices, scene.mesh.faces, l_max)
    r = m.rgbz
    photos = np.stack([s.linear_rgb for s in kept.scans]).astype(np.float32)
    return replace(m, rgbz=RgbzImages(photos, r.depth, r.cameras)), m


def measure(ctx, variants: dict, held, method: str, repeat: int) -> dict:
    """Per variant (name -> model): mean scores over ``held`` and the median frame time of
    ``repeat`` draws per view, the variants' draws interleaved so that they share the machine's load."""
    from contextlib import ExitStack

    from render.evaluate import score_view
    from render.methods import create_renderer

    out = {}
    with ExitStack() as stack:
        rs = {v: stack.enter_context(create_renderer(method, ctx, m)) for v, m in variants.items()}
        ms = {v: [] for v in rs}
        for r in rs.values():
            r.render(held[0].camera, read=False)
        for _ in range(repeat):
            for s in held:
                for v, r in rs.items():
                    ms[v].append(r.render(s.camera, read=False).stats.ms)
        for v, r in rs.items():
            rows = [score_view(s, r.render(s.camera)) for s in held]
            out[v] = {k: float(np.mean([x[k] for x in rows])) for k in SCORES}
            out[v]["ms"] = float(np.median(ms[v]))
    return out


def picture(ctx, variants: dict, scan, env_name: str, path: Path) -> None:
    """One held-out view over the map ``env_name``: binary mask | soft alpha | truth (composite_frame,
    tone mapped, no glare), cropped to the object, labelled; written to ``path``."""
    from capture.imageio import write_png
    from capture.scan import to_uint8_srgb
    from render.composite.pipeline import composite_frame
    from render.evaluate import labelled
    from render.methods import create_renderer
    from render.shading.envmap import named_envmap

    env = named_envmap(env_name)
    panels = []
    for label, model in variants.items():
        with create_renderer("gather", ctx, model) as r:
            fr = r.render(scan.camera)
        img = composite_frame(ctx, fr.rgb, fr.depth, scan.camera, env, alpha=fr.alpha, ground=False, glare=False)
        panels.append((label, img))
    truth = composite_frame(ctx, scan.linear_rgb, scan.depth, scan.camera, env, alpha=scan.alpha, ground=False,
                            glare=False)
    panels.append(("truth (photo, true matte)", truth))
    ys, xs = np.nonzero(scan.alpha > 0)
    H, W = scan.alpha.shape
    side = max(np.ptp(ys), np.ptp(xs)) * (1 + 2 * CROP_MARGIN)
    cy, cx = (ys.min() + ys.max()) / 2, (xs.min() + xs.max()) / 2
    y0, x0 = int(max(cy - side / 2, 0)), int(max(cx - side / 2, 0))
    y1, x1 = int(min(cy + side / 2, H)), int(min(cx + side / 2, W))
    tiles = [labelled(to_uint8_srgb(img[y0:y1, x0:x1]), label) for label, img in panels]
    write_png(path, np.concatenate(tiles, 1))


def _table(res: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    t = Table(title="gather without / with the true matte in the model (held-out views; linear-light composites)")
    for c in ("scene", "model", "ms/frame", "PSNR masked (black)", "SSIM masked", "sharpness", "PSNR white 235",
              "PSNR dark", "alpha MSE", "SAD/1000"):
        t.add_column(c, justify="right")
    for scene, per in res["scenes"].items():
        for variant, r in per.items():
            t.add_row(scene, variant, f"{r['ms']:.1f}", f"{r['psnr_masked']:.2f}", f"{r['ssim_masked']:.3f}",
                      f"{r['sharpness']:.2f}", f"{r['psnr_white']:.2f}", f"{r['psnr_dark']:.2f}",
                      f"{r['alpha_mse']:.4f}", f"{r['alpha_sad']:.2f}")
    Console(width=160).print(t)


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="furrow bench alpha", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenes", default="furball,plant", help="comma-separated furrow synth scenes")
    p.add_argument("--size", default="320x240", help="WIDTHxHEIGHT (default 320x240)")
    p.add_argument("--views", type=int, default=24, help="views of the turntable (half kept, half held out)")
    p.add_argument("--strands", type=int, default=None, help="furball strands (default: the scene's)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--l-max", type=int, default=128, help="finest level of the exact-geometry model")
    p.add_argument("--repeat", type=int, default=3, help="timed draws per held-out view")
    p.add_argument("--method", default="gather", help="registered method measured (default gather)")
    p.add_argument("--picture", type=Path, default=None, help="write the before / after picture (first scene)")
    p.add_argument("--map", default="courtyard", help="environment map of the picture (default courtyard)")
    p.add_argument("-o", "--out", type=Path, default=OUT_ROOT / "bench" / "alpha")
    p.add_argument("--json", action="store_true", help="print the results as JSON on stdout")
    args = p.parse_args(argv)

    from render.evaluate import holdout_split
    from render.gl import gl_context

    res = {"size": args.size, "views": args.views, "method": args.method, "scenes": {}}
    for i, name in enumerate(args.scenes.split(",")):
        extra = ["--strands", str(args.strands)] if args.strands and name != "plant" else []
        ss, scene = synth_with_matte([name, "--size", args.size, "--views", str(args.views), "--seed", str(args.seed)]
                                     + extra)
        split = holdout_split(ss, 2)
        binary, matte = models(split.kept, scene, args.l_max)
        with gl_context() as ctx:
            res["scenes"][name] = measure(ctx, {"no matte": binary, "true matte": matte}, split.held, args.method,
                                          args.repeat)
            if args.picture is not None and i == 0:
                picture(ctx, {"binary mask (no matte)": binary, "soft alpha (true matte)": matte},
                        split.held[len(split.held) // 4], args.map, args.picture)
    args.out.mkdir(parents=True, exist_ok=True)
    write_json(args.out / "alpha.json", res)
    return print_result(res, args.json, _table, f"wrote {args.out / 'alpha.json'}")
