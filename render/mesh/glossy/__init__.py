"""Glossy mesh renderer with per-vertex / per-texel roughness through the multi-scale environment map
(``gl.py``: :class:`render.mesh.glossy.gl.GlossyRenderer`) and its numpy twin (``reference.py``)."""
