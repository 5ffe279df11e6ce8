"""The relighting pass that follows any method's frame (issue 15; docs/relight.md).

- ``gl.py``: the GL owner :class:`render.relight.gl.Relighter`;
- ``reference.py``: its numpy twin;
- ``shaders/relight_*.glsl``; the environment maths (transfer tables) are in ``render.shading.transfer``.
"""
