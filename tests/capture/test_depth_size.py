"""write_transforms(depth_size=...) writes phone-like coarse depth that the reader resamples to the colour."""

from __future__ import annotations

import numpy as np
import pytest

from capture.imageio import read_depth_raw
from capture.io import ScanIOError, read_scanset, write_transforms
from tests.scenes import make_scanset, scan_ring, sphere_scene


def test_depth_written_small_and_read_back_at_colour_size(tmp_path):
    ss = make_scanset(sphere_scene(), scan_ring(4, 64, 48))
    tj = write_transforms(ss, tmp_path / "s", depth_size=(16, 12))
    raw = read_depth_raw(sorted((tmp_path / "s" / "depth").iterdir())[0])
    assert raw.shape == (12, 16)
    back = read_scanset(tj)
    d = back.scans[0].depth
    assert d.shape == (48, 64)
    both = (d > 0) & (ss.scans[0].depth > 0)
    assert both.sum() > 0.5 * (ss.scans[0].depth > 0).sum()
    assert np.median(np.abs(d[both] - ss.scans[0].depth[both])) < 0.005  # metres, 4x coarser depth
    with pytest.raises(ScanIOError, match="depth size"):
        write_transforms(ss, tmp_path / "t", depth_size=(128, 96))
