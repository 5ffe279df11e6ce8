"""EnvMap: the direction <-> pixel mapping, solid angles, sampling, rotation, resizing, I/O."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading.envmap import (
    BUNDLED_NAMES,
    EnvMap,
    bundled_envmap,
    dir_to_uv,
    load_envmap,
    pixel_solid_angles,
    procedural_sky,
    save_envmap,
    uv_to_dir,
)


def _rand_dirs(n, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_dir_uv_round_trip():
    d = _rand_dirs(10000)
    uv = dir_to_uv(d)
    assert np.all((uv[:, 0] >= 0) & (uv[:, 0] < 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= 1))
    np.testing.assert_allclose(uv_to_dir(uv), d, atol=1e-12)
    uv2 = np.random.default_rng(1).uniform([0, 0.001], [1, 0.999], size=(1000, 2))
    np.testing.assert_allclose(dir_to_uv(uv_to_dir(uv2)), uv2, atol=1e-12)


def test_mapping_convention_landmarks():
    # documented: v=0 is +z, u=0.5 is +x, u=0.25 is +y, u=0.75 is -y
    np.testing.assert_allclose(dir_to_uv([0, 0, 1])[1], 0.0, atol=1e-15)
    np.testing.assert_allclose(dir_to_uv([0, 0, -1])[1], 1.0, atol=1e-15)
    np.testing.assert_allclose(dir_to_uv([[1, 0, 0], [0, 1, 0], [0, -1, 0]]),
                               [[0.5, 0.5], [0.25, 0.5], [0.75, 0.5]], atol=1e-15)
    # top row of a map is the sky: pixel_directions row 0 points up
    d = EnvMap(np.zeros((8, 16, 3), np.float32)).pixel_directions()
    assert np.all(d[0, :, 2] > 0.9) and np.all(d[-1, :, 2] < -0.9)


@pytest.mark.parametrize("h", [1, 3, 64, 512])
def test_solid_angles_sum_to_4pi(h):
    s = pixel_solid_angles(h)
    assert s.shape == (h, 2 * h)
    np.testing.assert_allclose(s.sum(), 4 * np.pi, rtol=1e-12)
    # compare with the numeric integral of sin(theta) over each row (independent route)
    from scipy.integrate import quad

    rows = [0, h // 2, h - 1]
    num = [quad(np.sin, np.pi * i / h, np.pi * (i + 1) / h, epsabs=0, epsrel=1e-13)[0] * np.pi / h
           for i in rows]
    np.testing.assert_allclose(s[rows, 0], num, rtol=1e-10)


def test_sample_exact_at_pixel_centres_and_wraps():
    rng = np.random.default_rng(2)
    env = EnvMap(rng.uniform(0, 5, (16, 32, 3)).astype(np.float32))
    np.testing.assert_allclose(env.sample(env.pixel_directions()), env.data, rtol=1e-6)
    # halfway between the last and the first column (the seam at u = 0): mean of both
    v = (5 + 0.5) / 16
    d = uv_to_dir(np.array([0.0, v]))
    np.testing.assert_allclose(env.sample(d), 0.5 * (env.data[5, 0] + env.data[5, -1]), rtol=1e-6)


def test_rotation():
    rng = np.random.default_rng(3)
    env = EnvMap(rng.uniform(0, 1, (16, 32, 3)).astype(np.float32))
    for a in [2 * np.pi * 5 / 32, -2 * np.pi * 3 / 32]:  # whole columns: exact
        r = env.rotated(a)
        d = env.pixel_directions()
        c, s = np.cos(a), np.sin(a)
        rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        np.testing.assert_allclose(r.sample(d @ rz.T), env.data, atol=1e-6)
    # a smooth map rotated by a fraction of a column stays close
    d = env.pixel_directions()
    smooth = EnvMap((1.5 + d[..., :1] * np.array([1.0, 0.5, 0.2]) + d[..., 1:2] * 0.3).astype(np.float32))
    a = 0.3
    c, s = np.cos(a), np.sin(a)
    rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    np.testing.assert_allclose(smooth.rotated(a).sample(d @ rz.T), smooth.data, atol=0.02)
    np.testing.assert_allclose(env.rotated(a).total_power(), env.total_power(), rtol=1e-6)


@pytest.mark.parametrize("h", [16, 24, 48, 100])
def test_resized_preserves_power(h):
    env = bundled_envmap("sunset").resized(64)
    r = env.resized(h)
    assert r.data.shape == (h, 2 * h, 3)
    np.testing.assert_allclose(r.total_power(), env.total_power(), rtol=1e-5)


def test_resized_integer_factor_is_solid_angle_weighted_box():
    rng = np.random.default_rng(4)
    env = EnvMap(rng.uniform(0, 1, (8, 16, 3)).astype(np.float32))
    r = env.resized(4)
    om = env.pixel_solid_angles()
    ref = np.einsum("hwc,hw->hwc", env.data.astype(np.float64), om).reshape(4, 2, 8, 2, 3).sum((1, 3))
    ref /= om.reshape(4, 2, 8, 2).sum((1, 3))[..., None]
    np.testing.assert_allclose(r.data, ref, rtol=1e-5)


def test_exr_round_trip(tmp_path):
    rng = np.random.default_rng(5)
    data = (rng.lognormal(0, 3, (8, 16, 3))).astype(np.float32)
    data[0, 0] = 1e5
    data[1, 1] = 1e-3
    p = save_envmap(EnvMap(data, "x"), tmp_path / "sub" / "x.exr")
    back = load_envmap(p)
    np.testing.assert_array_equal(back.data, data)
    assert back.name == "x"
    assert not list((tmp_path / "sub").glob("*.tmp*"))


def test_hdr_reader(tmp_path):
    from render.shading.rgbe import write_rgbe

    # hand-made flat file: pixel (m=128,64,32, e=129) = (128.5, 64.5, 32.5) * 2^(129-136)
    p = tmp_path / "flat.hdr"
    hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n"
    p.write_bytes(hdr + bytes([128, 64, 32, 129, 0, 0, 0, 0]))
    from render.shading.rgbe import read_rgbe
    np.testing.assert_allclose(read_rgbe(p), [[[128.5 / 128, 64.5 / 128, 32.5 / 128], [0, 0, 0]]])
    # RLE written file (runs and literals) of a real map reads back within RGBE precision
    env = bundled_envmap("studio").resized(32)
    q = write_rgbe(tmp_path / "studio.hdr", env.data)
    back = load_envmap(q)
    err = np.abs(back.data - env.data) / np.maximum(env.data.max(-1, keepdims=True), 1e-6)
    assert err.max() < 1.0 / 128, err.max()


def test_load_errors_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.exr"):
        load_envmap(tmp_path / "nope.exr")
    bad = tmp_path / "bad.hdr"
    bad.write_bytes(b"not an hdr\n")
    with pytest.raises(ValueError, match="bad.hdr"):
        load_envmap(bad)
    junk = tmp_path / "junk.exr"
    junk.write_bytes(b"\x00" * 100)
    with pytest.raises(ValueError, match="junk.exr"):
        load_envmap(junk)
    sq = tmp_path / "square.exr"
    import OpenEXR
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                      {"RGB": np.ones((4, 4, 3), np.float32)}) as f:
        f.write(str(sq))
    with pytest.raises(ValueError, match="square.exr.*2:1"):
        load_envmap(sq)
    with pytest.raises(ValueError):
        EnvMap(np.ones((4, 4, 3), np.float32))
    with pytest.raises(ValueError):
        EnvMap(np.full((4, 8, 3), np.nan, np.float32))


def test_bundled_and_procedural():
    for name in BUNDLED_NAMES:
        e = bundled_envmap(name)
        assert e.data.shape == (512, 1024, 3) and e.name == name
        assert float(e.data.min()) >= 0
    with pytest.raises(FileNotFoundError, match="nonexistent"):
        bundled_envmap("nonexistent")
    sky = procedural_sky(32)
    assert sky.data.shape == (32, 64, 3)
    d = sky.pixel_directions()
    up = sky.data[d[..., 2] > 0.3].mean(0)
    down = sky.data[d[..., 2] < -0.3].mean(0)
    assert up[2] > down[2]  # blue sky above the ground
    from render.shading.envmap import SUN_DIR
    assert np.argmax(sky.sample(SUN_DIR)) == 0 and sky.sample(SUN_DIR).max() > 50
