"""Headless GL context and the shader #include preprocessor."""

from __future__ import annotations

import numpy as np
import pytest

import render.gl as rgl


def test_context_is_gl45_core(gl_ctx):
    assert gl_ctx.version_code >= rgl.GL_REQUIRE


def test_missing_gl_explains(monkeypatch):
    import moderngl

    def boom(**kw):
        raise Exception("eglGetDisplay failed")

    monkeypatch.setattr(moderngl, "create_standalone_context", boom)
    with pytest.raises(rgl.GLUnavailable, match=r"apt-get install .*libegl1"):
        rgl.create_context()


def test_include_resolves_once_and_detects_cycles(tmp_path, monkeypatch):
    monkeypatch.setattr(rgl, "SHADER_DIR", tmp_path)
    (tmp_path / "a.glsl").write_text('#version 430\n#include "b.glsl"\n#include "b.glsl"\nvoid main(){}\n')
    (tmp_path / "b.glsl").write_text("float twice(float x){return 2.0*x;}\n")
    src = rgl.load_shader("a.glsl", defines={"N": 3})
    assert src.count("float twice") == 1
    assert src.splitlines()[0] == "#version 430" and src.splitlines()[1] == "#define N 3"
    (tmp_path / "c.glsl").write_text('#include "d.glsl"\n')
    (tmp_path / "d.glsl").write_text('#include "c.glsl"\n')
    with pytest.raises(ValueError, match="cycle"):
        rgl.load_shader("c.glsl")
    (tmp_path / "e.glsl").write_text('#include "missing.glsl"\n')
    with pytest.raises(FileNotFoundError, match="missing.glsl.*included from e.glsl"):
        rgl.load_shader("e.glsl")


def test_program_from_included_shader_runs(gl_ctx, tmp_path, monkeypatch):
    """Included code really executes: each point writes twice(x) + OFFSET into its own pixel.

    (Transform feedback returns zeros on this llvmpipe/EGL stack, so GPU-vs-numpy tests in
    furrow read values back through a float framebuffer instead.)"""
    import moderngl

    monkeypatch.setattr(rgl, "SHADER_DIR", tmp_path)
    (tmp_path / "lib.glsl").write_text("float twice(float x){return 2.0*x;}\n")
    (tmp_path / "v.glsl").write_text('#version 430\n#include "lib.glsl"\nin float x; out float y;\n'
                                     "void main(){ gl_Position = vec4((x + 0.5) / 5.0 * 2.0 - 1.0, 0.0, 0.0, 1.0);"
                                     " y = twice(x) + OFFSET; }\n")
    (tmp_path / "f.glsl").write_text("#version 430\nin float y; out vec4 c; void main(){ c = vec4(y); }\n")
    prog = rgl.program(gl_ctx, "v.glsl", "f.glsl", defines={"OFFSET": "1.0"})
    xs = np.arange(5, dtype="f4")
    vbo = gl_ctx.buffer(xs.tobytes())
    tex = gl_ctx.texture((5, 1), 4, dtype="f4")
    fbo = gl_ctx.framebuffer(color_attachments=[tex])
    fbo.use()
    fbo.clear()
    vao = gl_ctx.vertex_array(prog, [(vbo, "f4", "x")])
    vao.render(moderngl.POINTS)
    got = np.frombuffer(fbo.read(components=4, dtype="f4"), "f4").reshape(5, 4)[:, 0]
    assert np.array_equal(got, 2 * xs + 1)
    for o in (vao, fbo, tex, vbo, prog):
        o.release()


def test_twin_constants_come_from_python(tmp_path, monkeypatch):
    """An include listed in TWIN_CONSTANTS gets its numpy twin's constants as #defines wherever it
    is expanded (after #version when it has one); the shipped shaders use the injected names."""
    from render.shading import sg

    src = rgl.load_shader("composite_shadow_frag.glsl")
    for name, value in (("SG_COS_LAMBDA", sg.COS_LOBE_LAMBDA), ("SG_COS_MU", sg.COS_LOBE_MU),
                        ("SG_PRODUCT_AXIS_EPS", sg.PRODUCT_AXIS_EPS)):
        line = next(ln for ln in src.splitlines() if ln.startswith(f"#define {name} "))
        assert float(line.split()[2]) == value
    body = (rgl.SHADER_DIR / "shading_sg.glsl").read_text()
    assert "SG_PRODUCT_AXIS_EPS * s" in body and "1e-7" not in body
    monkeypatch.setattr(rgl, "SHADER_DIR", tmp_path)
    monkeypatch.setitem(rgl.TWIN_CONSTANTS, "t.glsl", lambda: {"K": 2})
    (tmp_path / "t.glsl").write_text("#version 430\nvoid main(){}\n")
    (tmp_path / "u.glsl").write_text('#version 430\n#include "t.glsl"\n')
    assert rgl.load_shader("t.glsl").splitlines()[:2] == ["#version 430", "#define K 2"]
    assert "#define K 2" in rgl.load_shader("u.glsl").splitlines()


def test_hair_threshold_comes_from_python():
    from render.mesh.raster.gl import HAIR_TANGENT_SQ, shaded_defines

    assert float(shaded_defines("table")["HAIR_TANGENT_SQ"]) == HAIR_TANGENT_SQ
    assert "> HAIR_TANGENT_SQ" in (rgl.shader_path("raster_shaded_frag.glsl")).read_text()
