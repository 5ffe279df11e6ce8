"""The ``points`` method: the plain RGB-D point splatter, the baseline of every evaluation (issue 11).

- ``spec.py``: its spec (render.methods.MethodSpec; registered as ``points``; no options);
- ``gl.py``: the owner :class:`render.points.gl.PointsRenderer`;
- ``reference.py``: the splatter in vectorised numpy (the algorithm; ``gl.py`` and gather reuse it).
"""
