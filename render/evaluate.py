"""Held-out evaluation (docs/methods.md §1.8, the paper's Fig. 11): build a model from every K-th frame
of a scan set, render the other frames with every method and score them against the photos.

Used by ``furrow eval``, ``furrow/bench/lopt.py`` and ``furrow/bench/render.py``.  Every method is drawn
through the one registry (``render.methods``) with the same options, so the methods differ only
in how they draw; which methods are evaluated and shown on the sheets is their specs' say
(``render.methods.eval_methods``, ``sheet_methods``).
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import NamedTuple

import numpy as np

from render import metrics
from render.methods import RenderOptions, create_renderer, eval_methods, sheet_methods

#: Amplification of the error panels of the side-by-side sheets.
ERROR_GAIN = 4.0
#: Label text of the sheets: OpenCV Hershey font scale per 480 image rows, and its colour.
LABEL_SCALE = 0.6
LABEL_COLOUR = (255, 255, 0)
#: Where the evaluated model's geometry comes from (build_eval_model): the pipeline ("model"; "auto"
#: is the same) or the synthetic capture's exact mesh ("gt").
GEOMETRIES = ("auto", "model", "gt")
#: Backdrops of the composite scores (8-bit sRGB grey): a product photo's white and a dark one.
COMPOSITE_BACKDROPS = {"white": 235, "dark": 24}
#: Matting convention: SAD is reported in thousands of pixels (sum of |alpha error| / 1000).
SAD_UNIT = 1000.0
#: Per-view scores averaged by summarise (composite ones are NaN where the scan has no matte; facets, alpha_pull,
#: fine_depth and partial_share NaN for a method that does not report them).
SUMMARY_KEYS = ("psnr", "ssim", "psnr_masked", "ssim_masked", "sharpness", "hole_fraction", "largest_hole", "ms",
                "cpu_ms", "facets", "psnr_white", "psnr_dark", "alpha_mse", "alpha_sad", "alpha_pull",
                "fine_depth", "partial_share")


def result_key(method: str) -> str:
    """JSON key of a method's results ("mesh-vdtm" -> "mesh_vdtm")."""
    return method.replace("-", "_")


def reference_foreground(scan) -> np.ndarray:
    """(H, W) bool foreground of a reference view: its non-black 8-bit pixels (the captures are
    over black).  The depth is not used: a scorer outside the project sees only the PNGs, and a
    sensor's flying pixels put depth on the black background beside every silhouette."""
    return metrics.foreground(scan.srgb8)


class HoldOut(NamedTuple):
    """A scan set split for held-out evaluation: the model's scans and the references."""

    kept: object  # capture.scan.ScanSet of the frames i % holdout == 0 (None from source_holdout)
    held: list  # the held-out capture.scan.Scan references
    kept_idx: list[int]
    held_idx: list[int]


def holdout_indices(n: int, holdout: int, max_views: int | None = None) -> tuple[list[int], list[int]]:
    """(kept, held): positions i % holdout == 0 of ``range(n)`` for the model, the others held out,
    at most ``max_views`` of them (evenly spaced)."""
    if holdout < 2:
        raise ValueError(f"--holdout must be >= 2, got {holdout}")
    kept = [i for i in range(n) if i % holdout == 0]
    held = [i for i in range(n) if i % holdout != 0]
    if max_views is not None and len(held) > max_views:
        held = [held[int(round(j))] for j in np.linspace(0, len(held) - 1, max_views)]
    return kept, held


def holdout_split(scanset, holdout: int, max_views: int | None = None) -> HoldOut:
    """A scan set in memory split by :func:`holdout_indices`."""
    from capture.scan import ScanSet

    kept, held = holdout_indices(len(scanset.scans), holdout, max_views)
    return HoldOut(ScanSet(tuple(scanset.scans[i] for i in kept), scanset.bounds, scanset.metadata),
                   [scanset.scans[i] for i in held], kept, held)


def source_holdout(source, holdout: int, cfg=None, max_views: int | None = None, progress=None) -> HoldOut:
    """A capture (capture.sources.Source) split as :func:`holdout_split` does, among the frames
    ``cfg`` reads (its ``frames``): ``kept_idx`` and ``held_idx`` index ``source.frames``; the held-out
    references are read by the pipeline's reading stages (volume.pipeline.runner.read_views); ``kept``
    is None (the pipeline reads those: :func:`build_eval_model`)."""
    from capture.scan import select_indices
    from volume.pipeline.config import PipelineConfig
    from volume.pipeline.runner import read_views

    cfg = cfg or PipelineConfig()
    frames = select_indices(cfg.read.frames, len(source))
    kept, held = holdout_indices(len(frames), holdout, max_views)
    kept, held = [frames[i] for i in kept], [frames[i] for i in held]
    return HoldOut(None, read_views(source, [source.frames[i] for i in held], cfg, progress), kept, held)


class EvalModel(NamedTuple):
    """The model of the kept frames (:func:`build_eval_model`)."""

    model: object  # volume.model.Model
    geometry: str  # "model" or "gt"
    summary: dict | None  # the pipeline's ``furrow model --json`` summary ("model" geometry)
    metadata: dict  # the kept scans' scan-set metadata


@contextlib.contextmanager
def build_eval_model(source, kept: list[int], cfg=None, geometry: str = "auto", l_max: int = 128, hooks=None):
    """``with build_eval_model(...) as em:`` the :class:`EvalModel` of the frames ``kept`` (indices
    into ``source.frames``, a capture.sources.Source).

    ``geometry``: "model" (and "auto") runs the pipeline (volume/pipeline: the same stages and
    config as ``furrow model --frames KEPT``; ``cfg`` a PipelineConfig, its ``frames`` replaced by
    ``kept``); "gt" takes the voxels from the synthetic set's exact gt/mesh.ply (render.gt_model, up
    to ``l_max``) and the kept frames as read.  The pipeline's spill folder (the model's RGBz crops)
    lives until the ``with`` block ends."""
    from dataclasses import replace

    from capture.sources import ReadConfig
    from volume.pipeline.config import PipelineConfig
    from volume.pipeline.runner import run_pipeline

    if geometry not in GEOMETRIES:
        raise ValueError(f"unknown geometry {geometry!r}; use one of {GEOMETRIES}")
    cfg = replace(cfg or PipelineConfig(), read=ReadConfig(",".join(map(str, kept))))
    if geometry == "gt":
        yield _gt_model(source, kept, cfg, l_max)
        return
    with run_pipeline(source, cfg, hooks) as run:
        yield EvalModel(run.model, "model", run.summary(), run.work.metadata)


def _gt_model(source, kept, cfg, l_max: int) -> EvalModel:
    """The EvalModel of ``--geometry gt`` (:func:`build_eval_model`)."""
    from capture.sources import finish_scanset
    from render.gt_model import model_from_geometry
    from volume.metrics import read_ply_mesh
    from volume.pipeline.runner import read_views

    base = Path(source.path) if Path(source.path).is_dir() else Path(source.path).parent
    ply = base / "gt" / "mesh.ply"
    if not ply.is_file():
        raise FileNotFoundError(f"{ply}: --geometry gt needs a synthetic scan set with gt/mesh.ply")
    ss = finish_scanset(source, read_views(source, [source.frames[i] for i in kept], cfg))
    v, f = read_ply_mesh(ply)
    model = model_from_geometry(ss, v, f, l_max, provenance={"scans": str(source.path), "gt_mesh": str(ply)})
    return EvalModel(model, "gt", None, ss.metadata)


def summarise(views: list[dict]) -> dict:
    """Means over the per-view records (ms, cpu_ms -> ms_per_frame, cpu_ms_per_frame), the largest
    hole over all views, and the records themselves under ``views``."""
    out = {}
    for k in SUMMARY_KEYS:
        vals = np.array([v.get(k, np.nan) for v in views], np.float64)
        out[k] = float(np.nanmean(vals)) if np.isfinite(vals).any() else float("nan")
    out["ms_per_frame"] = out.pop("ms")
    out["cpu_ms_per_frame"] = out.pop("cpu_ms")
    out["largest_hole"] = float(np.max([v["largest_hole"] for v in views]))
    out["views"] = views
    return out


def composite_scores(scan, frame) -> dict:
    """Scores of the frame composited with its matte against the true composite, when the scan
    has a true matte (``scan.alpha``; else {}): the held-out photo is over black (premultiplied, as
    the evaluation captures are made), so its composite over a backdrop B is photo + (1 - alpha) B
    in linear light, and the frame's is rgb + (1 - frame.alpha) B (render.frame.Frame.over).
    psnr_white / psnr_dark: PSNR (8-bit sRGB) over COMPOSITE_BACKDROPS inside the union of the
    true matte's, the photo's and the frame's foreground; alpha_mse: mean squared alpha error
    there; alpha_sad: sum of |alpha error| over the image / SAD_UNIT."""
    if scan.alpha is None:
        return {}
    from capture.scan import srgb_to_linear

    true_a = np.asarray(scan.alpha, np.float64)
    photo = scan.linear_rgb.astype(np.float64)
    region = (true_a > 0) | reference_foreground(scan) | frame.mask
    out = {}
    for name, grey in COMPOSITE_BACKDROPS.items():
        B = float(srgb_to_linear(np.float64(grey / 255.0)))
        want = photo + (1.0 - true_a)[..., None] * B
        out[f"psnr_{name}"] = metrics.psnr(np.clip(want, 0, None), np.clip(frame.over(B), 0, None), region)
    err = np.asarray(frame.alpha, np.float64) - true_a
    out["alpha_mse"] = float(np.mean(err[region] ** 2)) if region.any() else float("nan")
    out["alpha_sad"] = float(np.abs(err).sum() / SAD_UNIT)
    return out


def score_view(scan, frame) -> dict:
    """Scores of one rendered frame against its reference scan (render.metrics.compare: 8-bit
    sRGB, masked scores inside the union of the non-black pixels of the reference and of the
    rendering over black, i.e. its premultiplied colour, as ``furrow render --background black``
    writes it), the composite scores (:func:`composite_scores`, with a true matte) and the frame's
    stats record."""
    m = metrics.compare(scan.srgb8, metrics.as_srgb8(frame.rgb), reference_foreground(scan))
    m.update(composite_scores(scan, frame))
    m.update(frame.stats.record())
    return m


def labelled(img: np.ndarray, text: str) -> np.ndarray:
    """``img`` (H, W, 3) uint8 with ``text`` written in its top-left corner (LABEL_COLOUR)."""
    import cv2

    out = np.ascontiguousarray(img)
    rows = img.shape[0] / 480
    cv2.putText(out, text, (4, max(int(18 * rows), 8)), cv2.FONT_HERSHEY_SIMPLEX, LABEL_SCALE * rows, LABEL_COLOUR, 1,
                cv2.LINE_AA)
    return out


def side_by_side(reference: np.ndarray, images: dict) -> np.ndarray:
    """(2 H, (1 + n) W, 3) uint8 sheet: top row the reference and the n renderings (8-bit sRGB,
    ``images`` name -> image), bottom row under each rendering ERROR_GAIN x its absolute error
    (under the reference: black).  Every panel is labelled."""
    ref = np.asarray(reference, np.uint8)
    top = [labelled(ref.copy(), "reference")]
    bottom = [np.zeros_like(ref)]
    for name, img in images.items():
        im = metrics.as_srgb8(img)
        err = np.clip(np.abs(im.astype(np.float32) - ref.astype(np.float32)) * ERROR_GAIN, 0, 255).astype(np.uint8)
        top.append(labelled(im.copy(), name))
        bottom.append(labelled(err, f"{ERROR_GAIN:g} x |{name} - reference|"))
    return np.concatenate([np.concatenate(top, 1), np.concatenate(bottom, 1)], 0)


def write_side_by_side(path: Path, reference: np.ndarray, images: dict) -> None:
    """Write :func:`side_by_side` as a PNG (atomic)."""
    from capture.imageio import write_png

    write_png(path, side_by_side(reference, images))


def evaluate(ctx, model, held, options: RenderOptions | None = None, methods=None,
             out_dir: Path | None = None, progress=None) -> dict:
    """Render every held-out scan with every method in ``methods`` (default: eval_methods()), all
    with the same ``options``; per method (key result_key(name)) the per-view scores and their
    means (summarise).  With ``out_dir``: out_dir/side_by_side/VIEW.png sheets (side_by_side) of
    the sheet methods (render.methods.sheet_methods) among ``methods``."""
    from contextlib import ExitStack

    options = options if options is not None else RenderOptions()
    methods = tuple(methods) if methods is not None else eval_methods()
    on_sheet = set(sheet_methods())
    res = {result_key(m): [] for m in methods}
    with ExitStack() as stack:
        renderers = [stack.enter_context(create_renderer(m, ctx, model, options)) for m in methods]
        for r in renderers:  # warm-up: shader compilation
            r.render(held[0].camera, read=False)
        for scan in progress(held, "evaluating") if progress else held:
            name = Path(scan.name).name
            frames = [r.render(scan.camera) for r in renderers]
            for m, fr in zip(methods, frames):
                res[result_key(m)].append({**score_view(scan, fr), "view": name})
            if out_dir is not None:
                sheet = {m: fr.rgb for m, fr in zip(methods, frames) if m in on_sheet}
                write_side_by_side(out_dir / "side_by_side" / (Path(name).stem + ".png"), scan.srgb8, sheet)
    return {k: summarise(v) for k, v in res.items()}
