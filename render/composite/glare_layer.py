"""GL glare layer (docs/methods.md §4; seed 002 §3.5): streak pairs drawn as additive triangle fans.

:class:`GlareLayer` owns the GL objects (programs, the 6-vertex fan template, instance buffer,
float32 framebuffers). Each pair (``render.shading.glare_maps.Streaks``) is one instance of a
triangle fan of 4 triangles -- centre colour c, rim black, linearly interpolated -- blended with
ONE, ONE (overlaps add up). To keep the light of thin pairs right the layer is drawn at
``supersample`` x the resolution and box-averaged by a second pass (glare_down_frag.glsl).
numpy twin: ``render.shading.glare_maps.rasterize_streaks_reference``; image rows and
framebuffer rows meet only in ``capture.camera`` (``gl_row``, ``gl_rows_to_image``) and in
``framebuffer_row.glsl``.
"""

from __future__ import annotations

import time

import numpy as np

from capture.camera import gl_row, gl_rows_to_image
from capture.sampling import points_box
from render.owner import GLOwner

#: Default sub-samples per pixel side of the streak layer.
GLARE_SUPERSAMPLE = 4
#: Fan template: (a along, b across, weight): centre, then the rim closing on itself.
_FAN = np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [1, 0, 0]], np.float32)


class GlareLayer(GLOwner):
    """Draws streak pairs for a width x height image. ``render(streaks)`` -> (H, W, 3) float32
    light (top row first); ``last_ms``: GPU time of the last call (draw + average + read back)."""

    def __init__(self, ctx, width: int, height: int, supersample: int = GLARE_SUPERSAMPLE):
        from render.gl import program

        if int(width) < 1 or int(height) < 1 or not 1 <= int(supersample) <= 8:
            raise ValueError(f"GlareLayer: bad size {width}x{height} or supersample {supersample}")
        super().__init__(ctx)
        self.size = (int(width), int(height))
        self.s = int(supersample)
        self._prog = self.own(program(ctx, "glare_vert.glsl", "glare_frag.glsl"))
        self._down = self.own(program(ctx, "composite_vert.glsl", "glare_down_frag.glsl",
                                      defines={"SUPERSAMPLE": self.s}))
        self._fan = self.own(ctx.buffer(_FAN.tobytes()))
        self._inst = None
        self._vao = None
        self._cap = 0
        w, h = self.size
        self._hi = self.own(ctx.texture((w * self.s, h * self.s), 4, dtype="f4"))
        self._fbo_hi = self.own(ctx.framebuffer(color_attachments=[self._hi]))
        self._lo = self.own(ctx.texture((w, h), 4, dtype="f4"))
        self._fbo_lo = self.own(ctx.framebuffer(color_attachments=[self._lo]))
        self._vao_down = self.own(ctx.vertex_array(self._down, []))
        self.last_ms = 0.0

    def _upload(self, streaks) -> int:
        m = len(streaks)
        data = np.concatenate([streaks.centre, streaks.axis, streaks.length[:, None], streaks.width[:, None],
                               streaks.colour], 1).astype(np.float32)
        if m > self._cap:
            self.free(self._vao, self._inst)
            self._cap = max(m, 2 * self._cap, 256)
            self._inst = self.own(self.ctx.buffer(reserve=self._cap * 9 * 4))
            self._vao = self.own(self.ctx.vertex_array(self._prog, [
                (self._fan, "3f", "in_corner"),
                (self._inst, "2f 2f 1f 1f 3f/i", "in_centre", "in_axis", "in_len", "in_wid", "in_col")]))
        if m:
            self._inst.write(data.tobytes())
        return m

    def _box(self, streaks):
        """Framebuffer pixel box (x, y, w, h) at 1x covering every pair (+1 px), or None."""
        if len(streaks) == 0:
            return None
        a = np.abs(streaks.axis)
        ext = a * streaks.length[:, None] + a[:, ::-1] * streaks.width[:, None] / 2
        lo, hi = points_box(np.concatenate([streaks.centre - ext, streaks.centre + ext]))
        w, h = self.size
        u0, u1 = max(int(np.floor(lo[0])) - 1, 0), min(int(np.ceil(hi[0])) + 2, w)
        v_top, v_bottom = int(np.floor(lo[1])) - 1, int(np.ceil(hi[1])) + 1  # image rows, 1 px margin
        y0, y1 = max(gl_row(v_bottom, h), 0), min(gl_row(v_top, h) + 1, h)
        if u1 <= u0 or y1 <= y0:
            return None
        return (u0, y0, u1 - u0, y1 - y0)

    def render(self, streaks) -> np.ndarray:
        """Draw the pairs; only the box around them is cleared, drawn and averaged (scissor)."""
        import moderngl

        ctx = self.ctx
        t0 = time.perf_counter()
        w, h = self.size
        s = self.s
        m = self._upload(streaks)
        box = self._box(streaks)
        self._fbo_lo.use()
        self._fbo_lo.viewport = (0, 0, w, h)
        self._fbo_lo.scissor = None
        self._fbo_lo.clear(0.0, 0.0, 0.0, 0.0)
        if box is not None:
            hbox = tuple(v * s for v in box)
            self._fbo_hi.use()
            self._fbo_hi.viewport = (0, 0, w * s, h * s)
            self._fbo_hi.scissor = hbox
            self._fbo_hi.clear(0.0, 0.0, 0.0, 0.0, viewport=hbox)
            self._prog["u_size"].value = (float(w), float(h))
            ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ONE, moderngl.ONE
            ctx.blend_equation = moderngl.FUNC_ADD
            self._vao.render(moderngl.TRIANGLE_FAN, vertices=6, instances=m)
            ctx.disable(moderngl.BLEND)
            self._fbo_hi.scissor = None
            self._fbo_lo.use()
            self._fbo_lo.scissor = box
            self._hi.use(0)
            self._down["u_hi"].value = 0
            self._vao_down.render(moderngl.TRIANGLES, vertices=3)
            self._fbo_lo.scissor = None
        img = np.frombuffer(self._fbo_lo.read(components=4, dtype="f4"), np.float32).reshape(h, w, 4)[..., :3]
        self.last_ms = 1e3 * (time.perf_counter() - t0)
        return gl_rows_to_image(img).copy()
