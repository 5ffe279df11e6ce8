"""The ``gather`` method's spec: its renderer and what it supports (render.methods); it has no options."""

from __future__ import annotations

from render.methods import MethodSpec

SPEC = MethodSpec(
    "gather", "render.gather.gl:GatherRenderer",
    "the z-buffer of the 2 nearest kept views' RGB-D points in 2 x 2 splats, colours resampled (bilinear) from "
    "those 2 views with (1 / angle) x soft visibility (the photos' own anti-aliasing is kept)",
    alpha="matte")
