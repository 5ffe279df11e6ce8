"""Evaluate a GLSL expression once per input vector on the GPU (one fragment per input),
to compare GLSL twins with their numpy references."""

from __future__ import annotations

import numpy as np

from render.gl import load_shader

_VERT = """#version 430
void main() {
    vec2 p = vec2((gl_VertexID == 1) ? 3.0 : -1.0, (gl_VertexID == 2) ? 3.0 : -1.0);
    gl_Position = vec4(p, 0.0, 1.0);
}
"""

WIDTH = 256


def eval_glsl(ctx, includes: list[str], expr: str, inputs: np.ndarray, uniforms: dict | None = None,
              textures: dict | None = None, prelude: str = "", defines: dict | None = None) -> np.ndarray:
    """(N, 4) float32 results of ``expr`` (a vec4 GLSL expression of ``vec4 x``, the input row)
    for (N, k<=4) float inputs. ``includes``: shader files from render/shaders; ``uniforms``:
    name -> value; ``textures``: uniform sampler name -> moderngl texture."""
    x = np.zeros((len(inputs), 4), np.float32)
    x[:, :np.asarray(inputs).shape[1]] = inputs
    n = len(x)
    w = min(WIDTH, n)
    h = -(-n // w)
    pad = np.zeros((w * h, 4), np.float32)
    pad[:n] = x
    src = ("#version 430\n" + "".join(f"#define {k} {v}\n" for k, v in (defines or {}).items())
           + "".join(load_shader(i) for i in includes) + prelude + f"""
uniform sampler2D u_in;
out vec4 o_val;
void main() {{
    vec4 x = texelFetch(u_in, ivec2(gl_FragCoord.xy), 0);
    o_val = {expr};
}}
""")
    prog = ctx.program(vertex_shader=_VERT, fragment_shader=src)
    tin = ctx.texture((w, h), 4, pad.tobytes(), dtype="f4")
    tout = ctx.texture((w, h), 4, dtype="f4")
    fbo = ctx.framebuffer(color_attachments=[tout])
    vao = ctx.vertex_array(prog, [])
    try:
        unit = 0
        tin.use(unit)
        prog["u_in"].value = unit
        for name, tex in (textures or {}).items():
            unit += 1
            tex.use(unit)
            prog[name].value = unit
        for name, val in (uniforms or {}).items():
            prog[name].value = val
        fbo.use()
        fbo.viewport = (0, 0, w, h)
        vao.render(mode=ctx.TRIANGLES, vertices=3)
        ctx.finish()
        out = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(w * h, 4)
    finally:
        for o in (vao, fbo, tout, tin, prog):
            o.release()
    return out[:n].copy()
