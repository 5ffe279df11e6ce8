"""What a viewer client asked for: the method, its per-frame options, the size cap, the
environment compositing and the debug view (one frozen, validated value per change)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from render.methods import DEFAULT_METHOD, RenderOptions, method_specs, samples_per_pixel_side

#: Debug views computed from any method's Frame ("colour" is the normal picture).
FRAME_VIEWS = ("colour", "depth", "level")
#: Default cap on the full frame's height (lines); the browser canvas is used up to it.
DEFAULT_MAX_LINES = 720
#: Full-frame height caps offered in the GUI.
MAX_LINES_CHOICES = (240, 360, 480, 720, 1080)


def renderer_views() -> tuple[str, ...]:
    """Debug views a renderer draws itself: every method spec's ``debug_outputs``, in registry order."""
    out: list[str] = []
    for spec in method_specs():
        out += [v for v in spec.debug_outputs if v not in out and v not in FRAME_VIEWS]
    return tuple(out)


def all_views() -> tuple[str, ...]:
    """The views a client can ask for: FRAME_VIEWS, then :func:`renderer_views`."""
    return FRAME_VIEWS + renderer_views()


@dataclass(frozen=True)
class EnvSettings:
    """Environment compositing of the picture (docs/methods.md §3-§4; render.composite.pipeline)."""

    #: Environment map: a bundled name or a .exr/.hdr path; None = black background, no compositing.
    map: str | None = None
    #: Linear exposure factor (> 0).
    exposure: float = 1.0
    #: The object's shadow on a ground plane under it (from its sphere set).
    ground: bool = False
    #: Glare streaks on over-bright pixels.
    glare: bool = True
    #: Rotation of the map about its up axis, degrees.
    rotation_deg: float = 0.0
    #: Layout of a file map (render.shading.envmap.ENV_CONVENTIONS; bundled maps are furrow's).
    convention: str = "furrow"

    def __post_init__(self) -> None:
        if not self.exposure > 0:
            raise ValueError(f"exposure must be > 0, got {self.exposure}")


@dataclass(frozen=True)
class ViewSettings:
    """One client's choices (the GUI's state)."""

    #: Registry name of the rendering method (render.methods.METHODS); the CLI's default.
    method: str = DEFAULT_METHOD
    #: Per-frame options of the full frame (moving frames use one sample per pixel).
    options: RenderOptions = field(default_factory=RenderOptions)
    #: Cap on the full frame's height in lines (the canvas aspect is kept).
    max_lines: int = DEFAULT_MAX_LINES
    env: EnvSettings = field(default_factory=EnvSettings)
    #: One of all_views().
    view: str = "colour"

    def __post_init__(self) -> None:
        views = all_views()
        if self.view not in views:
            raise ValueError(f"unknown view {self.view!r}; use one of {', '.join(views)}")
        if int(self.max_lines) < 16:
            raise ValueError(f"max_lines must be >= 16, got {self.max_lines}")

    @property
    def still_samples(self) -> int:
        """S of the S x S samples per pixel of the method's still frame: options.supersample where
        the method reads it, else 1 (then the full frame is the last one, no supersampled pass)."""
        return samples_per_pixel_side(self.method, self.options)

    def changed(self, **changes) -> ViewSettings:
        """A copy with fields replaced; ``options`` / ``env`` may be given as dicts of field changes
        (``options``: shared fields and the fields of the method's own options)."""
        if isinstance(changes.get("options"), dict):
            changes["options"] = self.options.changed_for(changes.get("method", self.method), **changes["options"])
        if isinstance(changes.get("env"), dict):
            changes["env"] = dataclasses.replace(self.env, **changes["env"])
        return dataclasses.replace(self, **changes)
