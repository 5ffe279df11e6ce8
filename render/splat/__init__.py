"""The ``splat`` method: the model's 3D Gaussians (volume/splats.py, what ``furrow export --splats``
writes) drawn with the 3D Gaussian Splatting image formation (Kerbl et al. 2023; issue 33).

- ``gl.py``: the GL owner :class:`render.splat.gl.SplatRenderer` (registered as ``splat``):
  instanced screen-space quads, depth-sorted per frame, blended front to back;
- ``reference.py``: its numpy twin (float64), the same projection and blending per pixel;
- ``shaders/splat_*.glsl``: its shaders.
"""
