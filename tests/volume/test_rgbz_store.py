"""The compact RGBz store (volume.rgbz_store): crops around the object, 8-bit sRGB colour and
alpha, 16-bit depth over each view's range, compressed on disk, read view by view; dense
version-1 files still load."""

from __future__ import annotations

import json

import numpy as np
import pytest

from capture.scan import srgb_to_linear
from tests.volume.test_model import _cams, make_model
from volume.model import ModelError, RgbzImages, load_model, save_model
from volume.rgbz_store import DEPTH_LEVELS, CropFile, RgbzCrop, bbox


def _views(n=3, w=40, h=30, seed=0):
    """Dense views: an object (a disc of depth 0.3-0.5 m) on a black background, partial alpha."""
    rng = np.random.default_rng(seed)
    srgb = rng.integers(0, 256, (n, h, w, 3), dtype=np.uint8)
    yy, xx = np.mgrid[0:h, 0:w]
    depth = np.zeros((n, h, w), np.float32)
    alpha = np.zeros((n, h, w), np.float32)
    for i in range(n):
        disc = (xx - 12 - 4 * i) ** 2 + (yy - 14) ** 2 < 25
        depth[i][disc] = rng.uniform(0.3, 0.5, int(disc.sum()))
        alpha[i][disc] = rng.uniform(0.1, 1.0, int(disc.sum()))
    return srgb, depth, alpha


def test_bbox():
    m = np.zeros((20, 30), bool)
    assert bbox(m, 3) == (0, 0, 0, 0)
    m[5:7, 10:12] = True
    assert bbox(m, 3) == (7, 2, 8, 8)


def test_encode_decode_precision():
    srgb, depth, alpha = _views(1)
    c = RgbzCrop.encode(srgb[0], depth[0], alpha[0], margin=2)
    x0, y0, w, h = c.rect
    assert (w, h) == (13, 13) and w * h < 0.2 * depth[0].size  # the object, not the frame
    rgb, z, a = c.decode()
    sl = (slice(y0, y0 + h), slice(x0, x0 + w))
    np.testing.assert_array_equal(rgb, srgb_to_linear(srgb[0][sl] / np.float32(255)))  # 8-bit colour is exact
    has = depth[0][sl] > 0
    np.testing.assert_array_equal(z > 0, has)
    span = depth[0].max() - depth[0][depth[0] > 0].min()
    assert np.abs(z - depth[0][sl]).max() <= 0.5 * span / (DEPTH_LEVELS - 1) + 1e-7  # half a code
    assert np.abs(a - alpha[0][sl]).max() <= 0.5 / 255 + 1e-6
    # every depth pixel lies inside the crop
    assert (depth[0] > 0).sum() == has.sum()


def _compact(n=3):
    srgb, depth, alpha = _views(n)
    cams = _cams(n, 40, 30)
    return RgbzImages.from_crops(cams, [RgbzCrop.encode(srgb[i], depth[i], alpha[i]) for i in range(n)]), \
        (srgb, depth, alpha)


def test_compact_reads_like_dense():
    r, (srgb, depth, alpha) = _compact()
    assert r.compact and r.rgb.shape == (3, 30, 40, 3) and r.depth.shape == (3, 30, 40) and r.alpha.shape == depth.shape
    assert r.rgb.dtype == np.float16
    full = srgb_to_linear(srgb / np.float32(255))
    inside = np.zeros(depth.shape, bool)
    for i, (x0, y0, w, h) in enumerate(r.rects):
        inside[i, y0:y0 + h, x0:x0 + w] = True
    np.testing.assert_array_equal(r.rgb[inside], full[inside].astype(np.float16))
    assert not r.rgb[~inside].any() and not r.depth[~inside].any()
    np.testing.assert_allclose(r.depth.astype(np.float32), depth, rtol=2.0 ** -11)
    rgb1, d1, a1 = r.view(1)
    np.testing.assert_array_equal(rgb1.astype(np.float16), r.rgb[1])
    np.testing.assert_allclose(a1, alpha[1], atol=0.5 / 255 + 1e-6)


def test_compact_save_load_lazily(tmp_path):
    m = make_model()
    r, _ = _compact()
    import dataclasses

    m = dataclasses.replace(m, rgbz=r)
    out = save_model(m, tmp_path / "m")
    meta = json.loads((out / "model.json").read_text())
    assert meta["version"] == 2
    back = load_model(out)
    assert isinstance(back.rgbz._crops, CropFile) and back.rgbz._dense is None  # nothing decoded on load
    for n in range(3):
        a, b = r.encoded(n), back.rgbz.encoded(n)
        assert a.rect == b.rect and a.z0 == b.z0 and a.dz == b.dz
        np.testing.assert_array_equal(a.srgb, b.srgb)
        np.testing.assert_array_equal(a.depth, b.depth)
        np.testing.assert_array_equal(a.alpha, b.alpha)
    np.testing.assert_array_equal(back.rgbz.rgb, r.rgb)
    np.testing.assert_array_equal(back.rgbz.depth, r.depth)
    # a truncated file is named
    (out / "rgbz.npz").write_bytes((out / "rgbz.npz").read_bytes()[:200])
    with pytest.raises(ModelError, match="rgbz.npz"):
        load_model(out).rgbz.crop(0)


def test_dense_version1_still_loads(tmp_path):
    m = make_model()
    out = save_model(m, tmp_path / "m")
    assert json.loads((out / "model.json").read_text())["version"] == 1
    back = load_model(out)
    assert not back.rgbz.compact
    np.testing.assert_array_equal(back.rgbz.rgb, m.rgbz.rgb)


def test_crop_validation():
    srgb, depth, alpha = _views(1)
    c = RgbzCrop.encode(srgb[0], depth[0])
    with pytest.raises(ModelError, match="crops for"):
        RgbzImages.from_crops(_cams(2, 40, 30), [c])
    with pytest.raises(ModelError, match="outside its image"):
        RgbzImages.from_crops(_cams(1, 20, 15), [c])
    with pytest.raises(ModelError, match="uint16"):
        RgbzCrop(c.rect, c.srgb, c.depth.astype(np.int32), c.z0, c.dz)


def test_fine_level_values_stored_as_half(tmp_path):
    """Levels above VALUES_FULL_MAX_RES keep their distances as float16 on disk (read back as
    float32 within half a float16 unit); coarser levels stay exact."""
    import dataclasses

    from volume.model import VALUES_FULL_MAX_RES, SdfLevel, SdfPyramid

    rng = np.random.default_rng(3)
    L = 2 * VALUES_FULL_MAX_RES
    fine = rng.uniform(-0.3, 0.3, (L, L, L)).astype(np.float32)
    m = make_model()
    lv = m.pyramid.levels[-1]
    levels = (*m.pyramid.levels, SdfLevel(L, lv.origin, lv.extent / L, np.zeros((1, 3), np.int32), fine))
    m = dataclasses.replace(m, pyramid=SdfPyramid(levels, L))
    back = load_model(save_model(m, tmp_path / "m"))
    got = back.pyramid.level(L).values
    assert got.dtype == np.float32
    np.testing.assert_allclose(got, fine, rtol=2.0 ** -11, atol=2.0 ** -25)  # float16 subnormals near 0
    np.testing.assert_array_equal(back.pyramid.level(8).values, m.pyramid.level(8).values)


def test_measured_mask_round_trips(tmp_path):
    """The measured-depth mask (volume.rgbz.measured_depth) through a crop, its file, the compact
    store's file and a saved model, compact and dense; a store without it says None."""
    from dataclasses import replace

    from volume.rgbz_store import save_crops

    srgb, depth, alpha = _views(3)
    rng = np.random.default_rng(5)
    meas = (rng.random(depth.shape) < 0.5) & (depth > 0)
    crops = [RgbzCrop.encode(srgb[i], depth[i], alpha[i], measured=meas[i]) for i in range(3)]
    assert RgbzCrop.load(crops[0].save(tmp_path / "c.npz")).measured.tolist() == crops[0].measured.tolist()
    save_crops(tmp_path / "r.npz", crops, True)
    cams = _cams(3, 40, 30)
    for r in (RgbzImages.from_crops(cams, crops), RgbzImages.from_crops(cams, CropFile(tmp_path / "r.npz"))):
        np.testing.assert_array_equal(r.measured, meas)
    dense = RgbzImages(srgb_to_linear(srgb / np.float32(255)), depth, cams, alpha, measured=meas | (depth > 0.45))
    np.testing.assert_array_equal(dense.measured, (meas | (depth > 0.45)) & (depth > 0))
    for i, r in enumerate((RgbzImages.from_crops(cams, crops), dense)):
        m = make_model()
        m = replace(m, rgbz=r)
        save_model(m, tmp_path / f"m{i}")
        np.testing.assert_array_equal(load_model(tmp_path / f"m{i}").rgbz.measured, r.measured)
    assert RgbzImages.from_crops(cams, [RgbzCrop.encode(srgb[i], depth[i]) for i in range(3)]).measured is None
    assert RgbzImages(dense.rgb, dense.depth, cams).measured is None
    with pytest.raises(ModelError, match="measured"):
        RgbzImages(dense.rgb, dense.depth, cams, measured=meas[:2])
    with pytest.raises(ModelError, match="measured"):
        RgbzCrop(crops[0].rect, crops[0].srgb, crops[0].depth, crops[0].z0, crops[0].dz, None, crops[0].measured[1:])
