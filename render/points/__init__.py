"""The ``points`` method: the plain RGB-D point splatter, the baseline of every evaluation (issue 11).

- ``gl.py``: the owner :class:`render.points.gl.PointsRenderer` (registered as ``points``);
- ``reference.py``: the splatter in vectorised numpy (the algorithm; ``gl.py`` and gather reuse it).
"""
