"""The one registry of rendering methods, their per-frame options and their common shape.

Every way of drawing a model is a :class:`Renderer`: a GL owner (``render.owner.GLOwner``)
built from (context, model, options) by :func:`create_renderer`, with
``render(camera, options) -> render.frame.Frame`` and ``release()`` (idempotent; also via
``with``).  Clients look methods up by name in :data:`METHODS` and never branch on the name::

    with create_renderer("microfacet", ctx, model, RenderOptions(supersample=2)) as r:
        frame = r.render(camera)                       # the renderer's options
        frame = r.render(camera, tolerance_px=4.0)     # one field changed for this frame

Options may change from frame to frame without re-uploading the model (each method caches
what it compiles per option set).  A method reads the fields it lists in ``Renderer.uses`` and
ignores the others.  A new method is one module (a Renderer subclass with ``from_model``) and
one line in :data:`METHODS`.
"""

from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass
from typing import ClassVar

from capture.camera import Camera
from render.antialias import check_factor
from render.frame import Frame
from render.microfacet.geometry import DEBUG_OUTPUTS, DEPTH_REFINE
from render.microfacet.lod import DEFAULT_TOLERANCE_PX
from render.owner import GLOwner

#: Samples per pixel and axis of every method unless told otherwise (render.antialias; README
#: "Where the design moved": the references are area-sampled photographs or path-traced images).
DEFAULT_SUPERSAMPLE = 2
#: Slice generation paths of the microfacet renderer (render.microfacet.gl).
MICROFACET_MODES = ("instanced", "geometry")
#: Most parallax-correction steps accepted (render quality saturates after 2: furrow/bench/render.py).
MAX_REFINE = 4


@dataclass(frozen=True)
class RenderOptions:
    """Per-frame knobs of every method (validated on creation); a method ignores the fields it
    does not list in ``Renderer.uses``."""

    #: Screen-space tolerance E in output pixels: picks the pyramid level and slice spacing
    #: (docs/methods.md §1.7, Eq. 10-11).
    tolerance_px: float = DEFAULT_TOLERANCE_PX
    #: S x S samples per pixel, box-resolved on the GPU (render.antialias); 1 = off.
    supersample: int = DEFAULT_SUPERSAMPLE
    #: Microfacet parallax-correction steps along the eye ray (None = DEPTH_REFINE, 0 = the
    #: paper's colour at the slice point).
    refine: int | None = None
    #: Force this pyramid level index (the spacing then follows Eq. 10 on it); None = Eq. 11.
    level: int | None = None
    #: Force the slice spacing l in metres (clamped to the level's minimum); None = Eq. 10.
    spacing: float | None = None
    #: Microfacet slice generation: "instanced" (compute + instancing) or "geometry" (geometry shader).
    mode: str = "instanced"
    #: Draw the same microfacet squares untextured: the bare fill-cost reference of furrow/bench/render.py.
    fill_only: bool = False
    #: A debug output instead of the colour (methods that list "debug" in ``uses``): "camera" (the
    #: dominant input camera's index + 1 per pixel) or "rejections" (1 kept, 2 rejected by Eq. 2)
    #: in the red channel (render.microfacet.geometry.debug_codes); needs supersample 1.
    debug: str | None = None

    def __post_init__(self) -> None:
        if not self.tolerance_px > 0:
            raise ValueError(f"tolerance must be > 0 pixels, got {self.tolerance_px}")
        object.__setattr__(self, "supersample", check_factor(self.supersample))
        if self.refine is not None and not (int(self.refine) == self.refine and 0 <= self.refine <= MAX_REFINE):
            raise ValueError(f"refine must be 0..{MAX_REFINE} steps, got {self.refine}")
        if self.level is not None and int(self.level) != self.level:
            raise ValueError(f"level must be a level index, got {self.level}")
        if self.spacing is not None and not self.spacing > 0:
            raise ValueError(f"spacing must be > 0 metres, got {self.spacing}")
        if self.debug not in DEBUG_OUTPUTS:
            raise ValueError(f"unknown debug output {self.debug!r}; use one of {DEBUG_OUTPUTS[1:]}")
        if self.debug is not None and self.supersample != 1:
            raise ValueError("debug outputs are codes per pixel: they need supersample 1")
        if self.mode not in MICROFACET_MODES:
            raise ValueError(f"unknown microfacet mode {self.mode!r}; use one of {MICROFACET_MODES}")

    @property
    def refine_steps(self) -> int:
        """``refine`` with None resolved to the default DEPTH_REFINE."""
        return DEPTH_REFINE if self.refine is None else int(self.refine)

    def changed(self, **changes) -> RenderOptions:
        """A copy with the given fields replaced (validated)."""
        return dataclasses.replace(self, **changes) if changes else self


class Renderer(GLOwner):
    """A rendering method for one model (see the module docstring).

    Subclasses set ``name`` and ``uses``, implement ``from_model`` and ``_render``.
    """

    #: Registry name.
    name: ClassVar[str] = ""
    #: The RenderOptions fields this method reads.
    uses: ClassVar[frozenset[str]] = frozenset({"supersample"})

    def __init__(self, ctx, options: RenderOptions | None = None) -> None:
        super().__init__(ctx)
        self.options = options if options is not None else RenderOptions()

    @classmethod
    def from_model(cls, ctx, model, options: RenderOptions | None = None) -> Renderer:
        """The renderer of a ``volume.model.Model`` with default ``options``."""
        raise NotImplementedError

    def render(self, camera: Camera, options: RenderOptions | None = None, *, read: bool = True,
               **changes) -> Frame:
        """One frame seen by ``camera`` (its size is the image size) with ``options`` (default: the
        renderer's) and the given fields changed; ``read=False`` draws and times only (the
        returned frame is empty)."""
        self.check_alive()
        if options is not None and not isinstance(options, RenderOptions):
            raise TypeError(f"{type(self).__name__}.render: options must be a RenderOptions, got {options!r} "
                            "(the tolerance is RenderOptions.tolerance_px)")
        opts = (options if options is not None else self.options).changed(**changes)
        return self._render(camera, opts, read)

    def _render(self, camera: Camera, options: RenderOptions, read: bool) -> Frame:
        raise NotImplementedError


#: The method of ``furrow render`` when none is named, first in ``furrow eval``: splatted depth
#: with colours gathered from the two nearest views (render/gather/gl.py), 3-4 dB above the point
#: splatter and the microfacets on held-out fur and plants (README "Novel views").
DEFAULT_METHOD = "gather"

#: name -> "module:Renderer class" (imported on first use, so that importing the registry
#: compiles and uploads nothing).
METHODS: dict[str, str] = {
    "microfacet": "render.microfacet.gl:MicrofacetRenderer",
    "mesh-vdtm": "render.mesh.gl:VdtmRenderer",
    "mesh-colour": "render.mesh.gl:MeshColourRenderer",
    "points": "render.points.gl:PointsRenderer",
    "gather": "render.gather.gl:GatherRenderer",
    "splat": "render.splat.gl:SplatRenderer",
}


def method_class(name: str) -> type[Renderer]:
    """The Renderer class registered as ``name``."""
    if name not in METHODS:
        raise ValueError(f"unknown rendering method {name!r}; use one of {', '.join(METHODS)}")
    module, cls = METHODS[name].split(":")
    return getattr(importlib.import_module(module), cls)


def samples_per_pixel_side(name: str, options: RenderOptions | None = None) -> int:
    """S of the S x S samples per pixel that method ``name`` draws a full frame with: the options'
    supersample where the method reads it, else 1 (one sample per pixel)."""
    options = options or RenderOptions()
    return int(options.supersample) if "supersample" in method_class(name).uses else 1


def create_renderer(name: str, ctx, model, options: RenderOptions | None = None) -> Renderer:
    """The ``name`` method's renderer of ``model`` on ``ctx`` (release it, or use ``with``)."""
    return method_class(name).from_model(ctx, model, options)


def unused_options(name: str, fields) -> list[str]:
    """The option fields among ``fields`` that method ``name`` ignores (a CLI rejects them)."""
    return [f for f in fields if f not in method_class(name).uses]
