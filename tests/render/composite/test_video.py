"""render.composite.video.write_mp4: frames survive the round trip (lossy codec: stated tolerance)."""

from __future__ import annotations

import numpy as np
import pytest

from render.composite.video import write_mp4

imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
#: Mean absolute error (8-bit levels) accepted after H.264 at quality 8 on smooth test frames.
MEAN_ABS_TOL = 4.0


def frames(n, w=66, h=50):
    yy, xx = np.mgrid[0:h, 0:w]
    for i in range(n):
        img = np.zeros((h, w, 3), np.uint8)
        img[..., 0] = (xx * 255 // w + 20 * i) % 256
        img[..., 1] = yy * 255 // h
        img[..., 2] = 128
        yield img


def read_back(path):
    gen = imageio_ffmpeg.read_frames(str(path))
    meta = gen.__next__()
    w, h = meta["size"]
    return meta, [np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in gen]


def test_round_trip(tmp_path):
    p = tmp_path / "v.mp4"
    assert write_mp4(frames(12), p, fps=24) == 12
    meta, got = read_back(p)
    assert meta["fps"] == pytest.approx(24) and len(got) == 12
    for a, b in zip(frames(12), got):
        assert np.abs(a.astype(float) - b).mean() < MEAN_ABS_TOL
    # a frame sequence with a different content order is not mistaken for it (the test can fail)
    assert np.abs(next(frames(1)).astype(float) - got[6]).mean() > 4 * MEAN_ABS_TOL


def test_odd_size_padded(tmp_path):
    p = tmp_path / "odd.mp4"
    write_mp4(frames(3, w=65, h=49), p, fps=10)
    meta, got = read_back(p)
    assert meta["size"] == (66, 50)
    assert np.abs(next(frames(1, 65, 49)).astype(float) - got[0][:49, :65]).mean() < MEAN_ABS_TOL


def test_bad_input_leaves_nothing(tmp_path):
    p = tmp_path / "bad.mp4"
    with pytest.raises(ValueError, match="no frames"):
        write_mp4([], p, fps=10)
    mixed = [next(frames(1)), next(frames(1, w=40, h=30))]
    with pytest.raises(ValueError, match="frame 1 is 40x30"):
        write_mp4(mixed, p, fps=10)
    with pytest.raises(ValueError, match="uint8"):
        write_mp4([np.zeros((4, 4, 3), np.float32)], p, fps=10)
    assert list(tmp_path.iterdir()) == []
