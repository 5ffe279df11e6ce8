"""The matte stage names the views whose frame is a JPEG with subsampled chroma (volume.surroundings._for_frame,
capture.jpeg_chroma): their MatteConfig says so, every other view's is the stage's own."""

from __future__ import annotations

from types import SimpleNamespace

import cv2
import numpy as np

from capture.matting import MatteConfig
from volume.surroundings import _for_frame


def test_only_a_subsampled_jpeg_frame_is_flagged(tmp_path):
    u8 = np.random.default_rng(0).integers(0, 256, (24, 32, 3), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "a.jpg"), u8, [cv2.IMWRITE_JPEG_QUALITY, 90])
    cv2.imwrite(str(tmp_path / "b.jpg"), u8, [cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444])
    cv2.imwrite(str(tmp_path / "c.png"), u8)
    cfg = MatteConfig()

    def ref(name):
        return SimpleNamespace(rgb=tmp_path / name, where=f"frame {name}")

    assert _for_frame(cfg, ref("a.jpg")).subsampled
    assert _for_frame(cfg, ref("a")).subsampled  # a stem completed as the reader completes it
    for name in ("b.jpg", "c.png", "missing.jpg"):
        assert _for_frame(cfg, ref(name)) is cfg, name
    assert _for_frame(MatteConfig(mode="off"), ref("a.jpg")).subsampled is False
    assert _for_frame(MatteConfig(jpeg_chroma="off"), ref("a.jpg")).subsampled is False  # --jpeg-chroma off
