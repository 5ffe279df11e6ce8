"""The ``microfacet`` method: the paper's view-dependent microfacet billboards (docs/methods.md §1.2-§1.7).

- ``spec.py``: its spec (render.methods.MethodSpec; registered as ``microfacet``) and its own options,
  :class:`render.microfacet.spec.MicrofacetOptions` (tolerance E, level, refine, mode, debug, ...);
- ``gl.py``: the GL owner :class:`render.microfacet.gl.MicrofacetRenderer`;
- ``reference.py``: the brute-force ray caster of whole frames, its slow twin;
- ``geometry.py``: the numpy twin of every shader step (slice placement, Eq. 2, 10, 11, camera selection);
- ``rgbz_textures.py``: the RGBz texels and the matte beside them (premultiplied colour + alpha when
  the model has a matte; shared with the mesh baseline);
- ``lod.py``: level of detail (Eq. 8-11); ``cull.py``: exact tile culling (twin of ``microfacet_cull.glsl``);
- ``shaders/microfacet_*.glsl``: its shaders (``microfacet_rgbz.glsl`` is also included by the mesh
  baseline: shaders are found by their unique file name, see ``render.gl``).
"""
