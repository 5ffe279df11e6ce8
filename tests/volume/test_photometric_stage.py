"""The model build's photometric stage: a timed stage, corrected colours, the off switches."""

from __future__ import annotations

import contextlib
from dataclasses import replace

import numpy as np

from capture.photometric import PhotometricConfig
from capture.scan import ScanSet
from tests.capture.test_photometric import _scans, _views
from volume.build import ModelConfig
from volume.photometric import OFF_KEY, STAGE, align_views


def test_stage_corrects_colours_and_records_gains():
    views = _views(8)
    gains = np.ones((8, 3))
    gains[3] = (1.3, 1.2, 1.25)                      # one view over-exposed by ~1/3 EV
    ss = ScanSet(tuple(_scans(views, gains)), np.array([[-0.2] * 3, [0.2] * 3]), {})
    stages = []

    def stage(name):
        stages.append(name)
        return contextlib.nullcontext()

    out, rec = align_views(ss, PhotometricConfig(stride=1), stage)
    assert stages == [STAGE] and len(rec["views"]) == 8 and rec["config"]["reference"] == "median"
    assert abs(rec["views"][3]["ev"] + np.log2(1.25)) < 0.02 and abs(rec["views"][0]["ev"]) < 0.01
    ref = _scans(views)[3].linear_rgb
    m = out.scans[3].depth > 0
    assert np.abs(out.scans[3].linear_rgb - ref)[m].mean() < 0.5 * np.abs(ss.scans[3].linear_rgb - ref)[m].mean()
    assert align_views(ss, None)[1] is None
    assert align_views(replace(ss, metadata={OFF_KEY: "off"}), PhotometricConfig())[1] is None
    assert ModelConfig().photometric == PhotometricConfig()
