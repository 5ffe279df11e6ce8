"""The ``gather`` method (the default of ``furrow render`` and ``furrow view``; docs/methods.md §1.9).

Depth per pixel from a z-buffer of the RGB-D points of the 2 kept views nearest in viewing angle,
colour gathered from those views' photographs with soft visibility.

- ``spec.py``: its spec (render.methods.MethodSpec; registered as ``gather``; no options);
- ``gl.py``: the GL owner :class:`render.gather.gl.GatherRenderer`;
- ``reference.py``: its numpy twin (float64), which the tests compare it with;
- ``shaders/gather_*.glsl``: its shaders.
"""
