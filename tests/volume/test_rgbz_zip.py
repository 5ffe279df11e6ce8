"""volume.rgbz_zip and the crops deflated in the RGBz pass (volume.rgbz.CROPS_DEFLATED_IN_VIEWS) against
volume.rgbz_store.save_crops, the reference: the same members, every decoded array the same."""

from __future__ import annotations

import numpy as np
import pytest

from volume.rgbz_store import CropFile, RgbzCrop, save_crops
from volume.rgbz_zip import deflate_crop, save_deflated_crops


def _crops(n: int, seed: int = 0) -> list[RgbzCrop]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        h, w = 20 + 3 * k, 30 - 2 * k
        rgb = rng.random((h, w, 3)).astype(np.float32)
        depth = np.where(rng.random((h, w)) < 0.7, rng.uniform(0.3, 0.5, (h, w)), 0.0).astype(np.float32)
        alpha = None if k == 1 else rng.random((h, w)).astype(np.float32)  # one view without its own alpha
        measured = None if k == 2 else rng.random((h, w)) < 0.5
        out.append(RgbzCrop.encode(rgb, depth, alpha, margin=0, measured=measured))
    return out


def _arrays(path) -> dict:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


@pytest.mark.parametrize("with_alpha", [True, False])
def test_deflated_crops_equal_the_reference(tmp_path, with_alpha):
    """Crops deflated view by view and copied (save_deflated_crops) give the file save_crops writes:
    byte for byte (the zip headers zipfile writes for the reference), so the same members, each array
    equal in dtype and values; CropFile reads them alike; each view's file is removed once copied."""
    crops = _crops(4)
    save_crops(tmp_path / "ref.npz", iter(crops), with_alpha)
    parts = [deflate_crop(tmp_path / f"v{n}.zip", n, c, with_alpha) for n, c in enumerate(crops)]
    assert save_deflated_crops(tmp_path / "got.npz", parts)
    assert (tmp_path / "got.npz").read_bytes() == (tmp_path / "ref.npz").read_bytes()
    ref, got = _arrays(tmp_path / "ref.npz"), _arrays(tmp_path / "got.npz")
    assert list(got) == list(ref)  # the same members in the same order
    for k in ref:
        assert got[k].dtype == ref[k].dtype and got[k].shape == ref[k].shape, k
        np.testing.assert_array_equal(got[k], ref[k])
    a, b = CropFile(tmp_path / "ref.npz"), CropFile(tmp_path / "got.npz")
    for n in range(len(crops)):
        x, y = a.crop(n), b.crop(n)
        assert x.rect == y.rect and (x.z0, x.dz) == (y.z0, y.dz)
        for p, q in zip(x.decode(), y.decode(), strict=True):
            np.testing.assert_array_equal(p, q)
    assert not any((tmp_path / f"v{n}.zip").exists() for n in range(len(crops)))


def test_past_the_plain_zip_limits_the_reference_is_taken(tmp_path, monkeypatch):
    """Archives past the plain format's limits: save_deflated_crops writes nothing and removes no
    view's file (build_rgbz then takes save_crops)."""
    import volume.rgbz_zip as rz

    crops = _crops(2)
    parts = [deflate_crop(tmp_path / f"v{n}.zip", n, c, True) for n, c in enumerate(crops)]
    monkeypatch.setattr(rz, "ZIP_MAX_BYTES", 100)
    assert not save_deflated_crops(tmp_path / "got.npz", parts)
    assert not (tmp_path / "got.npz").exists() and all(p.file.exists() for p in parts)


def test_build_rgbz_deflated_in_views_equals_the_reference(tmp_path, monkeypatch):
    """build_rgbz with a crop file: the crops deflated in the views' pass (CROPS_DEFLATED_IN_VIEWS)
    and the reference (plain crops, deflated by save_crops) decode to the same views."""
    import volume.rgbz as rg
    from tests.scenes import make_scanset, scan_ring, sphere_scene
    from volume.build import Fused
    from volume.fusion import fuse_consensus
    from volume.grid import cube_for_bounds
    from volume.mesh import marching_cubes

    ss = make_scanset(sphere_scene(), scan_ring(5, 48, 36), noise=0.001)
    origin, extent = cube_for_bounds(ss.bounds)
    f = fuse_consensus(ss, origin, extent / 32, 32)
    level = Fused(origin, extent, {32: f}, 32).level(32)
    verts, faces = marching_cubes(level)
    import volume.rgbz_zip as rz

    out = {}
    for on in (False, True, "past the zip limits"):
        monkeypatch.setattr(rg, "CROPS_DEFLATED_IN_VIEWS", bool(on))
        if on == "past the zip limits":  # the deflated views read back and written by save_crops
            monkeypatch.setattr(rz, "fits", lambda sizes: False)
        folder = tmp_path / str(on)
        folder.mkdir()
        out[on] = rg.build_rgbz(ss, verts, faces, level, crop_file=folder / "rgbz.npz")
        assert sorted(p.name for p in folder.iterdir()) == ["rgbz.npz"]  # each view's file removed
    ref, ref_stats = out[False]
    for got, got_stats in (out[True], out["past the zip limits"]):
        assert ref_stats == got_stats
        for n in range(len(ref)):
            for x, y in zip(ref.crop(n), got.crop(n), strict=True):
                np.testing.assert_array_equal(x, y)
            np.testing.assert_array_equal(ref.measured_mask(n), got.measured_mask(n))


@pytest.mark.parametrize("spilled", [False, True])
def test_mesh_colours_in_the_views_pass_equal_the_reference(tmp_path, spilled):
    """volume.build.MESH_COLOURS_IN_VIEWS: the vertex colours summed from each view's share made in the
    RGBz pass (build_rgbz_coloured) equal vertex_colors_views over the store's decoded views (the
    reference), bit for bit, with the crops in memory or in a crop file."""
    from tests.scenes import make_scanset, scan_ring, sphere_scene
    from volume.build import Fused
    from volume.fusion import fuse_consensus
    from volume.grid import cube_for_bounds
    from volume.mesh import colour_spec, marching_cubes, vertex_colors_views
    from volume.rgbz import build_rgbz_coloured

    ss = make_scanset(sphere_scene(), scan_ring(5, 48, 36), noise=0.001)
    origin, extent = cube_for_bounds(ss.bounds)
    level = Fused(origin, extent, {32: fuse_consensus(ss, origin, extent / 32, 32)}, 32).level(32)
    verts, faces = marching_cubes(level)
    spec = colour_spec(verts, faces, level.voxel_size)
    rgbz, _, got = build_rgbz_coloured(ss, verts, faces, level, crop_file=tmp_path / "rgbz.npz" if spilled else None,
                                       colour=spec)
    ref = vertex_colors_views(verts, faces, rgbz.cameras, (rgbz.view(n)[:2] for n in range(len(rgbz))),
                              level.voxel_size)
    assert got.dtype == ref.dtype == np.float32 and len(np.unique(ref, axis=0)) > 10
    np.testing.assert_array_equal(got, ref)
