"""The pipeline's photometric stage: its own row, corrected colours, the off switch (its config None)."""

from __future__ import annotations

import contextlib

import numpy as np

from capture.photometric import PhotometricConfig
from capture.scan import ScanSet
from tests.capture.test_photometric import _scans, _views
from volume.pipeline.config import PipelineConfig
from volume.pipeline.runner import run_pipeline
from volume.pipeline.stages import stage
from volume.pipeline.work import Hooks


def _photometric(ss, cfg):
    rows = []

    def row(name):
        rows.append(name)
        return contextlib.nullcontext()

    with run_pipeline(ss, PipelineConfig(photometric=cfg, spill="never"), Hooks(row=row),
                      stages=(stage("photometric"),)) as run:
        return run.work, rows


def test_stage_corrects_colours_and_records_gains():
    views = _views(8)
    gains = np.ones((8, 3))
    gains[3] = (1.3, 1.2, 1.25)                      # one view over-exposed by ~1/3 EV
    ss = ScanSet(tuple(_scans(views, gains)), np.array([[-0.2] * 3, [0.2] * 3]), {})
    work, rows = _photometric(ss, PhotometricConfig(stride=1, reference="median"))   # the other views' level kept
    rec = work.records["photometric"]
    assert rows == ["photometric"] and len(rec["views"]) == 8 and rec["config"]["reference"] == "median"
    assert abs(rec["views"][3]["ev"] + np.log2(1.25)) < 0.02 and abs(rec["views"][0]["ev"]) < 0.01
    mean = _photometric(ss, PhotometricConfig(stride=1))[0].records["photometric"]   # the default gauge
    ev = np.array([v["ev"] for v in mean["views"]])
    assert mean["config"]["reference"] == "mean" and abs(ev.mean()) < 1e-3
    assert abs(ev[3] - ev[0] + np.log2(1.25)) < 0.02 and abs(ev[0] - np.log2(1.25) / 8) < 0.01
    ref = _scans(views)[3].linear_rgb
    m = work.scans[3].depth > 0
    assert np.abs(work.scans[3].linear_rgb - ref)[m].mean() < 0.5 * np.abs(ss.scans[3].linear_rgb - ref)[m].mean()
    off, rows = _photometric(ss, None)                # --no-photometric: the stage does not run
    assert rows == [] and "photometric" not in off.records
    assert all(a is b for a, b in zip(off.scans, ss.scans, strict=True))
    one, _ = _photometric(ScanSet(ss.scans[:1], ss.bounds, {}), PhotometricConfig())
    assert one.records["photometric"] is None
    assert PipelineConfig().photometric == PhotometricConfig()
