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
    """A compute-free check that included code really executes: transform feedback of 2*x."""
    monkeypatch.setattr(rgl, "SHADER_DIR", tmp_path)
    (tmp_path / "lib.glsl").write_text("float twice(float x){return 2.0*x;}\n")
    (tmp_path / "v.glsl").write_text('#version 430\n#include "lib.glsl"\nin float x; out float y;\n'
                                     "void main(){ y = twice(x) + OFFSET; }\n")
    prog = rgl.program(gl_ctx, "v.glsl", defines={"OFFSET": "1.0"}, varyings=["y"])
    xs = np.arange(5, dtype="f4")
    vbo = gl_ctx.buffer(xs.tobytes())
    out = gl_ctx.buffer(reserve=xs.nbytes)
    vao = gl_ctx.vertex_array(prog, [(vbo, "f", "x")])
    vao.transform(out, vertices=5)
    got = np.frombuffer(out.read(), "f4")
    assert np.array_equal(got, 2 * xs + 1)
    for o in (vao, out, vbo, prog):
        o.release()
