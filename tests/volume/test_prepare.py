"""Extent and matte stages before fusion (volume/surroundings.py): a pot on a table gives a model of the pot alone."""

from __future__ import annotations

import numpy as np
import pytest

from capture.matting import MatteConfig
from datasets_synthetic.lighting import LightingConfig
from datasets_synthetic.rig import TurntableRig
from datasets_synthetic.synth import SynthConfig, synthesize
from volume.pipeline import build_model
from volume.pipeline.config import FuseConfig, PipelineConfig
from volume.pipeline.work import Hooks
from volume.pyramid import LoptConfig

RIG = TurntableRig(views_per_ring=8, width=128, height=96)
#: Fused-model points (mesh vertices) allowed within this height above the true table top (metres):
#: the pot's own foot reaches down to it, so the check is outside the pot's footprint.
TABLE_BAND_M = 0.004


@pytest.fixture(scope="module")
def pot_on_table(gl_ctx):
    cfg = SynthConfig(scene="plant", rig=RIG, supersample=2, background="clutter", support="table",
                      lighting=LightingConfig(hair_model="kajiya-kay"))
    return synthesize(cfg, gl_ctx)


def _build(scanset, **stages):
    cfg = PipelineConfig(fuse=FuseConfig(lopt=LoptConfig(max_res=64, min_res=8)), **stages)
    names = []

    def row(name):
        import contextlib

        if name not in names:
            names.append(name)
        return contextlib.nullcontext()

    model, summary = build_model(scanset, cfg, Hooks(row=row))
    return model, summary, names


@pytest.mark.slow  # two model builds, ~40 s on this machine
def test_model_of_a_pot_on_a_table_holds_no_table(pot_on_table):
    z0 = pot_on_table.info["support"]["z0"]
    pot_r = 0.08  # the pot's radius is under 0.06 m; its foot is the only geometry allowed near the table
    model, summary, stages = _build(pot_on_table.scanset, matte=MatteConfig(mode="estimate"))
    assert stages[stages.index("extent"):][:5] == ["extent", "background plate", "matte warm-up", "matte",
                                                   "photometric"]
    ex = summary["surroundings"]["extent"]
    assert ex["plane"] is not None and ex["removed_fraction"]["support"] > 0.3
    v = model.mesh_vertices
    near_table = v[:, 2] < z0 + TABLE_BAND_M
    assert not np.any(near_table & (np.hypot(v[:, 0], v[:, 1]) > pot_r))
    assert np.ptp(v[:, 0]) < 0.25  # the table top is 1.2 m wide
    # the matte and the foreground colour are stored per kept view
    assert model.rgbz.alpha is not None and model.rgbz.alpha.shape == model.rgbz.depth.shape
    assert summary["surroundings"]["matte"]["methods"] == {"estimate": 8}
    # without the extent stage the table is modelled too
    raw, raw_summary, _ = _build(pot_on_table.scanset, extent=None, matte=MatteConfig(mode="off"))
    assert np.ptp(raw.mesh_vertices[:, 0]) > 0.5
    assert raw.rgbz.alpha is None
    assert raw_summary["l_opt"] >= summary["l_opt"]
