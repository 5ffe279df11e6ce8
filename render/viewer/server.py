"""``furrow view``: the viser server, its clients and their sessions.

:class:`Viewer` starts the GL thread (render.viewer.gl_worker), the viser server and, per
connected browser, a render thread (render.viewer.session) with its own controls
(render.viewer.gui); the capture cameras are clickable frustums that snap the clicked client's
view to them.  "splats in the browser" swaps a client's server frames for the model's 3D
Gaussians drawn by the browser itself (viser's splat node; its render thread pauses).
:meth:`Viewer.close` ends the sessions, releases every GL object on the GL thread,
stops the server and writes the frame log (``--stats``).
"""

from __future__ import annotations

import errno
import socket
import threading
from pathlib import Path

import numpy as np

from render.viewer.adaptive import AdaptiveConfig
from render.viewer.session import FrameLog, Session, ViewCamera
from render.viewer.settings import ViewSettings

#: Frustum size as a share of the object's bounding-box diagonal.
FRUSTUM_SCALE = 0.08
#: Frustum line width (screen pixels) and colour.
FRUSTUM_LINE_PX = 2.0
FRUSTUM_RGB = (230, 140, 30)
#: Longest side (pixels) of the capture image shown in each frustum.
FRUSTUM_THUMB = 96
#: Seconds to wait for a screenshot or an export frame.
JOB_TIMEOUT_S = 600.0
#: Scene node of a client's own splats, and the hint of the panel's checkbox.
CLIENT_SPLATS_NODE = "/splats"
SPLATS_HINT = ("draw the model's 3D Gaussians in the browser (what furrow export --splats writes; their "
               "view-independent colour) instead of frames rendered here: the server no longer limits the frame rate")


class PortInUse(OSError):
    """The requested port is taken (viser would silently move to the next one)."""


def check_port(host: str, port: int) -> None:
    """Raise PortInUse when ``host:port`` cannot be bound (0 = any free port: always fine)."""
    if port == 0:
        return
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind((host, port))
        except OSError as e:
            if e.errno in (errno.EADDRINUSE, errno.EACCES):
                raise PortInUse(f"port {port} on {host} is in use (choose another with --port)") from None
            raise


class Viewer:
    """The running viewer (see the module docstring).

    Args:
        model: the volume.model.Model to show.
        cameras: the capture cameras shown as frustums (capture.camera.Camera list).
        host, port: where to serve (port 0: any free port).
        settings: every new client's initial ViewSettings.
        cfg: adaptive-resolution knobs.
        out_dir: where screenshots and exported videos are saved (they are also downloaded).
        env_names: environment maps offered in the GUI.
    """

    def __init__(self, model, cameras, host: str = "127.0.0.1", port: int = 8080,
                 settings: ViewSettings | None = None, cfg: AdaptiveConfig | None = None,
                 out_dir: Path = Path("out/view"), env_names=()) -> None:
        self.model = model
        self.cameras = list(cameras)
        self.host = host
        self.settings = settings or ViewSettings()
        self.cfg = cfg or AdaptiveConfig()
        self.out_dir = Path(out_dir)
        self.env_names = tuple(env_names)
        self.log = FrameLog()
        self.sessions: dict[int, Session] = {}
        self._lock = threading.Lock()
        self._closed = False
        self._frustums: list[dict] | None = None
        self._splats = None
        self._client_nodes: dict = {}
        check_port(host, port)
        from render.viewer.gl_worker import GLWorker

        self.worker = GLWorker(model)
        try:
            self.server = self._start_server(host, port)
        except BaseException:
            self.worker.close()
            raise

    # ------------------------------------------------------------------ server
    def _start_server(self, host: str, port: int):
        import viser

        server = viser.ViserServer(host=host, port=port, label="furrow", verbose=False)
        if port != 0 and server.get_port() != port:  # viser moved to another port: taken meanwhile
            server.stop()
            raise PortInUse(f"port {port} on {host} is in use (choose another with --port)")
        self.port = server.get_port()
        server.on_client_connect(self._connect)
        server.on_client_disconnect(self._disconnect)
        return server

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def frustum_specs(self) -> list[dict]:
        """The frustum of every capture camera (computed once): viser add_camera_frustum keyword
        arguments (vertical fov, aspect, pose as R_world_camera quaternion and position, a
        thumbnail of the capture image when the model holds one per camera)."""
        if self._frustums is None:
            from viser.transforms import SO3

            from capture.scan import to_uint8_srgb

            b = np.asarray(self.model.bounds, float)
            scale = FRUSTUM_SCALE * float(np.linalg.norm(b[1] - b[0]))
            rgb = getattr(self.model.rgbz, "rgb", None)
            self._frustums = []
            for i, cam in enumerate(self.cameras):
                thumb = None
                if rgb is not None and len(rgb) == len(self.cameras):
                    step = max(1, int(np.ceil(max(cam.width, cam.height) / FRUSTUM_THUMB)))
                    thumb = to_uint8_srgb(np.asarray(rgb[i])[::step, ::step])
                self._frustums.append(dict(
                    fov=float(2.0 * np.arctan(0.5 * cam.height / cam.K[1, 1])), aspect=cam.width / cam.height,
                    scale=scale, wxyz=SO3.from_matrix(cam.world_from_cam[:3, :3]).wxyz, position=cam.center,
                    image=thumb, format="jpeg", color=FRUSTUM_RGB, thickness=FRUSTUM_LINE_PX,
                    thickness_units="screen"))
        return self._frustums

    def _add_frustums(self, client) -> list:
        """The capture cameras as clickable frustums in ``client``'s own scene (each client shows
        or hides its own)."""
        handles = []
        for i, (cam, spec) in enumerate(zip(self.cameras, self.frustum_specs())):
            h = client.scene.add_camera_frustum(f"/capture/cam_{i:03d}", **spec)
            h.on_click(lambda event, cam=cam: self.snap(event.client, cam))
            handles.append(h)
        return handles

    def snap(self, client, cam) -> None:
        """Move ``client``'s view to look through capture camera ``cam``."""
        from capture.camera import viser_view

        dist = float(np.linalg.norm(np.asarray(self.model.bounds, float).mean(axis=0) - cam.center))
        v = viser_view(cam, max(dist, 1e-3))
        with client.atomic():
            client.camera.fov = v["fov"]
            client.camera.position = v["position"]
            client.camera.look_at = v["look_at"]
            client.camera.up_direction = v["up_direction"]

    # ------------------------------------------------------------------ clients
    def _connect(self, client) -> None:
        from render.viewer import gui

        controls = gui.build_controls(client.gui, self.settings, self.env_names)
        recent: list[dict] = []
        last_full: list[dict] = []
        still_count = [0]

        def send(image, jpeg_quality: int | None) -> None:
            if jpeg_quality is None:
                client.scene.set_background_image(image, format="png")
            else:
                client.scene.set_background_image(image, format="jpeg", jpeg_quality=jpeg_quality)

        def note(msg: str) -> None:
            controls.note.content = f"*{msg}*"
            controls.note.visible = True

        def frame_done(rec: dict) -> None:
            recent.append(rec)
            del recent[:-gui.READOUT_WINDOW]
            if not rec["moving"]:
                last_full[:] = [rec]
                still_count[0] += 1
                controls.note.visible = False
            level = f"pyramid level drawn: L = {rec['level']}" if "level" in rec else ""
            controls.readout.content = gui.readout_text(recent, last_full[0] if last_full else None, level,
                                                        still_count[0])

        session = Session(self.worker, send, self.settings, self.cfg, self.log, name=str(client.client_id),
                          on_note=note, on_frame=frame_done)
        gui.on_settings_change(controls, session.update_settings, note)
        frustums = self._add_frustums(client)
        controls.cameras.on_update(lambda _e: _show(frustums, controls.cameras.value))
        controls.screenshot.on_click(lambda _e: self._spawn(self.screenshot, client, session, note))
        splats_box = client.gui.add_checkbox("splats in the browser", False, hint=SPLATS_HINT)
        splats_box.on_update(lambda _e: self._spawn(self.client_splats, client, session, splats_box, note))
        controls.export.on_click(lambda _e: self._spawn(self.export, client, session, controls, note))

        def camera_update(cam) -> None:
            session.update_camera(ViewCamera(tuple(cam.wxyz), tuple(cam.position), float(cam.fov),
                                             int(cam.image_width), int(cam.image_height)))

        client.camera.on_update(camera_update)
        camera_update(client.camera)
        with self._lock:
            if self._closed:
                return
            self.sessions[client.client_id] = session.start()

    def _disconnect(self, client) -> None:
        with self._lock:
            session = self.sessions.pop(client.client_id, None)
        if session is not None:
            session.stop()

    def splats(self):
        """The model's 3D Gaussians (volume.splats.build_splats, built once, on first use)."""
        with self._lock:
            if self._splats is None:
                from volume.splats import build_splats

                self._splats = build_splats(self.model)
            return self._splats

    def client_splats(self, client, session: Session, box, note) -> None:
        """Show the splats drawn by the client itself (viser's Gaussian splat node: sorted and
        blended in the browser, one colour per Gaussian, their DC term) instead of the server's
        frames, or go back to the server's frames."""
        from volume.export_web import splat_node

        try:
            if box.value:
                note("building the splats...")
                node = client.scene.add_gaussian_splats(CLIENT_SPLATS_NODE, **splat_node(self.splats()))
                session.pause(True)
                client.scene.set_background_image(None)
                note(f"{len(self.splats())} splats drawn by the browser (view-independent colour)")
                self._client_nodes[client.client_id] = node
            else:
                node = self._client_nodes.pop(client.client_id, None)
                if node is not None:
                    node.remove()
                session.pause(False)
        except Exception as e:
            note(f"client-side splats failed: {type(e).__name__}: {e}")

    @staticmethod
    def _spawn(fn, *args) -> None:
        threading.Thread(target=fn, args=args, daemon=True).start()

    # ------------------------------------------------------------------ downloads
    def _render_full(self, session: Session, cam, settings: ViewSettings) -> np.ndarray:
        from render.viewer.views import draw

        drawn = self.worker.submit(lambda scene: draw(scene, cam, settings, settings.still_samples))
        return drawn.result(JOB_TIMEOUT_S).image

    def screenshot(self, client, session: Session, note) -> Path | None:
        """Render the client's view at full resolution, supersampled; save it under out_dir and
        send it to the client as a PNG download."""
        from capture.imageio import write_png

        vc, settings = session.camera, session.settings
        if vc is None:
            return None
        try:
            img = self._render_full(session, vc.camera(*vc.full_size(settings.max_lines)), settings)
            self.out_dir.mkdir(parents=True, exist_ok=True)
            path = self.out_dir / f"furrow_view_{len(list(self.out_dir.glob('furrow_view_*.png'))):03d}.png"
            write_png(path, img)
            client.send_file_download(path.name, path.read_bytes())
            return path
        except Exception as e:
            note(f"screenshot failed: {type(e).__name__}: {e}")
            return None

    def export_cameras(self, session: Session, kind: str, n: int) -> list:
        """The cameras of an export: a turntable of ``n`` frames from the client's current view
        around the rig's up axis through the object's centre, or the capture cameras in order."""
        from capture.orbit import estimate_up, orbit_cameras

        if kind == "capture path":
            return list(self.cameras)
        vc, settings = session.camera, session.settings
        cam = vc.camera(*vc.full_size(settings.max_lines))
        centre = np.asarray(self.model.bounds, float).mean(axis=0)
        return orbit_cameras([cam], n, center=centre, up=estimate_up(self.model.rgbz.cameras))

    def export(self, client, session: Session, controls, note) -> Path | None:
        """Render an export offline at full quality (progress bar in the client's GUI), write the
        MP4 under out_dir (render.composite.video.write_mp4) and send it as a download."""
        from render.composite.video import write_mp4

        if session.camera is None:
            return None
        settings = session.settings
        cams = self.export_cameras(session, controls.export_kind.value, int(controls.export_frames.value))
        controls.export.disabled = True
        controls.progress.value = 0.0
        controls.progress.visible = True

        def frames():
            for i, cam in enumerate(cams):
                yield self._render_full(session, cam, settings)
                controls.progress.value = 100.0 * (i + 1) / len(cams)

        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            name = controls.export_kind.value.replace(" ", "_")
            path = self.out_dir / f"furrow_{name}_{len(list(self.out_dir.glob('furrow_*.mp4'))):03d}.mp4"
            write_mp4(frames(), path, fps=float(controls.export_fps.value))
            client.send_file_download(path.name, path.read_bytes())
            return path
        except Exception as e:
            note(f"export failed: {type(e).__name__}: {e}")
            return None
        finally:
            controls.export.disabled = False
            controls.progress.visible = False

    # ------------------------------------------------------------------ shutdown
    def close(self, stats_path: Path | None = None) -> bool:
        """End every session, release the GL objects and the context, stop the server and write the
        frame log to ``stats_path``. Returns True when the GL thread released everything."""
        with self._lock:
            self._closed = True
            sessions = list(self.sessions.values())
            self.sessions.clear()
        for s in sessions:
            s.stop()
        released = self.worker.close()
        self.server.stop()
        if stats_path is not None:
            self.log.write(stats_path)
        return released and self.worker.released


def _show(handles, visible: bool) -> None:
    for h in handles:
        h.visible = bool(visible)
