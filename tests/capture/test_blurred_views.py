"""capture.blurred_views: frames blurred where the others are sharp, found by the fixed camera's plate (the turntable
scene of tests/plate_scenes.py, its room textured); the kernel fit against a kernel put in."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from capture.blurred_views import BLURRED, fit_kernel, window_offsets
from capture.plate import PlateConfig, background_plates
from tests import plate_scenes as ps

BLURRED_IDS = (2, 7)


def _blur(img: np.ndarray, n: int = 5) -> np.ndarray:
    import cv2

    k = np.zeros((n, n), np.float32)
    k[n // 2] = 1.0 / n  # a horizontal line: a camera shaken sideways
    return cv2.filter2D(np.asarray(img, np.float32), -1, k, borderType=cv2.BORDER_REFLECT)


def test_fit_kernel_finds_the_kernel_put_in():
    """photo = k * plate (a 5x5 kernel, noise 1e-4): the kernel back within 0.01 a tap, the held-back RMS a fraction
    of the plate's own; photo = plate + noise: no gain (the ratio above BLURRED)."""
    import cv2

    rng = np.random.default_rng(1)
    plate = rng.random((80, 96, 3)).astype(np.float32)  # white: every tap told apart
    k = np.abs(rng.normal(size=(5, 5))).astype(np.float32)
    k /= k.sum()
    photo = cv2.filter2D(plate, -1, k, borderType=cv2.BORDER_REFLECT) + rng.normal(0, 1e-4, plate.shape)
    ys, xs = np.mgrid[4:76, 4:92]
    fit = fit_kernel(photo, plate, ys.ravel(), xs.ravel(), 2)
    assert np.abs(fit["kernel"] - k).max() < 0.01 and fit["rms_blurred"] < 0.1 * fit["rms_plate"], fit
    same = fit_kernel(plate + rng.normal(0, 1e-3, plate.shape), plate, ys.ravel(), xs.ravel(), 2)
    assert same["rms_blurred"] > BLURRED * same["rms_plate"], same
    dy, dx = window_offsets(1)
    assert list(zip(dy, dx))[:3] == [(-1, -1), (-1, 0), (-1, 1)] and len(dy) == 9


@pytest.mark.parametrize("gains", [None, "auto exposure"])
def test_blurred_frames_of_a_turntable_are_found(gains):
    g = None if gains is None else np.exp(np.random.default_rng(3).normal(0.0, 0.2, (12, 3)))
    views, _, _, _ = ps.turntable_capture(width=192, height=144, gains=g)
    views = [replace(v, linear=_blur(v.linear)) if i in BLURRED_IDS else v for i, v in enumerate(views)]
    _, rec = background_plates(views, PlateConfig())
    assert rec["mode"] == "fixed"
    found = [i for i, r in enumerate(rec["per_view"]) if r["blur"].get("blurred")]
    assert found == list(BLURRED_IDS), [r["blur"] for r in rec["per_view"]]
    ratios = [r["blur"]["ratio"] for i, r in enumerate(rec["per_view"]) if i not in BLURRED_IDS]
    assert min(ratios) > BLURRED, ratios


def test_a_sharp_turntable_has_no_blurred_frame():
    views, _, _, _ = ps.turntable_capture(width=192, height=144)
    _, rec = background_plates(views, PlateConfig())
    assert not any(r["blur"].get("blurred") for r in rec["per_view"]), [r["blur"] for r in rec["per_view"]]

