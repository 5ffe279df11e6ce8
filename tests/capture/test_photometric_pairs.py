"""The photometric pairs' usable samples (capture.photometric_pairs.usable) on the box of the depth's pixels
against the whole frame (the reference): the same mask, bit for bit, whatever the object's place."""

from __future__ import annotations

import numpy as np
import pytest

from capture.photometric import PhotometricConfig
from capture.photometric_pairs import usable
from capture.scan import Scan
from tests import scenes


@pytest.mark.parametrize("where", ["middle", "corner", "edges", "none"])
@pytest.mark.parametrize("with_alpha", [False, True])
def test_usable_on_the_depths_box_is_the_whole_frames(where, with_alpha):
    rng = np.random.default_rng(7)
    H, W = 60, 80
    cam = scenes.ring_cameras(1, W, H)[0]
    d = np.zeros((H, W), np.float32)
    box = {"middle": (slice(20, 40), slice(25, 55)), "corner": (slice(0, 15), slice(60, 80)),
           "edges": (slice(0, 60), slice(0, 80)), "none": (slice(0, 0), slice(0, 0))}[where]
    d[box] = rng.uniform(0.5, 0.6, d[box].shape) * (rng.random(d[box].shape) > 0.1)  # holes and depth edges
    d[box][::7] *= 1.2
    rgb = rng.random((H, W, 3)).astype(np.float32)
    alpha = np.clip(rng.uniform(0.9, 1.2, (H, W)), 0, 1).astype(np.float32) if with_alpha else None
    s = Scan(rgb, d, cam, "v", alpha)
    cfg = PhotometricConfig()
    lin_ref, ok_ref = usable(s, cfg, boxed=False)
    lin, ok = usable(s, cfg, boxed=True)
    assert where == "none" or (ok_ref.any() and (~ok_ref & (d > 0)).any())  # both outcomes on the depth
    np.testing.assert_array_equal(ok, ok_ref)
    np.testing.assert_array_equal(lin, lin_ref)
