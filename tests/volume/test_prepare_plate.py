"""The plate and matte stages end to end (volume/surroundings.py): nothing lost over black, the room taken out.

Over black C = a F exactly, so the default matte (a detected black backdrop, solved with B = 0)
must render the held-out views as ``--matte off`` does: measured on this capture (a 128x96 conifer,
8 views, 4 kept) gather's masked PSNR differs by under 0.01 dB and no pixel more is left empty.
"""

from __future__ import annotations

import numpy as np
import pytest

from capture.matting import MatteConfig
from capture.scan import Scan, ScanSet
from datasets_synthetic.lighting import LightingConfig
from datasets_synthetic.rig import TurntableRig
from datasets_synthetic.synth import SynthConfig, synthesize
from render import evaluate as ev
from volume.pipeline import build_model
from volume.pipeline.config import FuseConfig, PipelineConfig
from volume.pyramid import LoptConfig

RIG = TurntableRig(views_per_ring=8, width=128, height=96)
#: Held-out masked PSNR of the default matte against --matte off over black (dB), and holes.
BLACK_PSNR_TOL = 0.05
BLACK_HOLES_TOL = 1e-3


def _kept_without_matte(scanset):
    split = ev.holdout_split(scanset, 2, None)
    kept = ScanSet(tuple(Scan(s.rgb, s.depth, s.camera, s.name) for s in split.kept.scans), split.kept.bounds,
                   split.kept.metadata)
    return kept, split.held


def _scores(gl_ctx, kept, held, matte: str) -> dict:
    cfg = PipelineConfig(fuse=FuseConfig(lopt=LoptConfig(max_res=64, min_res=8)), matte=MatteConfig(mode=matte))
    model, summary = build_model(kept, cfg)
    res = ev.evaluate(gl_ctx, model, held, methods=("gather", "points"))
    return {"summary": summary, **res}


@pytest.mark.slow  # a synthetic capture and two model builds, ~40 s on this machine
def test_black_capture_scores_what_matte_off_scores(gl_ctx):
    cfg = SynthConfig(scene="plant", rig=RIG, supersample=2, lighting=LightingConfig(hair_model="kajiya-kay"))
    kept, held = _kept_without_matte(synthesize(cfg, gl_ctx).scanset)
    auto = _scores(gl_ctx, kept, held, "auto")
    off = _scores(gl_ctx, kept, held, "off")
    assert auto["summary"]["surroundings"]["matte"]["methods"] == {"backdrop": len(kept)}
    assert auto["summary"]["surroundings"]["plate"]["mode"] == "unused"  # the backdrop path reads no plate
    for m in ("gather", "points"):
        assert abs(auto[m]["psnr_masked"] - off[m]["psnr_masked"]) <= BLACK_PSNR_TOL, (m, auto[m], off[m])
        assert auto[m]["hole_fraction"] <= off[m]["hole_fraction"] + BLACK_HOLES_TOL
    # and the matte is not the depth mask: fringe pixels are partial
    assert auto["summary"]["surroundings"]["matte"]["partial_fraction_mean"] > 0
    assert np.isfinite(auto["gather"]["alpha_mse"])


def test_a_measured_vignette_is_taken_out_of_every_scan(caplog):
    """volume.surroundings._devignetted: where the plate stage took a vignette out of its views, every scan the
    matte and later stages read is divided by the same v (capture.vignetting.devignette_view), and the log says so."""
    from capture.camera import Camera, make_K
    from capture.vignetting import devignette_view
    from volume.pipeline.work import Context, Work
    from volume.surroundings import _devignetted

    cam = Camera(make_K(50.0, 50.0, 31.5, 23.5), np.eye(4), 64, 48)
    rng = np.random.default_rng(4)
    scans = tuple(Scan(rng.integers(10, 240, (48, 64, 3)).astype(np.uint8), np.ones((48, 64), np.float32), cam,
                       f"v{k}") for k in range(3))
    vig = {"coefficients": [-0.3, -0.05], "reason": "the corners at 0.71 of the centre"}
    out = _devignetted(Work(None, (), scans), vig, Context(None, lambda s: s))
    for s, o in zip(scans, out.scans, strict=True):
        assert np.array_equal(o.rgb, devignette_view(s, 0, vig["coefficients"])[0].rgb)
        assert o.rgb[:4, :4].mean() > s.rgb[:4, :4].mean() + 10 and np.array_equal(o.rgb[23, 31], s.rgb[23, 31])
    assert "darkens the corners" in caplog.text
