"""The one registry of rendering methods: each method's spec, the options every method shares,
and the common shape of a renderer.

A method is a folder ``render/NAME/`` whose ``spec.py`` declares a :class:`MethodSpec`: the
renderer class (imported on first use), the method's own options dataclass (each field with its
command-line flag, help and viewer control, :func:`option`) and what the method supports (the
shared supersampling, its kind of alpha, held-out evaluation, the side-by-side sheets, debug
outputs).  :data:`METHODS` has one line per method (``name -> "module:SPEC"``).  Everything a
client offers is made from the specs, never by naming a method: the flags and help of
``furrow render`` and ``furrow eval`` (furrow/method_flags.py), the viewer's method list and
controls (render.viewer.gui), eval's method list and sheets (:func:`eval_methods`,
:func:`sheet_methods`).  docs/design.md "Adding a method" walks through a new one.

Every renderer is a :class:`Renderer`: a GL owner (``render.owner.GLOwner``) built from
(context, model, options) by :func:`create_renderer`, with ``render(camera, options) ->
render.frame.Frame`` and ``release()`` (idempotent; also via ``with``)::

    opts = RenderOptions.for_method("microfacet", supersample=2, tolerance_px=8.0)
    with create_renderer("microfacet", ctx, model, opts) as r:
        frame = r.render(camera)                       # the renderer's options
        frame = r.render(camera, tolerance_px=4.0)     # one field changed for this frame

:class:`RenderOptions` holds what every method shares (``supersample``) and each method's own
options by name; options may change from frame to frame without re-uploading the model.
"""

from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass
from typing import Any, ClassVar

from capture.camera import Camera
from render.antialias import MAX_SUPERSAMPLE, check_factor
from render.frame import Frame
from render.owner import GLOwner

#: Samples per pixel and axis of every method that supersamples, unless told otherwise
#: (render.antialias; the references are area-sampled photographs or path-traced images).
DEFAULT_SUPERSAMPLE = 2
#: The alpha a method's frames carry (MethodSpec.alpha): "coverage" (the share of a pixel's samples
#: drawn: 0 / 1 at one sample), "matte" (that times the model's view matte, volume.model.RgbzImages
#: .alpha, where it has one), "soft" (every pixel a blend of semi-transparent primitives).
ALPHA_KINDS = ("coverage", "matte", "soft")
#: Viewer control kinds (Control.kind): render.viewer.gui builds each.
CONTROL_KINDS = ("slider", "dropdown", "checkbox")
#: Key of an option field's OptionInfo in its dataclasses.Field metadata.
OPTION_KEY = "furrow_option"


@dataclass(frozen=True)
class Control:
    """The viewer control of one option field (render.viewer.gui.add_control builds it)."""

    #: One of CONTROL_KINDS.
    kind: str
    #: Label in the panel.
    label: str
    #: Slider range and step.
    lo: float = 0.0
    hi: float = 1.0
    step: float = 1.0
    #: Dropdown choices (values of the field; shown as text).
    choices: tuple = ()
    #: Tooltip.
    hint: str = ""
    #: For a field whose None means "the method's default": the control value that stands for None.
    none_value: Any = None

    def __post_init__(self) -> None:
        if self.kind not in CONTROL_KINDS:
            raise ValueError(f"unknown control kind {self.kind!r}; use one of {CONTROL_KINDS}")

    def to_value(self, shown, kind: type):
        """The field value of the control's shown value (``kind``: the field's type)."""
        if self.none_value is not None and shown == self.none_value:
            return None
        return bool(shown) if kind is bool else kind(shown)

    def shown(self, value):
        """The control value that shows field value ``value``."""
        if value is None:
            return self.none_value
        return str(value) if self.kind == "dropdown" else value


@dataclass(frozen=True)
class OptionInfo:
    """What a client needs to offer one option field (:func:`option`)."""

    #: Help text of the flag (and the field's documentation).
    help: str
    #: Value type (argparse converts with it; bool fields are on/off switches).
    type: type
    #: Command-line flag ("--tolerance"), or None for an option no command line sets.
    flag: str | None = None
    #: Accepted values (argparse choices), or None.
    choices: tuple | None = None
    #: Placeholder of the value in --help.
    metavar: str | None = None
    #: The viewer's control, or None for an option the viewer does not offer.
    control: Control | None = None


def option(default, help: str, *, flag: str | None = None, type: type | None = None, choices=None,
           metavar: str | None = None, control: Control | None = None):
    """A field of an options dataclass with its flag, help and viewer control (``type`` defaults
    to the type of ``default``; give it when the default is None)."""
    if type is None:
        if default is None:
            raise ValueError(f"option {flag or help!r}: a None default needs its type")
        type = builtins_type(default)
    info = OptionInfo(help, type, flag, None if choices is None else tuple(choices), metavar, control)
    return dataclasses.field(default=default, metadata={OPTION_KEY: info})


def builtins_type(value) -> type:
    """int, float, bool or str: the type of an option's default."""
    for t in (bool, int, float, str):
        if isinstance(value, t):
            return t
    raise ValueError(f"option default {value!r}: give its type")


def option_fields(options_cls) -> list[tuple[dataclasses.Field, OptionInfo]]:
    """(field, OptionInfo) of every field of an options dataclass declared with :func:`option`."""
    if options_cls is None:
        return []
    return [(f, f.metadata[OPTION_KEY]) for f in dataclasses.fields(options_cls) if OPTION_KEY in f.metadata]


@dataclass(frozen=True)
class MethodSpec:
    """What a rendering method is and supports (one per method, in its folder's ``spec.py``)."""

    #: Registry name (``furrow render --method NAME``).
    name: str
    #: "module:Class" of its Renderer (imported on first use).
    renderer: str
    #: One line: what it draws (help texts, the viewer's hint).
    summary: str
    #: Its own options: a frozen dataclass of :func:`option` fields with defaults, or None.
    options: type | None = None
    #: It draws RenderOptions.supersample x supersample samples per pixel (else one, whatever it says).
    supersample: bool = False
    #: The alpha of its frames (ALPHA_KINDS).
    alpha: str = "matte"
    #: ``furrow eval`` draws it (and its table lists it).
    evaluate: bool = True
    #: The side-by-side sheets show it.
    sheet: bool = True
    #: Debug outputs it draws itself instead of the colour (the viewer's debug views): its options
    #: then have a field ``debug`` (None or one of these).
    debug_outputs: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.alpha not in ALPHA_KINDS:
            raise ValueError(f"method {self.name!r}: alpha must be one of {ALPHA_KINDS}, got {self.alpha!r}")
        if ":" not in self.renderer:
            raise ValueError(f"method {self.name!r}: renderer must be 'module:Class', got {self.renderer!r}")
        names = {f.name for f in dataclasses.fields(self.options)} if self.options is not None else set()
        if self.debug_outputs and "debug" not in names:
            raise ValueError(f"method {self.name!r} lists debug outputs: its options need a field 'debug'")
        for f in dataclasses.fields(self.options) if self.options is not None else ():
            if f.default is dataclasses.MISSING:
                raise ValueError(f"method {self.name!r}: option {f.name} needs a default")

    def reads(self, shared: str) -> bool:
        """Whether the method reads the shared RenderOptions field ``shared``."""
        return shared == "supersample" and self.supersample

    def default_options(self):
        """The method's options with their defaults (None for a method without options)."""
        return None if self.options is None else self.options()

    def renderer_class(self) -> type[Renderer]:
        module, cls = self.renderer.split(":")
        return getattr(importlib.import_module(module), cls)


@dataclass(frozen=True)
class RenderOptions:
    """Per-frame options: what every method shares, and each method's own options by name
    (validated on creation)."""

    #: S x S samples per pixel, box-resolved on the GPU (render.antialias); 1 = off.  Read by the
    #: methods whose spec says ``supersample``; the others draw one sample per pixel.
    supersample: int = option(DEFAULT_SUPERSAMPLE, "anti-aliasing: S x S samples per pixel, box-resolved; 1 = off, "
                              "about S^2 x the fill cost (methods that supersample)", flag="--supersample",
                              metavar="S", control=Control("dropdown", "supersampling",
                                                           choices=tuple(range(1, MAX_SUPERSAMPLE + 1)),
                                                           hint="S x S samples per pixel of the still frame"))
    #: Each method's own options (an instance of its spec's options dataclass) by registry name, as
    #: sorted (name, options) pairs (a dict is accepted); a method not named draws with its defaults.
    methods: tuple = ()
    #: A frame drawn while the viewer's camera moves (set by render.viewer, no flag or control): a
    #: method may leave out a refinement that costs more than a glance shows (gather: its second depth
    #: layer); the still frame that follows has it.
    draft: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "supersample", check_factor(self.supersample))
        if not isinstance(self.draft, bool):
            raise ValueError(f"draft must be a bool, got {self.draft!r}")
        pairs = dict(self.methods)
        for name, opts in pairs.items():
            spec = method_spec(name)
            if spec.options is None or not isinstance(opts, spec.options):
                want = "no options" if spec.options is None else spec.options.__name__
                raise ValueError(f"options of method {name!r} must be {want}, got {type(opts).__name__}")
        object.__setattr__(self, "methods", tuple(sorted(pairs.items())))

    def of(self, name: str):
        """Method ``name``'s own options (its defaults when not set; None for a method without)."""
        return dict(self.methods).get(name) or method_spec(name).default_options()

    def changed(self, **changes) -> RenderOptions:
        """A copy with the given shared fields replaced (validated)."""
        return dataclasses.replace(self, **changes) if changes else self

    def changed_for(self, name: str, **changes) -> RenderOptions:
        """A copy with shared fields and fields of method ``name``'s own options replaced; a field
        that is neither is an error."""
        if not changes:
            return self
        shared = {f.name for f in dataclasses.fields(self)} - {"methods"}
        own = {k: v for k, v in changes.items() if k not in shared}
        out = self.changed(**{k: v for k, v in changes.items() if k in shared})
        if not own:
            return out
        spec = method_spec(name)
        names = {f.name for f in dataclasses.fields(spec.options)} if spec.options is not None else set()
        bad = sorted(set(own) - names)
        if bad:
            raise ValueError(f"method {name!r} has no option {', '.join(bad)} (its options: "
                             f"{', '.join(sorted(names)) or 'none'}; shared: {', '.join(sorted(shared))})")
        mine = dataclasses.replace(self.of(name), **own)
        return dataclasses.replace(out, methods={**dict(out.methods), name: mine})

    @classmethod
    def for_method(cls, name: str, **values) -> RenderOptions:
        """Options with shared fields and method ``name``'s own fields set from ``values``."""
        return cls().changed_for(name, **values)


class Renderer(GLOwner):
    """A rendering method for one model (see the module docstring).

    Subclasses set ``name`` (their registry name), implement ``from_model`` and ``_render``; a
    method reads its own options with ``options.of(self.name)``.
    """

    #: Registry name.
    name: ClassVar[str] = ""

    def __init__(self, ctx, options: RenderOptions | None = None) -> None:
        super().__init__(ctx)
        self.options = options if options is not None else RenderOptions()

    @property
    def spec(self) -> MethodSpec:
        """The method's spec (render.methods.METHODS)."""
        return method_spec(self.name)

    @classmethod
    def from_model(cls, ctx, model, options: RenderOptions | None = None) -> Renderer:
        """The renderer of a ``volume.model.Model`` with default ``options``."""
        raise NotImplementedError

    def render(self, camera: Camera, options: RenderOptions | None = None, *, read: bool = True,
               **changes) -> Frame:
        """One frame seen by ``camera`` (its size is the image size) with ``options`` (default: the
        renderer's) and the given fields (shared or the method's own) changed; ``read=False`` draws
        and times only (the returned frame is empty)."""
        self.check_alive()
        if options is not None and not isinstance(options, RenderOptions):
            raise TypeError(f"{type(self).__name__}.render: options must be a RenderOptions, got {options!r} "
                            "(a method's own option is a keyword: render(camera, tolerance_px=4.0))")
        opts = (options if options is not None else self.options).changed_for(self.name, **changes)
        return self._render(camera, opts, read)

    def _render(self, camera: Camera, options: RenderOptions, read: bool) -> Frame:
        raise NotImplementedError


#: The method of ``furrow render`` when none is named, first in ``furrow eval``: splatted depth
#: with colours gathered from the two nearest views (render/gather/gl.py), 3-4 dB above the point
#: splatter and the microfacets on held-out fur and plants (docs/methods.md).
DEFAULT_METHOD = "gather"

#: name -> "module:SPEC" of its spec (imported on first use, so that importing the registry
#: compiles and uploads nothing).  The order is the order of every list: help, viewer, eval.
METHODS: dict[str, str] = {
    "gather": "render.gather.spec:SPEC",
    "microfacet": "render.microfacet.spec:SPEC",
    "points": "render.points.spec:SPEC",
    "mesh-vdtm": "render.mesh.spec:VDTM",
    "mesh-colour": "render.mesh.spec:COLOUR",
    "splat": "render.splat.spec:SPEC",
}


def method_spec(name: str) -> MethodSpec:
    """The spec registered as ``name``."""
    if name not in METHODS:
        raise ValueError(f"unknown rendering method {name!r}; use one of {', '.join(METHODS)}")
    module, attr = METHODS[name].split(":")
    spec = getattr(importlib.import_module(module), attr)
    if not isinstance(spec, MethodSpec) or spec.name != name:
        raise ValueError(f"METHODS[{name!r}] = {METHODS[name]!r} is not the MethodSpec of {name!r}")
    return spec


def method_names() -> list[str]:
    """Every registered method's name, in registry order."""
    return list(METHODS)


def method_specs() -> list[MethodSpec]:
    """Every registered spec, in registry order."""
    return [method_spec(n) for n in METHODS]


def method_class(name: str) -> type[Renderer]:
    """The Renderer class of method ``name``."""
    return method_spec(name).renderer_class()


def eval_methods() -> tuple[str, ...]:
    """Methods ``furrow eval`` draws, in the order of its table (specs with ``evaluate``)."""
    return tuple(s.name for s in method_specs() if s.evaluate)


def sheet_methods() -> tuple[str, ...]:
    """Methods of the side-by-side sheets (specs with ``sheet``), in registry order."""
    return tuple(s.name for s in method_specs() if s.sheet)


def samples_per_pixel_side(name: str, options: RenderOptions | None = None) -> int:
    """S of the S x S samples per pixel that method ``name`` draws a full frame with: the options'
    supersample where its spec says it supersamples, else 1 (one sample per pixel)."""
    options = options or RenderOptions()
    return int(options.supersample) if method_spec(name).supersample else 1


def options_record(options: RenderOptions, *methods: str) -> dict:
    """JSON-ready record of ``options``: the shared fields, and under each of ``methods`` that has
    options its own fields (render_stats.json, eval.json)."""
    out = {f.name: getattr(options, f.name) for f in dataclasses.fields(options) if f.name != "methods"}
    for name in methods:
        own = options.of(name)
        if own is not None:
            out[name] = dataclasses.asdict(own)
    return out


def create_renderer(name: str, ctx, model, options: RenderOptions | None = None) -> Renderer:
    """The ``name`` method's renderer of ``model`` on ``ctx`` (release it, or use ``with``)."""
    return method_class(name).from_model(ctx, model, options)
