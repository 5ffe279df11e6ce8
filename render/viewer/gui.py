"""The viser controls of one client: they build a ViewSettings on every change and show the
live readout (frame time, fps, frame size, the level a method drew).

Everything listed comes from elsewhere: the methods and their option controls from the method
specs (render.methods: the shared options' controls, then each method's own, shown only while
that method is chosen), the maps from the bundled environment maps, the views from
render.viewer.settings.  Nothing here branches on a method's name.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

from render.methods import Control, RenderOptions, method_names, method_spec, option_fields
from render.viewer.settings import MAX_LINES_CHOICES, EnvSettings, ViewSettings, all_views

#: Label of "no environment" in the map dropdown.
NO_ENV = "none (black)"
#: Exposure slider range (linear factor) and step; rotation in degrees.
EXPOSURE_RANGE = (0.1, 8.0, 0.1)
ROTATION_RANGE = (-180.0, 180.0, 5.0)
#: Turntable export: default frame count and frame rate.
EXPORT_FRAMES = 36
EXPORT_FPS = 24
#: Frames per second shown in the readout: mean over this many recent moving frames.
READOUT_WINDOW = 10


@dataclass(frozen=True)
class OptionControl:
    """One option control: the handle, the method it belongs to (None: a shared option of
    RenderOptions), the field it sets, the field's type and its Control."""

    handle: object
    method: str | None
    name: str
    type: type
    control: Control

    @property
    def value(self):
        return self.control.to_value(self.handle.value, self.type)


@dataclass
class Controls:
    """The handles of one client's GUI (viser GuiHandles)."""

    method: object
    max_lines: object
    env_map: object
    exposure: object
    ground: object
    glare: object
    rotation: object
    view: object
    cameras: object
    readout: object
    note: object
    screenshot: object
    export_kind: object
    export_frames: object
    export_fps: object
    export: object
    progress: object
    #: The option controls made from the specs (shared first, then each method's).
    options: list = field(default_factory=list)
    #: Layout of the file maps (render.shading.envmap.ENV_CONVENTIONS), fixed by the command line.
    convention: str = "furrow"

    def render_options(self) -> RenderOptions:
        """The RenderOptions the option controls show (every method's own options)."""
        shared = {c.name: c.value for c in self.options if c.method is None}
        own: dict[str, dict] = {}
        for c in self.options:
            if c.method is not None:
                own.setdefault(c.method, {})[c.name] = c.value
        methods = {m: dataclasses.replace(method_spec(m).default_options(), **v) for m, v in own.items()}
        return RenderOptions(**shared, methods=methods)

    def settings(self) -> ViewSettings:
        """The ViewSettings the controls show (raises ValueError on an invalid combination)."""
        env = EnvSettings(map=None if self.env_map.value == NO_ENV else self.env_map.value,
                          exposure=float(self.exposure.value), ground=bool(self.ground.value),
                          glare=bool(self.glare.value), rotation_deg=float(self.rotation.value),
                          convention=self.convention)
        return ViewSettings(method=self.method.value, options=self.render_options(),
                            max_lines=int(self.max_lines.value), env=env, view=self.view.value)


def add_control(gui, ctl: Control, value):
    """A viser handle for ``ctl`` showing field value ``value``."""
    shown = ctl.shown(value)
    if ctl.kind == "slider":
        return gui.add_slider(ctl.label, ctl.lo, ctl.hi, ctl.step, initial_value=shown, hint=ctl.hint or None)
    if ctl.kind == "dropdown":
        return gui.add_dropdown(ctl.label, tuple(str(c) for c in ctl.choices), initial_value=shown,
                                hint=ctl.hint or None)
    return gui.add_checkbox(ctl.label, bool(shown), hint=ctl.hint or None)


def option_controls(gui, options: RenderOptions, methods) -> list[OptionControl]:
    """The controls of the shared options and of each method's own options (spec order)."""
    out = []
    for f, info in option_fields(RenderOptions):
        if info.control is not None:
            out.append(OptionControl(add_control(gui, info.control, getattr(options, f.name)), None, f.name,
                                     info.type, info.control))
    for name in methods:
        spec = method_spec(name)
        mine = options.of(name)
        for f, info in option_fields(spec.options):
            if info.control is not None:
                handle = add_control(gui, info.control, getattr(mine, f.name))
                out.append(OptionControl(handle, name, f.name, info.type, info.control))
    return out


def build_controls(gui, initial: ViewSettings, env_names, methods=None) -> Controls:
    """Add the controls to ``gui`` (a client's viser GuiApi), showing ``initial``; ``methods``:
    the method names offered (default: every registered method)."""
    methods = list(methods if methods is not None else method_names())
    with gui.add_folder("Render"):
        method = gui.add_dropdown("method", tuple(methods), initial_value=initial.method,
                                  hint=method_spec(initial.method).summary)
        opts = option_controls(gui, initial.options, methods)
        max_lines = gui.add_dropdown("max resolution", tuple(str(x) for x in MAX_LINES_CHOICES),
                                     initial_value=str(initial.max_lines), hint="lines of the full frame, at most")
        view = gui.add_dropdown("view", all_views(), initial_value=initial.view,
                                hint="debug views: depth, pyramid level and the method's own (its debug outputs)")
    with gui.add_folder("Environment"):
        env_map = gui.add_dropdown("map", (NO_ENV, *env_names), initial_value=initial.env.map or NO_ENV)
        exposure = gui.add_slider("exposure", *EXPOSURE_RANGE, initial_value=initial.env.exposure)
        ground = gui.add_checkbox("ground shadow", initial.env.ground)
        glare = gui.add_checkbox("glare", initial.env.glare)
        rotation = gui.add_slider("rotation (deg)", *ROTATION_RANGE, initial_value=initial.env.rotation_deg)
    with gui.add_folder("Capture"):
        cameras = gui.add_checkbox("show capture cameras", True, hint="click a frustum to look through it")
        screenshot = gui.add_button("screenshot (PNG)")
        export_kind = gui.add_dropdown("export", ("turntable", "capture path"), initial_value="turntable")
        export_frames = gui.add_number("frames", EXPORT_FRAMES, min=2, max=720, step=1)
        export_fps = gui.add_number("fps", EXPORT_FPS, min=1, max=60, step=1)
        export = gui.add_button("export MP4")
        progress = gui.add_progress_bar(0.0, visible=False)
    readout = gui.add_markdown("waiting for the first frame")
    note = gui.add_markdown("", visible=False)
    controls = Controls(method, max_lines, env_map, exposure, ground, glare, rotation, view, cameras, readout, note,
                        screenshot, export_kind, export_frames, export_fps, export, progress, opts,
                        initial.env.convention)
    sync_option_controls(controls)
    return controls


def sync_option_controls(controls) -> None:
    """Show only the chosen method's own option controls, and grey out the shared ones it does not
    read (a method that draws one sample per pixel greys supersampling), so that a control never
    looks as if it did nothing."""
    chosen = method_spec(controls.method.value)
    for c in controls.options:
        if c.method is None:
            c.handle.disabled = c.name == "supersample" and not chosen.supersample
        else:
            c.handle.visible = c.method == chosen.name


def on_settings_change(controls: Controls, apply: Callable[[ViewSettings], None],
                       report: Callable[[str], None]) -> None:
    """Call ``apply(settings)`` whenever a render control changes (``report(msg)`` when the
    combination is invalid)."""
    def changed(_event) -> None:
        sync_option_controls(controls)
        try:
            apply(controls.settings())
        except ValueError as e:
            report(str(e))

    for h in (controls.method, *(c.handle for c in controls.options), controls.max_lines, controls.env_map,
              controls.exposure, controls.ground, controls.glare, controls.rotation, controls.view):
        h.on_update(changed)


def readout_text(recent: list[dict], last_full: dict | None, level: str, still_count: int = 0) -> str:
    """The readout: moving fps and frame size over the recent frames, the last full frame's time
    (and how many still frames were sent so far: "still #N")."""
    lines = []
    moving = [r for r in recent if r["moving"]][-READOUT_WINDOW:]
    if len(moving) >= 2:
        span = moving[-1]["t"] - moving[0]["t"]
        fps = (len(moving) - 1) / span if span > 0 else float("nan")
        lines.append(f"moving: **{fps:.1f} fps**, {moving[-1]['width']}x{moving[-1]['height']}, "
                     f"{moving[-1]['total_ms']:.0f} ms/frame")
    if last_full is not None:
        ss = last_full.get("supersample", 1)
        lines.append(f"still #{still_count}: {last_full['width']}x{last_full['height']}, {ss}x{ss} samples, "
                     f"{last_full['total_ms']:.0f} ms (render {last_full['ms']:.0f} ms)")
    if level:
        lines.append(level)
    return "  \n".join(lines) or "waiting for the first frame"
