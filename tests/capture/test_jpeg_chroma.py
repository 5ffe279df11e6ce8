"""JPEG frames with subsampled chroma (capture.jpeg_chroma): the header read against Pillow's, no allowance where
the chroma is flat, and a JPEG's halo of chroma around thin needles not read as alpha.

The needle scene (tests/plate_scenes.needle_composite) through OpenCV's JPEG at quality 90, 4:2:0, the plate the
same background through the same JPEG (a fixed camera's plate is made of such frames).  Measured (seeds 0 / 1):
background pixels within 3 px of a needle with a bound above 0: 0.85 / 0.80 without the allowance, 0.10 / 0.075
with it; bounds above the true alpha + 0.05: 12.1 % / 10.2 % of the pixels against 0.6 % / 0.4 %; the matte's
alpha MSE (object, band and halo) 0.0166 / 0.0131 against 0.0113 / 0.0114, its mean alpha on those background
pixels 0.088 / 0.071 against 0.019 / 0.015.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy import ndimage

from capture.jpeg_chroma import chroma_allowance, subsampled_chroma
from capture.matting import depth_trimap
from capture.matting_known import alpha_lower_bound, known_background_matte
from capture.scan import srgb_to_linear, to_uint8_srgb
from tests import plate_scenes as ps

NOISE = 0.004
#: Background pixels beside a needle whose bound is above 0: at most this share with the allowance, at least the
#: other without it (the case has the halo to clear).
HALO_WITH, HALO_WITHOUT = 0.25, 0.6
#: Bounds above the true alpha + 0.05 (a bound that claims more coverage than there is): at most this share.
OVER_TRUTH = 0.02
#: The matte with the allowance: alpha MSE at most this fraction of the matte without it, its mean alpha on
#: the background beside the needles at most this fraction.
MSE_RATIO, HALO_ALPHA_RATIO = 0.95, 0.5


def _jpeg_file(path: Path, u8_rgb: np.ndarray, factor=None) -> Path:
    flags = [cv2.IMWRITE_JPEG_QUALITY, 90] + ([cv2.IMWRITE_JPEG_SAMPLING_FACTOR, factor] if factor else [])
    img = u8_rgb if u8_rgb.ndim == 2 else np.ascontiguousarray(u8_rgb[..., ::-1])
    assert cv2.imwrite(str(path), img, flags)
    return path


def _jpeg(linear: np.ndarray) -> np.ndarray:
    bgr = np.ascontiguousarray(to_uint8_srgb(linear)[..., ::-1])
    ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 90])
    assert ok
    return srgb_to_linear(cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1].astype(np.float32) / 255.0)


def test_the_header_says_what_pillow_says(tmp_path):
    from PIL import Image, JpegImagePlugin

    rng = np.random.default_rng(0)
    u8 = rng.integers(0, 256, (40, 56, 3), dtype=np.uint8)
    files = {"420": _jpeg_file(tmp_path / "a.jpg", u8),
             "422": _jpeg_file(tmp_path / "b.jpg", u8, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_422),
             "444": _jpeg_file(tmp_path / "c.jpg", u8, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444),
             "grey": _jpeg_file(tmp_path / "d.jpg", u8[..., 0])}
    for name, path in files.items():
        with Image.open(path) as im:
            want = JpegImagePlugin.get_sampling(im) in (1, 2) and len(im.getbands()) == 3
        assert subsampled_chroma(path) == want, name
    assert [subsampled_chroma(files[k]) for k in ("420", "422", "444", "grey")] == [True, True, False, False]
    body = files["420"].read_bytes()
    app1 = b"\xff\xe1" + (60_002).to_bytes(2, "big") + bytes(60_000)  # a 60 kB metadata block before the frame
    (tmp_path / "h.jpg").write_bytes(body[:2] + app1 + b"\xff" + body[2:])  # and a fill byte before the next marker
    assert subsampled_chroma(tmp_path / "h.jpg")
    cv2.imwrite(str(tmp_path / "e.png"), u8)
    (tmp_path / "f.jpg").write_bytes(files["420"].read_bytes()[:40])  # cut inside the headers
    (tmp_path / "g.jpg").write_bytes(b"\xff\xd8\x00garbage")
    for name in ("e.png", "f.jpg", "g.jpg", "missing.jpg"):
        assert not subsampled_chroma(tmp_path / name), name


def test_no_allowance_where_the_chroma_is_flat():
    rng = np.random.default_rng(1)
    grey = np.repeat(rng.uniform(0.0, 1.0, (30, 40, 1)), 3, axis=2)  # luma texture, no chroma at all
    assert np.abs(chroma_allowance(grey)).max() < 1e-12
    flat = np.broadcast_to(np.array([0.2, 0.5, 0.1]), (30, 40, 3)).copy()
    assert np.abs(chroma_allowance(flat)).max() < 1e-12
    B = rng.uniform(0.0, 1.0, (30, 40, 3))
    # there the bound is alpha_lower_bound's own (its compiled pass and the numpy twin agree bit for bit)
    np.testing.assert_allclose(alpha_lower_bound(grey, B, NOISE, chroma=True), alpha_lower_bound(grey, B, NOISE),
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_jpegs_chroma_beside_the_needles_is_not_alpha(seed):
    C, B, A, F, D = ps.needle_composite(seed=seed)
    Cj, Bj = _jpeg(C), _jpeg(B)
    beside = ndimage.binary_dilation(A > 0, iterations=3) & (A == 0)
    plain, chroma = alpha_lower_bound(Cj, Bj, NOISE), alpha_lower_bound(Cj, Bj, NOISE, chroma=True)
    assert (plain[beside] > 0).mean() >= HALO_WITHOUT
    assert (chroma[beside] > 0).mean() <= HALO_WITH
    assert (chroma > A + 0.05).mean() <= OVER_TRUTH
    tri = depth_trimap(D)
    region = (A > 0) | (tri > 0) | beside
    runs = [known_background_matte(Cj, tri, Bj, np.ones(A.shape, bool), NOISE, D > 0, chroma=c)[0]
            for c in (False, True)]
    mse = [float(np.mean((a - A)[region] ** 2)) for a in runs]
    assert mse[1] <= MSE_RATIO * mse[0], mse
    assert runs[1][beside].mean() <= HALO_ALPHA_RATIO * runs[0][beside].mean()
