"""The mesh methods: the fixed-mesh baselines ``mesh-vdtm`` and ``mesh-colour`` and the mesh rasterisers.

- ``spec.py``: their specs (render.methods.MethodSpec ``VDTM`` / ``COLOUR``, registered as ``mesh-vdtm`` /
  ``mesh-colour``; no options);
- ``gl.py``: :class:`render.mesh.gl.VdtmRenderer` and :class:`render.mesh.gl.MeshColourRenderer`;
  ``reference.py``: the numpy twin of the VDTM fragment shader;
- ``raster/``: the triangle rasteriser (colour, depth, normals; used by the synthetic ground truth and the
  colour floor) with its numpy twin;
- ``glossy/``: the glossy mesh renderer (multi-scale environment map) with its numpy twin;
- ``shaders/``: the shaders of all three (``raster_common.glsl`` is shared by raster and glossy).
"""
