"""The ``splat`` method's spec: its renderer and what it supports (render.methods); it has no options."""

from __future__ import annotations

from render.methods import MethodSpec

SPEC = MethodSpec(
    "splat", "render.splat.gl:SplatRenderer",
    "the model's 3D Gaussians (what `furrow export --splats` writes), drawn with the 3D Gaussian Splatting image "
    "formation: EWA projection, depth-sorted front-to-back blending (docs/splats.md)", alpha="soft")
