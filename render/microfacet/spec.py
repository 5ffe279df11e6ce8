"""The ``microfacet`` method's spec: its renderer, its own options and what it supports (render.methods)."""

from __future__ import annotations

from dataclasses import dataclass

from render.methods import Control, MethodSpec, option
from render.microfacet.geometry import DEBUG_OUTPUTS, DEPTH_REFINE
from render.microfacet.lod import DEFAULT_TOLERANCE_PX

#: Slice generation paths (render.microfacet.gl): compute + instancing, or a geometry shader.
MODES = ("instanced", "geometry")
#: Most parallax-correction steps accepted (render quality saturates after 2: furrow/bench/render.py).
MAX_REFINE = 4
#: Viewer range of the tolerance E (pixels): low, high, step.
TOLERANCE_RANGE = (0.5, 32.0, 0.5)


@dataclass(frozen=True)
class MicrofacetOptions:
    """Per-frame knobs of the microfacet renderer (validated on creation)."""

    #: Screen-space tolerance E in output pixels (docs/methods.md §1.7, Eq. 10-11).
    tolerance_px: float = option(
        DEFAULT_TOLERANCE_PX, "screen-space tolerance E in output pixels: picks the pyramid level and slice spacing "
        "(Eq. 10-11)", flag="--tolerance", metavar="E",
        control=Control("slider", "tolerance E (px)", *TOLERANCE_RANGE,
                        hint="screen-space tolerance: picks the pyramid level and slice spacing (Eq. 10-11)"))
    #: Pyramid level forced by its resolution L; None = Eq. 11 picks it.
    level: int | None = option(None, "force the pyramid level of resolution L (e.g. 64) instead of Eq. 11; the spacing "
                               "then follows Eq. 10 on it", flag="--level", type=int, metavar="L")
    #: Parallax-correction steps along the eye ray (None = DEPTH_REFINE, 0 = the paper's colour at the slice point).
    refine: int | None = option(
        None, f"parallax correction: steps along the eye ray to each camera's depth (default {DEPTH_REFINE}; 0 = the "
        "paper's colour at the slice point)", flag="--refine", type=int, metavar="N",
        control=Control("slider", "refine steps", -1, MAX_REFINE, 1, none_value=-1,
                        hint="parallax-correction steps (-1 = the method's default)"))
    #: Slice generation: "instanced" (compute + instancing) or "geometry" (geometry shader).
    mode: str = option("instanced", "slice generation: compute + instancing, or a geometry shader",
                       flag="--mode", choices=MODES)
    #: Slice spacing l forced in metres (clamped to the level's minimum); None = Eq. 10.
    spacing: float | None = option(None, "slice spacing l in metres (None: Eq. 10)", type=float)
    #: Draw the same squares untextured: the bare fill-cost reference of furrow/bench/render.py.
    fill_only: bool = option(False, "draw the slices untextured (the bare fill cost)")
    #: A debug output instead of the colour: "camera" (the dominant input camera's index + 1 per
    #: pixel) or "rejections" (1 kept, 2 rejected by Eq. 2) in the red channel
    #: (render.microfacet.geometry.debug_codes); needs supersample 1.
    debug: str | None = option(None, "debug output instead of the colour", type=str, choices=DEBUG_OUTPUTS[1:])

    def __post_init__(self) -> None:
        if not self.tolerance_px > 0:
            raise ValueError(f"tolerance must be > 0 pixels, got {self.tolerance_px}")
        if self.refine is not None and not (int(self.refine) == self.refine and 0 <= self.refine <= MAX_REFINE):
            raise ValueError(f"refine must be 0..{MAX_REFINE} steps, got {self.refine}")
        if self.level is not None and not (int(self.level) == self.level and self.level > 0):
            raise ValueError(f"level must be a pyramid resolution L > 0, got {self.level}")
        if self.spacing is not None and not self.spacing > 0:
            raise ValueError(f"spacing must be > 0 metres, got {self.spacing}")
        if self.debug not in DEBUG_OUTPUTS:
            raise ValueError(f"unknown debug output {self.debug!r}; use one of {DEBUG_OUTPUTS[1:]}")
        if self.mode not in MODES:
            raise ValueError(f"unknown microfacet mode {self.mode!r}; use one of {MODES}")

    @property
    def refine_steps(self) -> int:
        """``refine`` with None resolved to the default DEPTH_REFINE."""
        return DEPTH_REFINE if self.refine is None else int(self.refine)


SPEC = MethodSpec(
    "microfacet", "render.microfacet.gl:MicrofacetRenderer",
    "view-dependent microfacet billboards (docs/methods.md §1.2-1.7): the pyramid level and slice spacing follow "
    "the screen-space tolerance E",
    options=MicrofacetOptions, supersample=True, alpha="matte", debug_outputs=DEBUG_OUTPUTS[1:])
