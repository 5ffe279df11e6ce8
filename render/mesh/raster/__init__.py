"""Triangle-mesh rasteriser (``gl.py``: :class:`render.mesh.raster.gl.MeshRasterizer`), its numpy twin
(``reference.py``) and the directional shadow maps it uses (``shadow_maps.py``)."""
