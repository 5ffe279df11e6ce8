"""The ``points`` method's spec: its renderer and what it supports (render.methods); it has no options."""

from __future__ import annotations

from render.methods import MethodSpec

SPEC = MethodSpec(
    "points", "render.points.gl:PointsRenderer",
    "the plain RGB-D point splatter (4 nearest views, 2 x 2 splats, colours within 4 mm of the front averaged by "
    "1 / angle)", alpha="matte")
