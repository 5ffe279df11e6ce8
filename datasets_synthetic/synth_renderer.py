"""The two synthetic renderers behind one interface (``SynthConfig.renderer``, ``furrow synth
--synth-renderer``):

* ``gl`` (default): strands as ribbons, the hair lobes, shadow-map lookups and visibility culling
  on the GPU (``datasets_synthetic.strand_gl.StrandRasterizer``);
* ``numpy``: the reference, every strand a tube of triangles in the mesh rasteriser and the hair
  lobes evaluated in numpy per strand point and view (``datasets_synthetic.hair_shading``).

Both give a ``render.mesh.raster.gl.RasterResult`` per camera (colour, depth, normals, coverage);
tests/datasets_synthetic/test_strand_gl.py holds them to stated tolerances of each other.
"""

from __future__ import annotations

from datasets_synthetic.camera_traits import render_through_lens
from datasets_synthetic.hair_shading import prepare_hair, vertex_emission
from render.mesh.raster.gl import Lighting, MeshRasterizer, RasterMesh
from render.shading.envmap import EnvMap

#: Renderer names (the first is the default).
RENDERERS = ("gl", "numpy")


class SceneRenderer:
    """Owns the renderer of one scene under one lighting (a GL resource owner: ``with`` it or
    call :meth:`release`).  ``lc`` is a ``datasets_synthetic.lighting.LightingConfig`` (hair model,
    median-cut lights, shadows)."""

    def __init__(self, ctx, kind: str, supersample: int, mesh: RasterMesh, lighting: Lighting,
                 residual: EnvMap, lc) -> None:
        if kind not in RENDERERS:
            raise ValueError(f"synthetic renderer must be one of {', '.join(RENDERERS)}, got {kind!r}")
        self.kind = kind
        self._hair = None
        if kind == "gl":
            from datasets_synthetic.strand_gl import StrandRasterizer

            self.rast = StrandRasterizer(ctx, supersample=supersample)
            try:
                info = self.rast.set_scene(mesh, lighting, residual, lc.hair_model, lc.hair_env_lights, lc.shadows)
            except Exception:
                self.rast.release()
                raise
            self.hair_info = info
        else:
            self.rast = MeshRasterizer(ctx, supersample=supersample)
            try:
                self._hair = prepare_hair(self.rast, mesh, lighting, residual, lc.hair_model, lc.hair_env_lights,
                                          lc.shadows)
            except Exception:
                self.rast.release()
                raise
            self.hair_info = {**(self._hair.info() if self._hair is not None else {"model": "kajiya-kay"}),
                              "renderer": "numpy"}
        self.shadow_info = dict(self.rast.shadow_info)

    def render(self, cam, lens=None):
        """RasterResult of ``cam`` (through ``lens``, a ``capture.lens.Lens``, when given)."""
        if self._hair is not None:
            self.rast.set_emission(vertex_emission(self._hair, cam.center))
        return self.rast.render(cam) if lens is None else render_through_lens(self.rast, cam, lens)

    def release(self) -> None:
        self.rast.release()

    def __enter__(self) -> SceneRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.release()
