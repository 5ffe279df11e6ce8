"""MSEM video: per-frame build to disk and streaming into one 3-D texture."""

from __future__ import annotations

import numpy as np
import pytest

from render.shading.envmap import bundled_envmap
from render.shading.msem import msem_lookup
from render.shading.msem_video import MsemStream, build_msem_video
from tests.render.shading.glsl_harness import eval_glsl


@pytest.mark.gl
def test_build_and_stream(gl_ctx, tmp_path):
    env = bundled_envmap("sunset").resized(32)
    frames = [env.rotated(a) for a in (0.0, 0.7, 1.4)]
    res = build_msem_video(frames, 16, tmp_path)
    assert len(res["paths"]) == 3 and not list(tmp_path.glob(".msem*"))
    stream = MsemStream(gl_ctx, tmp_path)
    rng = np.random.default_rng(0)
    r = rng.normal(size=(300, 3)); r /= np.linalg.norm(r, axis=1, keepdims=True)
    sm = rng.uniform(0, 1, 300)
    try:
        for i in (2, 0, 1):
            tex = stream.frame(i)
            vol = np.load(res["paths"][i]).astype(np.float32)
            out = eval_glsl(gl_ctx, ["shading_msem.glsl"], "vec4(msem_radiance(u_msem, x.xyz, x.w), 1.0)",
                            np.c_[r, sm].astype(np.float32), textures={"u_msem": tex},
                            prelude="uniform sampler3D u_msem;\n")
            ref = msem_lookup(vol, r, sm)
            np.testing.assert_allclose(out[:, :3], ref, atol=np.abs(vol).max() / 256)
        # frames really differ (the map turns)
        a, b = (np.load(p) for p in res["paths"][:2])
        assert np.abs(a.astype(float) - b.astype(float)).mean() > 1e-3
    finally:
        stream.release()
    with pytest.raises(FileNotFoundError, match="no msem"):
        MsemStream(gl_ctx, tmp_path / "empty")
