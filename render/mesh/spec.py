"""The specs of the two mesh baselines, ``mesh-vdtm`` and ``mesh-colour`` (render.methods); neither has options."""

from __future__ import annotations

from render.methods import MethodSpec

VDTM = MethodSpec(
    "mesh-vdtm", "render.mesh.gl:VdtmRenderer",
    "the fixed-mesh baseline: the model's mesh textured from the input views with the microfacets' camera "
    "selection and blending (they differ only in geometry)", supersample=True, alpha="matte")
COLOUR = MethodSpec(
    "mesh-colour", "render.mesh.gl:MeshColourRenderer",
    "the floor: the model's mesh with its per-vertex colours", supersample=True, alpha="coverage", sheet=False)
