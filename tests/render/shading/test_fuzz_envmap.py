"""Fuzzing the environment-map reader (hypothesis): a damaged .exr or .hdr is read or refused with
EnvMapError naming the file -- never a bare MemoryError, IndexError or an OpenEXR exception."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from render.shading.envmap import EnvMap, EnvMapError, load_envmap, save_envmap
from render.shading.rgbe import write_rgbe
from tests.fuzz import assert_own_error, damaged_bytes

FUZZ = settings(max_examples=200, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.fixture(scope="module")
def maps(tmp_path_factory) -> dict[str, bytes]:
    root = tmp_path_factory.mktemp("fuzzenv")
    rng = np.random.default_rng(0)
    env = EnvMap(rng.random((16, 32, 3)).astype(np.float32) * 4, "fuzz")
    save_envmap(env, root / "m.exr")
    write_rgbe(root / "m.hdr", env.data)
    return {ext: (root / f"m.{ext}").read_bytes() for ext in ("exr", "hdr")}


@pytest.mark.parametrize("ext", ["exr", "hdr"])
@FUZZ
@given(data=st.data())
def test_damaged_env_maps(maps, tmp_path, ext, data):
    path = tmp_path / f"damaged.{ext}"
    path.write_bytes(data.draw(damaged_bytes(maps[ext])))
    try:
        env = load_envmap(path)
    except Exception as e:  # the point: which exception escapes
        assert_own_error(e, (EnvMapError,), str(path))
        return
    assert env.data.shape[1] == 2 * env.data.shape[0] and np.all(np.isfinite(env.data))


def test_huge_hdr_header_is_refused_without_allocating(tmp_path):
    """A header promising 100000 x 200000 pixels over a few bytes of data: an error, not a 320 GB allocation."""
    p = tmp_path / "huge.hdr"
    p.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 200000\n" + b"\x00" * 64)
    with pytest.raises(EnvMapError, match="huge.hdr"):
        load_envmap(p)


def test_missing_file_is_still_a_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.hdr"):
        load_envmap(Path(tmp_path / "nope.hdr"))
