"""Model bundle: validation, save/load round trip, atomic write, clear errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from capture.camera import Camera, look_at, make_K
from volume.model import Model, ModelError, RgbzImages, SdfLevel, SdfPyramid, SphereSet, load_model, save_model


def _cams(n=3, w=8, h=6):
    K = make_K(10.0, 10.0, (w - 1) / 2, (h - 1) / 2)
    return tuple(Camera(K, look_at([np.cos(a), np.sin(a), 0.2], [0, 0, 0]), w, h, f"c{i}")
                 for i, a in enumerate(np.linspace(0, 2 * np.pi, n, endpoint=False)))


def make_model(with_values=True, colors=True) -> Model:
    rng = np.random.default_rng(0)
    levels = []
    for L in (2, 4, 8):
        vals = rng.normal(size=(L, L, L)).astype(np.float32) if with_values else None
        levels.append(SdfLevel(L, np.array([-0.1, -0.1, -0.1]), 0.2 / L, rng.integers(0, L, size=(5, 3)), vals))
    cams = _cams()
    rgbz = RgbzImages(rng.random((3, 6, 8, 3), dtype=np.float32), rng.random((3, 6, 8), dtype=np.float32), cams)
    v = rng.random((4, 3), dtype=np.float32)
    return Model(SdfPyramid(tuple(levels), 8), rgbz, SphereSet(rng.random((2, 3)), [0.1, 0.2]), v,
                 np.array([[0, 1, 2], [1, 2, 3]]), v.copy() if colors else None, np.array([[-0.1] * 3, [0.1] * 3]),
                 {"max_res": 8}, {"source": "test"})


def test_round_trip_exact(tmp_path):
    m = make_model()
    out = save_model(m, tmp_path / "m")
    r = load_model(out)
    assert r.pyramid.resolutions == [2, 4, 8] and r.pyramid.l_opt == 8
    for a, b in zip(m.pyramid.levels, r.pyramid.levels):
        np.testing.assert_array_equal(a.surface, b.surface)
        np.testing.assert_array_equal(a.values, b.values)
        np.testing.assert_array_equal(a.origin, b.origin)
        assert a.voxel_size == b.voxel_size
    np.testing.assert_array_equal(m.rgbz.rgb, r.rgbz.rgb)
    np.testing.assert_array_equal(m.rgbz.depth, r.rgbz.depth)
    for a, b in zip(m.rgbz.cameras, r.rgbz.cameras):
        np.testing.assert_allclose(a.K, b.K, atol=1e-12)
        np.testing.assert_allclose(a.cam_from_world, b.cam_from_world, atol=1e-12)
        assert a.name == b.name
    np.testing.assert_array_equal(m.spheres.radii, r.spheres.radii)
    np.testing.assert_array_equal(m.mesh_faces, r.mesh_faces)
    np.testing.assert_array_equal(m.mesh_colors, r.mesh_colors)
    assert r.params == {"max_res": 8} and r.provenance == {"source": "test"}
    meta = json.loads((out / "model.json").read_text())
    assert meta["version"] == 1 and meta["units"]["length"] == "metres"


def test_round_trip_optional_parts(tmp_path):
    r = load_model(save_model(make_model(with_values=False, colors=False), tmp_path / "m"))
    assert r.mesh_colors is None and all(lv.values is None for lv in r.pyramid.levels)


def test_centers():
    lv = SdfLevel(4, np.array([1.0, 2.0, 3.0]), 0.5, np.array([[0, 0, 0], [3, 1, 2]]))
    np.testing.assert_allclose(lv.centers(), [[1.25, 2.25, 3.25], [2.75, 2.75, 4.25]])


def test_overwrite_replaces_and_leaves_no_temp(tmp_path):
    save_model(make_model(), tmp_path / "m")
    save_model(make_model(colors=False), tmp_path / "m")
    assert load_model(tmp_path / "m").mesh_colors is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m"]


def test_interrupted_save_leaves_nothing(tmp_path, monkeypatch):
    import volume.model as vm

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(vm.np, "savez", boom)
    with pytest.raises(OSError):
        save_model(make_model(), tmp_path / "m")
    assert list(tmp_path.iterdir()) == []


def test_wrong_version_and_missing_file(tmp_path):
    out = save_model(make_model(), tmp_path / "m")
    meta = json.loads((out / "model.json").read_text())
    meta["version"] = 99
    (out / "model.json").write_text(json.dumps(meta))
    with pytest.raises(ModelError, match=r"model.json.*version 99"):
        load_model(out)
    out = save_model(make_model(), tmp_path / "m2")
    (out / "rgbz.npz").unlink()
    with pytest.raises(ModelError, match=r"rgbz.npz: missing"):
        load_model(out)
    with pytest.raises(ModelError, match="no such model folder"):
        load_model(tmp_path / "nope")
    (out / "mesh.npz").write_bytes(b"garbage")
    (out / "rgbz.npz").write_bytes(b"garbage")
    with pytest.raises(ModelError, match=r"rgbz.npz: cannot read"):
        load_model(out)


def test_validation_errors():
    with pytest.raises(ModelError, match="powers of two"):
        SdfPyramid((SdfLevel(3, np.zeros(3), 1.0, np.zeros((0, 3))),), 3)
    with pytest.raises(ModelError, match="l_opt"):
        SdfPyramid((SdfLevel(4, np.zeros(3), 1.0, np.zeros((0, 3))),), 8)
    with pytest.raises(ModelError, match="different cube"):
        SdfPyramid((SdfLevel(4, np.zeros(3), 1.0, np.zeros((0, 3))),
                    SdfLevel(8, np.zeros(3), 1.0, np.zeros((0, 3)))), 8)
    with pytest.raises(ModelError, match="outside"):
        SdfLevel(4, np.zeros(3), 1.0, np.array([[0, 0, 4]]))
    with pytest.raises(ModelError, match="float32"):
        SdfLevel(2, np.zeros(3), 1.0, np.zeros((0, 3)), np.zeros((2, 2, 2)))
    with pytest.raises(ModelError, match="radii"):
        SphereSet(np.zeros((1, 3)), [0.0])
    with pytest.raises(ModelError, match="depth"):
        RgbzImages(np.zeros((3, 6, 8, 3), np.float32), np.full((3, 6, 8), np.nan, np.float32), _cams())
    m = make_model()
    with pytest.raises(ModelError, match="mesh_faces"):
        Model(m.pyramid, m.rgbz, m.spheres, m.mesh_vertices, np.array([[0, 1, 9]]), None, m.bounds)
    assert m.pyramid.levels[0].surface.flags.writeable is False
    assert len(SphereSet(np.zeros((0, 3)), np.zeros(0))) == 0


# ---------------------------------------------------------------------------- capture lighting (issue 15)
def _lighting(h=4):
    from volume.model import CaptureLighting

    rad = np.random.default_rng(1).random((h, 2 * h, 3)).astype(np.float32)
    return CaptureLighting(rad, np.array([0.0, 0.0, 1.0]), 30.0, "forest")


def test_capture_env_round_trip(tmp_path):
    import dataclasses

    m = dataclasses.replace(make_model(), capture_env=_lighting())
    out = save_model(m, tmp_path / "m")
    r = load_model(out)
    np.testing.assert_array_equal(r.capture_env.radiance, m.capture_env.radiance)
    np.testing.assert_array_equal(r.capture_env.up, [0, 0, 1])
    assert r.capture_env.rotation_deg == 30.0 and r.capture_env.source == "forest"
    meta = json.loads((out / "model.json").read_text())
    assert meta["version"] == 1 and "capture_env.npz" in meta["files"] and meta["capture_env"]["up"] == [0, 0, 1]


def test_model_without_capture_env_loads_as_before(tmp_path):
    """A model written before the capture lighting existed (no key, no file) loads with None."""
    out = save_model(make_model(), tmp_path / "m")
    meta = json.loads((out / "model.json").read_text())
    assert "capture_env" not in meta and not (out / "capture_env.npz").exists()
    assert load_model(out).capture_env is None


def test_capture_env_missing_file_is_named(tmp_path):
    import dataclasses

    out = save_model(dataclasses.replace(make_model(), capture_env=_lighting()), tmp_path / "m")
    (out / "capture_env.npz").unlink()
    with pytest.raises(ModelError, match="capture_env.npz"):
        load_model(out)


@pytest.mark.parametrize("kw, msg", [({"radiance": np.zeros((4, 4, 3), np.float32)}, "2H"),
                                     ({"radiance": np.zeros((4, 8, 3), np.float32)}, "black"),
                                     ({"radiance": -np.ones((4, 8, 3), np.float32)}, ">= 0"),
                                     ({"up": np.array([0.0, 0.0, 2.0])}, "unit")])
def test_capture_lighting_validated(kw, msg):
    from volume.model import CaptureLighting

    args = {"radiance": np.ones((4, 8, 3), np.float32), "up": np.array([0.0, 0.0, 1.0])}
    args.update(kw)
    with pytest.raises(ModelError, match=msg):
        CaptureLighting(**args)


def test_rgbz_stored_as_half_floats(tmp_path):
    """RGBz images are kept as float16 (RGBZ_STORAGE): every 8-bit sRGB value survives exactly,
    depth within half a unit of its 11-bit mantissa; float32 input (and float32 files of earlier
    models) are converted on construction."""
    from capture.scan import srgb_to_linear, to_uint8_srgb
    from volume.model import RGBZ_STORAGE

    levels = np.arange(256, dtype=np.float32)
    rgb = srgb_to_linear(np.broadcast_to(levels[:48].reshape(6, 8, 1) / 255, (6, 8, 3)))
    rgb = np.stack([rgb, srgb_to_linear(np.broadcast_to(levels[48:96].reshape(6, 8, 1) / 255, (6, 8, 3))),
                    srgb_to_linear(np.broadcast_to(levels[208:].reshape(6, 8, 1) / 255, (6, 8, 3)))])
    depth = np.random.default_rng(1).uniform(0.05, 30.0, (3, 6, 8)).astype(np.float32)
    r = RgbzImages(rgb, depth, _cams())
    assert r.rgb.dtype == RGBZ_STORAGE == np.float16 and r.depth.dtype == np.float16
    np.testing.assert_array_equal(to_uint8_srgb(r.rgb), to_uint8_srgb(rgb))
    np.testing.assert_allclose(r.depth.astype(np.float32), depth, rtol=2.0 ** -11)
    m = make_model()
    np.savez(tmp_path / "old_rgbz.npz", rgb=rgb, depth=depth)  # a float32 file as earlier models wrote
    out = save_model(m, tmp_path / "m")
    (tmp_path / "old_rgbz.npz").replace(out / "rgbz.npz")
    back = load_model(out)
    assert back.rgbz.rgb.dtype == np.float16
    np.testing.assert_array_equal(back.rgbz.depth, r.depth)
    with pytest.raises(ModelError, match="float32 or float16"):
        RgbzImages(rgb.astype(np.float64), depth, _cams())
