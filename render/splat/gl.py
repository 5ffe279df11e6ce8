"""The ``splat`` rendering method on the GPU: the model's 3D Gaussians drawn as instanced
screen-space quads with the reference's EWA projection (the formulas and the numpy twin:
``render/splat/reference.py``).

The Gaussians are built from the model on load (volume.splats.build_splats, the same function
and defaults as ``furrow export --splats``, so what is scored is what is exported) and uploaded
once as a shader storage buffer (:func:`pack`).  Per frame the CPU sorts the Gaussians by the
z-depth of their centres (numpy, ties by index, the twin's order) and uploads only that order;
``splat_vert.glsl`` projects each Gaussian (covariance, colour from its spherical harmonics, the
ellipse where its alpha reaches ALPHA_MIN) and ``splat_frag.glsl`` writes its premultiplied alpha
per pixel, blended front to back (source factor 1 - destination alpha, destination factor 1)
into two float32 targets: (display colour x alpha, alpha) and (z x alpha, alpha).  The frame is
read back and converted as the twin converts it (reference.to_frame).  One sample per pixel
whatever ``RenderOptions.supersample`` says: the EWA low pass is the anti-aliasing.
"""

from __future__ import annotations

import numpy as np

from capture.camera import Camera, gl_rows_to_image
from render.frame import Frame, FrameStats
from render.gl import program, set_uniform
from render.methods import Renderer, RenderOptions
from render.owner import FrameTimer
from render.splat import reference as sr
from volume import splat_sh

#: Extra half-size (pixels) of each quad beyond the ellipse: pixels at its rim are then always
#: rasterised and the fragment's alpha test alone decides, as in the twin.
QUAD_MARGIN_PX = 1.0
#: vec4 ahead of the SH coefficients in a Gaussian's record: position + opacity, covariance (2).
HEADER_VEC4 = 3


def stride_vec4(k: int) -> int:
    """vec4 per Gaussian record with ``k`` SH coefficients per channel."""
    return HEADER_VEC4 + (3 * k + 3) // 4


def pack(splats) -> np.ndarray:
    """(N, stride_vec4(K) * 4) float32 records of the shader storage buffer: x y z opacity |
    c00 c01 c02 c11 | c12 c22 0 0 | SH floats (coefficient k, channel c at 3 k + c), zero padded."""
    n, k = len(splats), splats.sh.shape[1]
    out = np.zeros((n, 4 * stride_vec4(k)), np.float32)
    out[:, :3] = splats.positions
    out[:, 3] = splats.opacities
    c = splats.covariances()
    out[:, 4:10] = np.stack([c[:, 0, 0], c[:, 0, 1], c[:, 0, 2], c[:, 1, 1], c[:, 1, 2], c[:, 2, 2]], 1)
    out[:, 12:12 + 3 * k] = splats.sh.reshape(n, 3 * k)
    return out


def shader_defines(k: int) -> dict:
    """Constants of the splat shaders, one source with the numpy twin."""
    d = {"STRIDE": stride_vec4(k), "SH_K": k, "LOW_PASS": f"{sr.LOW_PASS_PX2:.9e}",
         "JACOBIAN_CLAMP": f"{sr.JACOBIAN_CLAMP:.9e}", "ALPHA_MIN": f"{sr.ALPHA_MIN:.9e}",
         "ALPHA_MAX": f"{sr.ALPHA_MAX:.9e}", "NEAR_M": f"{sr.NEAR_M:.9e}", "QUAD_MARGIN_PX": f"{QUAD_MARGIN_PX:.9e}",
         "SH_C0": f"{splat_sh.SH_C0:.17e}", "SH_C1": f"{splat_sh.SH_C1:.17e}"}
    d.update({f"SH_C2_{i}": f"{c:.17e}" for i, c in enumerate(splat_sh.SH_C2)})
    d.update({f"SH_C3_{i}": f"{c:.17e}" for i, c in enumerate(splat_sh.SH_C3)})
    return d


def draw_order(positions: np.ndarray, opacities: np.ndarray, eye: Camera) -> np.ndarray:
    """(P,) uint32 indices of the Gaussians drawn by ``eye`` (z > NEAR_M, opacity >= ALPHA_MIN),
    front to back by the z of their centres, ties by index (the twin's order)."""
    R, t = eye.cam_from_world[:3, :3], eye.cam_from_world[:3, 3]
    z = np.asarray(positions, np.float64) @ R[2] + t[2]
    keep = np.nonzero((z > sr.NEAR_M) & (np.asarray(opacities) >= sr.ALPHA_MIN))[0]
    return keep[np.argsort(z[keep], kind="stable")].astype(np.uint32)


class SplatRenderer(Renderer):
    """Owns the Gaussians' storage buffer and the splat program for one splat set.

    Args:
        ctx: moderngl context.
        splats: the Gaussians (volume.splats.Splats).
        options: default per-frame options (none is read).
    """

    name = "splat"

    def __init__(self, ctx, splats, options: RenderOptions | None = None):
        super().__init__(ctx, options)
        if not len(splats):
            raise ValueError("splat renderer: no Gaussian to draw")
        self.splats = splats
        k = splats.sh.shape[1]
        records = pack(splats)
        limit = int(ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE", records.nbytes))
        if records.nbytes > limit:
            raise ValueError(f"splat renderer: {len(splats)} Gaussians need {records.nbytes} bytes, more than the "
                             f"GL storage block limit {limit}")
        self.data = self.own(ctx.buffer(records.tobytes()))
        self.order = self.own(ctx.buffer(reserve=4 * len(splats)))
        self.prog = self.own(program(ctx, "splat_vert.glsl", "splat_frag.glsl", defines=shader_defines(k)))
        self.vao = self.own(ctx.vertex_array(self.prog, []))
        self.uploaded_bytes = records.nbytes

    @classmethod
    def from_model(cls, ctx, model, options: RenderOptions | None = None) -> SplatRenderer:
        """The Gaussians of a volume.model.Model built from its kept views (volume.splats.build_splats,
        default config: what ``furrow export --splats`` writes)."""
        from volume.splats import build_splats

        return cls(ctx, build_splats(model), options)

    def _draw(self, eye: Camera, order: np.ndarray):
        ctx = self.ctx
        tgt = self.target(eye.width, eye.height, colours=(4, 4), depth=False)
        tgt.fbo.use()
        ctx.viewport = (0, 0, eye.width, eye.height)
        tgt.fbo.clear(0.0, 0.0, 0.0, 0.0)
        if not len(order):
            return tgt
        self.order.write(order.tobytes())
        p = self.prog
        p["rot"].write(np.ascontiguousarray(eye.cam_from_world[:3, :3].T, np.float32).tobytes())
        p["trans"].value = tuple(float(x) for x in eye.cam_from_world[:3, 3])
        p["intr"].value = (eye.K[0, 0], eye.K[1, 1], eye.K[0, 2], eye.K[1, 2])
        p["skew"].value = float(eye.K[0, 1])
        p["size"].value = (float(eye.width), float(eye.height))
        set_uniform(p, "eye_center", tuple(float(x) for x in eye.center))  # unused at degree 0
        p["height"].value = eye.height
        self.data.bind_to_storage_buffer(0)
        self.order.bind_to_storage_buffer(1)
        ctx.enable_only(ctx.BLEND)
        ctx.blend_func = ctx.ONE_MINUS_DST_ALPHA, ctx.ONE
        self.vao.render(ctx.TRIANGLE_STRIP, vertices=4, instances=len(order))
        # the context may be shared (tests, the viewer): leave its state as found
        ctx.blend_func = ctx.SRC_ALPHA, ctx.ONE_MINUS_SRC_ALPHA
        ctx.disable(ctx.BLEND)
        return tgt

    def _render(self, eye: Camera, options: RenderOptions, read: bool) -> Frame:
        with FrameTimer(self.ctx) as t:
            order = draw_order(self.splats.positions, self.splats.opacities, eye)
            tgt = self._draw(eye, order)
        stats = FrameStats(t.ms, t.cpu_ms, supersample=1, facets=len(order))
        if not read:
            return Frame.empty(eye.width, eye.height, stats)
        c = gl_rows_to_image(tgt.read_colour(0))
        d = gl_rows_to_image(tgt.read_colour(1))
        return Frame(*sr.to_frame(c[..., :3], c[..., 3], d[..., 0]), stats)


def drawn_alphas(ctx, splats, cameras):
    """The alpha (H, W) of ``splats`` drawn by each of ``cameras`` (a generator; one upload): what
    volume.splat_refine.refine_opacities asks its ``draw`` for."""
    with SplatRenderer(ctx, splats) as r:
        for cam in cameras:
            yield r.render(cam).alpha
