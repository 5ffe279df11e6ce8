"""The viser controls of one client: they build a ViewSettings on every change and show the
live readout (frame time, fps, frame size, level picked by the tolerance E).

Everything listed comes from elsewhere: the methods from the renderer registry
(render.methods.METHODS), the maps from the bundled environment maps, the views from
render.viewer.settings.  Nothing here branches on a method's name.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from render.viewer.settings import MAX_LINES_CHOICES, VIEWS, EnvSettings, ViewSettings

#: Label of "no environment" in the map dropdown.
NO_ENV = "none (black)"
#: Tolerance E slider range (pixels) and step.
TOLERANCE_RANGE = (0.5, 32.0, 0.5)
#: Supersampling choices (samples per pixel and axis).
SUPERSAMPLE_CHOICES = ("1", "2", "3", "4")
#: Exposure slider range (linear factor) and step; rotation in degrees.
EXPOSURE_RANGE = (0.1, 8.0, 0.1)
ROTATION_RANGE = (-180.0, 180.0, 5.0)
#: Turntable export: default frame count and frame rate.
EXPORT_FRAMES = 36
EXPORT_FPS = 24
#: Frames per second shown in the readout: mean over this many recent moving frames.
READOUT_WINDOW = 10


@dataclass
class Controls:
    """The handles of one client's GUI (viser GuiHandles)."""

    method: object
    tolerance: object
    supersample: object
    refine: object
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
    #: Layout of the file maps (render.shading.envmap.ENV_CONVENTIONS), fixed by the command line.
    convention: str = "furrow"

    def settings(self) -> ViewSettings:
        """The ViewSettings the controls show (raises ValueError on an invalid combination)."""
        from render.methods import RenderOptions

        refine = int(self.refine.value)
        opts = RenderOptions(tolerance_px=float(self.tolerance.value), supersample=int(self.supersample.value),
                             refine=None if refine < 0 else refine)
        env = EnvSettings(map=None if self.env_map.value == NO_ENV else self.env_map.value,
                          exposure=float(self.exposure.value), ground=bool(self.ground.value),
                          glare=bool(self.glare.value), rotation_deg=float(self.rotation.value),
                          convention=self.convention)
        return ViewSettings(method=self.method.value, options=opts, max_lines=int(self.max_lines.value), env=env,
                            view=self.view.value)


def build_controls(gui, initial: ViewSettings, env_names, methods) -> Controls:
    """Add the controls to ``gui`` (a client's viser GuiApi), showing ``initial``."""
    from render.methods import MAX_REFINE

    with gui.add_folder("Render"):
        method = gui.add_dropdown("method", tuple(methods), initial_value=initial.method)
        tol = gui.add_slider("tolerance E (px)", *TOLERANCE_RANGE, initial_value=initial.options.tolerance_px,
                             hint="screen-space tolerance: picks the pyramid level and slice spacing (Eq. 10-11)")
        ss = gui.add_dropdown("supersampling", SUPERSAMPLE_CHOICES, initial_value=str(initial.options.supersample),
                              hint="S x S samples per pixel of the still frame")
        refine = gui.add_slider("refine steps", -1, MAX_REFINE, 1,
                                initial_value=-1 if initial.options.refine is None else initial.options.refine,
                                hint="parallax-correction steps (-1 = the method's default)")
        max_lines = gui.add_dropdown("max resolution", tuple(str(x) for x in MAX_LINES_CHOICES),
                                     initial_value=str(initial.max_lines), hint="lines of the full frame, at most")
        view = gui.add_dropdown("view", VIEWS, initial_value=initial.view,
                                hint="debug views: depth, pyramid level, dominant camera, Eq. 2 rejections")
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
    controls = Controls(method, tol, ss, refine, max_lines, env_map, exposure, ground, glare, rotation, view,
                        cameras, readout, note, screenshot, export_kind, export_frames, export_fps, export, progress,
                        initial.env.convention)
    sync_option_controls(controls)
    return controls


#: The per-frame option controls and the RenderOptions field each one sets.
OPTION_CONTROLS = (("tolerance", "tolerance_px"), ("supersample", "supersample"), ("refine", "refine"))


def sync_option_controls(controls) -> None:
    """Grey out the option controls that the chosen method does not read
    (render.methods.unused_options), so that a slider never looks as if it did nothing."""
    from render.methods import unused_options

    unused = set(unused_options(controls.method.value, [f for _, f in OPTION_CONTROLS]))
    for attr, field_name in OPTION_CONTROLS:
        getattr(controls, attr).disabled = field_name in unused


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

    for h in (controls.method, controls.tolerance, controls.supersample, controls.refine, controls.max_lines,
              controls.env_map, controls.exposure, controls.ground, controls.glare, controls.rotation, controls.view):
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
