"""Held-out evaluation (METHODS §1.8, the paper's Fig. 11): build a model from every K-th frame
of a scan set, render the other frames with every method and score them against the photos.

Used by ``furrow eval``, ``bench/lopt.py`` and ``bench/render.py``.  Every method is drawn
through the one registry (``render.methods``) with the same options, so the methods differ only
in how they draw.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import NamedTuple

import numpy as np

from render import metrics
from render.methods import RenderOptions, create_renderer

#: Methods ``furrow eval`` draws, in the order of its table; the first two fill the side-by-side
#: sheets.
EVAL_METHODS = ("microfacet", "mesh-vdtm", "mesh-colour")
#: Amplification of the error panel of the side-by-side sheets.
ERROR_GAIN = 4.0
#: Where the evaluated model's geometry comes from (build_eval_model).
GEOMETRIES = ("auto", "model", "gt")


def result_key(method: str) -> str:
    """JSON key of a method's results ("mesh-vdtm" -> "mesh_vdtm")."""
    return method.replace("-", "_")


def reference_foreground(scan) -> np.ndarray:
    """(H, W) bool foreground of a reference view: measured depth or any non-black 8-bit pixel."""
    return (scan.depth > 0) | (scan.srgb8.max(axis=-1) > 0)


class HoldOut(NamedTuple):
    """A scan set split for held-out evaluation: the model's scans and the references."""

    kept: object  # capture.scan.ScanSet of the frames i % holdout == 0
    held: list  # the held-out capture.scan.Scan references
    kept_idx: list[int]
    held_idx: list[int]


def holdout_split(scanset, holdout: int, max_views: int | None = None) -> HoldOut:
    """Keep the frames i % holdout == 0 for the model; hold out the others, at most ``max_views``
    of them (evenly spaced)."""
    from capture.scan import ScanSet

    if holdout < 2:
        raise ValueError(f"--holdout must be >= 2, got {holdout}")
    n = len(scanset.scans)
    kept = [i for i in range(n) if i % holdout == 0]
    held = [i for i in range(n) if i % holdout != 0]
    if max_views is not None and len(held) > max_views:
        held = [held[int(round(j))] for j in np.linspace(0, len(held) - 1, max_views)]
    return HoldOut(ScanSet(tuple(scanset.scans[i] for i in kept), scanset.bounds, scanset.metadata),
                   [scanset.scans[i] for i in held], kept, held)


def volume_builder():
    """The volume stage's public model builder, or None while it does not exist."""
    try:
        mod = importlib.import_module("volume.build")
    except ModuleNotFoundError as e:
        if e.name in ("volume.build",):
            return None
        raise
    return getattr(mod, "build_model", None)


def build_eval_model(kept, scans_path: Path, geometry: str, l_max: int):
    """Model of the kept scans; returns (model, geometry actually used).

    ``geometry``: "model" builds it with the volume stage (volume.build.build_model, as
    ``furrow model``); "gt" takes the voxels from the synthetic set's exact gt/mesh.ply
    (render.gt_model, up to ``l_max``); "auto" uses "model" when the volume stage provides it."""
    from capture.io import resolve_transforms

    if geometry not in GEOMETRIES:
        raise ValueError(f"unknown geometry {geometry!r}; use one of {GEOMETRIES}")
    builder = volume_builder() if geometry in ("auto", "model") else None
    if geometry == "model" and builder is None:
        raise RuntimeError("--geometry model: the volume stage has no volume.build.build_model yet; use --geometry gt")
    if builder is not None:
        out = builder(kept, provenance={"scans": str(scans_path), "frames": "i % holdout == 0"})
        return (out[0] if isinstance(out, tuple) else out), "model"
    from render.gt_model import model_from_geometry
    from volume.metrics import read_ply_mesh

    base = scans_path if scans_path.is_dir() else resolve_transforms(scans_path).parent
    ply = base / "gt" / "mesh.ply"
    if not ply.is_file():
        raise FileNotFoundError(f"{ply}: --geometry gt needs a synthetic scan set with gt/mesh.ply")
    v, f = read_ply_mesh(ply)
    return model_from_geometry(kept, v, f, l_max, provenance={"scans": str(scans_path), "gt_mesh": str(ply)}), "gt"


def summarise(views: list[dict]) -> dict:
    """Means over the per-view records (ms, cpu_ms -> ms_per_frame, cpu_ms_per_frame), the largest
    hole over all views, and the records themselves under ``views``."""
    keys = ("psnr", "ssim", "psnr_masked", "ssim_masked", "hole_fraction", "largest_hole", "ms", "cpu_ms", "facets")
    out = {k: float(np.nanmean([v.get(k, np.nan) for v in views])) for k in keys}
    out["ms_per_frame"] = out.pop("ms")
    out["cpu_ms_per_frame"] = out.pop("cpu_ms")
    out["largest_hole"] = float(np.max([v["largest_hole"] for v in views]))
    out["views"] = views
    return out


def score_view(scan, frame) -> dict:
    """Scores of one rendered frame against its reference scan (render.metrics.compare) and
    the frame's stats record."""
    m = metrics.compare(scan.srgb8, frame.rgb, reference_foreground(scan), frame.alpha)
    m.update(frame.stats.record())
    return m


def write_side_by_side(path: Path, reference: np.ndarray, frames: list) -> None:
    """Sheet reference | frames[0] | frames[1] | ERROR_GAIN x |frames[0] - reference| (8-bit sRGB)."""
    from capture.imageio import write_png
    from capture.scan import to_uint8_srgb

    imgs = [to_uint8_srgb(f.rgb) for f in frames]
    err = np.clip(np.abs(imgs[0].astype(np.float32) - reference.astype(np.float32)) * ERROR_GAIN, 0, 255)
    write_png(path, np.concatenate([reference, *imgs, err.astype(np.uint8)], 1))


def evaluate(ctx, model, held, options: RenderOptions | None = None, methods=EVAL_METHODS,
             out_dir: Path | None = None, progress=None) -> dict:
    """Render every held-out scan with every method in ``methods``, all with the same
    ``options``; per method (key result_key(name)) the per-view scores and their means
    (summarise).  With ``out_dir``: out_dir/side_by_side/VIEW.png sheets of the first two methods."""
    from contextlib import ExitStack

    options = options if options is not None else RenderOptions()
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
                write_side_by_side(out_dir / "side_by_side" / (Path(name).stem + ".png"), scan.srgb8, frames[:2])
    return {k: summarise(v) for k, v in res.items()}
