"""A phone-style capture (JPEG colour, depth at half / quarter of the colour resolution, millimetre PNG,
one top-level depth unit, no per-frame keys) models and renders within 1 dB of the same capture
with full-resolution depth and PNG colour.  The smooth control object (torus); every model is
scored against the SAME held-out full-resolution PNG photos, so only the input differs."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from capture.io import read_scanset
from furrow.cli import main
from render.evaluate import evaluate, holdout_split
from render.gl import gl_context
from render.methods import RenderOptions
from volume.pipeline import build_model
from volume.pipeline.config import FuseConfig, PipelineConfig
from volume.pyramid import LoptConfig

#: Allowed held-out PSNR loss (dB) of the phone-style captures against the full-resolution one.
MAX_PSNR_LOSS_DB = 1.0
#: Allowed SSIM loss.
MAX_SSIM_LOSS = 0.03
#: JPEG quality of the phone-style colour (phone apps export 85-95).
JPEG_QUALITY = 90
#: Finest model level: enough for a 160x120 capture, and quick.
MAX_RES = 64
SIZES = {"full": (160, 120), "half": (80, 60), "quarter": (40, 30)}


def phone_copy(full: Path, low: Path, dst: Path) -> None:
    """``full``'s cameras and colour (as JPEG) with ``low``'s depth maps (same rig at a lower
    resolution: genuinely low-resolution depth, not a decimated one) as millimetre 16-bit PNG."""
    meta = json.loads((full / "transforms.json").read_text())
    low_set = read_scanset(low)
    (dst / "images").mkdir(parents=True)
    (dst / "depth").mkdir()
    frames = []
    for f, s in zip(meta["frames"], low_set.scans):
        stem = Path(f["file_path"]).stem
        bgr = cv2.imread(str(full / f["file_path"]))
        cv2.imwrite(str(dst / "images" / f"{stem}.jpg"), bgr, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        cv2.imwrite(str(dst / "depth" / f"{stem}.png"), np.round(s.depth / 0.001).astype(np.uint16))
        frame = {k: v for k, v in f.items() if k not in ("depth_unit_scale_factor", "mask_path")}  # a phone: no matte
        frame.update(file_path=f"images/{stem}.jpg", depth_file_path=f"depth/{stem}.png")
        frames.append(frame)
    out = {k: v for k, v in meta.items() if k not in ("frames", "depth_unit_scale_factor")}
    out.update(depth_unit_scale_factor=0.001, frames=frames)
    (dst / "transforms.json").write_text(json.dumps(out))


@pytest.fixture(scope="module")
def captures(tmp_path_factory):
    root = tmp_path_factory.mktemp("phone")
    for name, (w, h) in SIZES.items():
        assert main(["synth", "torus", "-o", str(root / name), "--small", "--size", f"{w}x{h}"]) == 0
    for name in ("half", "quarter"):
        phone_copy(root / "full", root / name, root / f"phone_{name}")
    return root


def test_low_resolution_depth_and_jpeg_model_within_1db(captures):
    cfg = PipelineConfig(fuse=FuseConfig(lopt=LoptConfig(max_res=MAX_RES, min_res=8)))
    reference = holdout_split(read_scanset(captures / "full"), 2)
    scores = {}
    for name in ("full", "phone_half", "phone_quarter"):
        ss = read_scanset(captures / name)
        if name != "full":
            assert ss.scans[0].depth.shape == (120, 160) and "resampled" in ss.metadata["depth_resampled"]
        model, _ = build_model(holdout_split(ss, 2).kept, cfg)
        with gl_context() as ctx:
            res = evaluate(ctx, model, reference.held, RenderOptions(), methods=("microfacet",))
        scores[name] = (res["microfacet"]["psnr"], res["microfacet"]["ssim"])
    # measured (max_res 64): full 23.32 dB / 0.857, half 23.32 / 0.854, quarter 23.02 / 0.843
    psnr0, ssim0 = scores["full"]
    for name in ("phone_half", "phone_quarter"):
        psnr, ssim = scores[name]
        assert psnr >= psnr0 - MAX_PSNR_LOSS_DB, scores
        assert ssim >= ssim0 - MAX_SSIM_LOSS, scores
