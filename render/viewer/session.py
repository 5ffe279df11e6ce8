"""One browser client: its render thread, fed by camera and settings updates.

The thread follows render.viewer.adaptive: while the camera moves it draws reduced frames of the
*latest* camera (read when the GL thread takes the job, so a queue never shows an old view) at
the size that holds the frame budget, one sample per pixel, sent as lower-quality JPEG, at most
``max_fps`` a second (AdaptiveConfig); once the camera has been still for ``still_s`` it draws the
full-size frame (one sample per pixel), then the supersampled one, the last still frame sent as
PNG, unless the camera moved meanwhile (then the stale frame is dropped).  Each frame's time is
measured per stage (queued, render, convert, send: the cost model of the frame size, and the
``--stats`` record).  Every frame sent is recorded in the shared :class:`FrameLog`
(``furrow view --stats``).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from concurrent.futures import CancelledError
from dataclasses import dataclass

from capture.camera import Camera, camera_from_viser
from render.viewer.adaptive import (
    AdaptiveConfig,
    Sample,
    add_sample,
    choose_scale,
    fixed_costs,
    frame_size,
    next_action,
)
from render.viewer.settings import ViewSettings

#: JPEG quality of moving frames, and of the full frame when a supersampled one follows (the
#: last still frame goes out as PNG: lossless, but ~10x slower to encode).
MOVING_JPEG_QUALITY = 60
FULL_JPEG_QUALITY = 92
#: Seconds stop() waits for the thread.
STOP_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class ViewCamera:
    """A client's camera as viser reports it: R_world_camera quaternion ``wxyz``, ``position``
    (m), vertical ``fov`` (radians) and canvas ``width`` x ``height`` (pixels)."""

    wxyz: tuple
    position: tuple
    fov: float
    width: int
    height: int

    def camera(self, width: int, height: int) -> Camera:
        """The furrow Camera of this view drawn at ``width`` x ``height`` pixels."""
        return camera_from_viser(self.wxyz, self.position, self.fov, width, height)

    def full_size(self, max_lines: int) -> tuple[int, int]:
        """The full frame's size: the canvas, scaled down to at most ``max_lines`` lines."""
        if self.height <= max_lines:
            return int(self.width), int(self.height)
        s = max_lines / self.height
        return max(1, round(self.width * s)), int(max_lines)


def transport_quality(kind: str, settings: ViewSettings) -> int | None:
    """JPEG quality a frame of ``kind`` is sent with, or None for PNG (the last still frame)."""
    if kind == "moving":
        return MOVING_JPEG_QUALITY
    if kind == "full" and settings.still_samples > 1:
        return FULL_JPEG_QUALITY
    return None


class FrameLog:
    """Thread-safe record of every frame sent (``furrow view --stats``): ``t`` (s since start),
    ``ms`` (the renderer's GL time), ``total_ms`` (job submitted -> image handed to the client)
    and its stages ``wait_ms`` (queued behind other jobs on the GL thread), ``render_ms`` (the
    renderer: draw, read back), ``convert_ms`` (to the 8-bit picture) and ``send_ms`` (encoding
    and hand-off to the client), with the process CPU time of the last three (``render_cpu_ms``,
    ``convert_cpu_ms``, ``send_cpu_ms``), ``width``, ``height``, ``moving``, ``method``, ``client``, for full frames
    ``since_change_s`` (last camera/settings change -> full frame sent) and ``refined``
    (supersampled), and the renderer's own
    figures (``FrameStats.record()``: cpu_ms, facets, supersample, a method's level...)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._t0 = clock()
        self._lock = threading.Lock()
        self._frames: list[dict] = []

    def now(self) -> float:
        return self._clock() - self._t0

    def add(self, record: dict) -> dict:
        """Append ``record`` with its time ``t``; returns the stored record."""
        rec = {"t": round(self.now(), 4), **record}
        with self._lock:
            self._frames.append(rec)
        return rec

    def frames(self) -> list[dict]:
        with self._lock:
            return list(self._frames)

    def write(self, path) -> None:
        """Write ``{"frames": [...]}`` to ``path`` atomically."""
        from capture.atomic import write_json

        write_json(path, {"frames": self.frames()})


class Session:
    """The render thread of one client.

    Args:
        worker: the GL thread (render.viewer.gl_worker.GLWorker).
        send: ``send(image, jpeg_quality)`` hands an (H, W, 3) uint8 picture to the client, as
            JPEG of that quality, or PNG when it is None.
        settings: the client's initial ViewSettings.
        cfg: the adaptive-resolution knobs.
        log: where frames are recorded (a FrameLog), or None.
        name: client label in the log.
        on_note: called with a one-line message when a view cannot be drawn or a frame failed.
        on_frame: called with each record after its frame was sent (the fps readout).
    """

    def __init__(self, worker, send: Callable, settings: ViewSettings | None = None,
                 cfg: AdaptiveConfig | None = None, log: FrameLog | None = None, name: str = "",
                 on_note: Callable[[str], None] | None = None, on_frame: Callable[[dict], None] | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.worker = worker
        self.send = send
        self.cfg = cfg or AdaptiveConfig()
        self.log = log
        self.name = name
        self.on_note = on_note or (lambda msg: None)
        self.on_frame = on_frame or (lambda rec: None)
        self.clock = clock
        self._cond = threading.Condition()
        self._settings = settings or ViewSettings()
        self._camera: ViewCamera | None = None
        self._version = 0
        self._last_change = clock()
        self._moving_done = -1
        self._full_done = -1
        self._refined_done = -1
        self._history: list[Sample] = []
        self._fixed: tuple | None = None
        self._scale: float | None = None
        self._moving_started: float | None = None
        self._stopped = False
        self._paused = False
        self._thread = threading.Thread(target=self._loop, name=f"furrow-view-{name}", daemon=True)

    # ------------------------------------------------------------------ inputs
    def start(self) -> Session:
        self._thread.start()
        return self

    def update_camera(self, camera: ViewCamera) -> None:
        """A new camera from the client (any thread)."""
        with self._cond:
            self._camera = camera
            self._changed()

    def update_settings(self, settings: ViewSettings) -> None:
        """New settings from the client's GUI (any thread)."""
        with self._cond:
            self._settings = settings
            self._history, self._fixed = [], None  # another method / view / size cap: another cost
            self._changed()

    def pause(self, paused: bool) -> None:
        """Stop drawing frames (the client draws the model itself: client-side splats) or resume
        (a new frame of the current view follows)."""
        with self._cond:
            self._paused = bool(paused)
            self._changed()

    @property
    def settings(self) -> ViewSettings:
        with self._cond:
            return self._settings

    @property
    def camera(self) -> ViewCamera | None:
        with self._cond:
            return self._camera

    def _changed(self) -> None:
        self._version += 1
        self._last_change = self.clock()
        self._cond.notify_all()

    def stop(self, timeout: float = STOP_TIMEOUT_S) -> None:
        """End the thread (a frame in progress on the GL thread is finished and dropped)."""
        with self._cond:
            self._stopped = True
            self._cond.notify_all()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    # ------------------------------------------------------------------ loop
    def _next(self):
        """Block until there is something to draw; (kind, version) or None when stopped."""
        with self._cond:
            while not self._stopped:
                act = next_action(self.clock(), self._version, self._last_change, self._moving_done,
                                  self._full_done, self._refined_done, self._settings.still_samples > 1,
                                  self.cfg, self._moving_started)
                if act.kind != "wait" and self._camera is not None and not self._paused:
                    return act.kind, self._version
                self._cond.wait(act.wait_s if self._camera is not None and not self._paused else None)
            return None

    def _job(self, kind: str, version: int):
        """The GL-thread job of a frame: reads the latest camera when it runs."""
        from render.viewer.views import draw

        def job(scene):
            started, cpu0 = self.clock(), time.process_time()
            with self._cond:
                v, cam, settings = self._version, self._camera, self._settings
                scale = (choose_scale(self._history, self._full_px(cam, settings), self.cfg, self._scale, self._fixed)
                         if kind == "moving" else 1.0)
                if kind == "moving":
                    self._moving_started = started
            if kind != "moving" and v != version or self._stopped:
                return None  # stale still frame: dropped unrun
            full = cam.full_size(settings.max_lines)
            size = frame_size(full, scale) if kind == "moving" else full
            ss = settings.still_samples if kind == "refine" else 1
            drawn = draw(scene, cam.camera(*size), settings, ss, draft=kind == "moving")
            return v, scale, settings, drawn, (started, cpu0, self.clock(), time.process_time())

        return job

    @staticmethod
    def _full_px(cam: ViewCamera, settings: ViewSettings) -> int:
        w, h = cam.full_size(settings.max_lines)
        return w * h

    def _loop(self) -> None:
        while True:
            nxt = self._next()
            if nxt is None:
                return
            kind, version = nxt
            t0 = self.clock()
            try:
                out = self.worker.submit(self._job(kind, version)).result()
            except CancelledError:
                return
            except Exception as e:  # a failed frame: say why, do not retry this version
                self.on_note(f"frame failed: {type(e).__name__}: {e}")
                with self._cond:
                    self._moving_done = self._full_done = self._refined_done = version
                continue
            if out is None:
                continue
            self._deliver(kind, t0, *out)

    def _deliver(self, kind: str, t0: float, version: int, scale: float, settings: ViewSettings, drawn,
                 marks: tuple) -> None:
        """Send a drawn frame (unless stale), record it and teach the cost model; ``marks``: the
        job's (start, start CPU, end, end CPU) clocks (s)."""
        started, cpu0, drawn_t, cpu1 = marks
        with self._cond:
            if self._stopped or (kind != "moving" and version != self._version):
                return  # the camera moved while the still frame was drawn: drop it
        moving = kind == "moving"
        try:
            self.send(drawn.image, transport_quality(kind, settings))
        except Exception as e:  # the client went away mid-frame
            self.on_note(f"could not send a frame: {type(e).__name__}: {e}")
            return
        sent, cpu2 = self.clock(), time.process_time()
        h, w = drawn.image.shape[:2]
        convert, convert_cpu = float(drawn.stages.get("convert", 0.0)), float(drawn.stages.get("convert_cpu", 0.0))
        stages = {"wait_ms": (started - t0) * 1e3, "render_ms": (drawn_t - started) * 1e3 - convert,
                  "convert_ms": convert, "send_ms": (sent - drawn_t) * 1e3,
                  "render_cpu_ms": (cpu1 - cpu0) * 1e3 - convert_cpu, "convert_cpu_ms": convert_cpu,
                  "send_cpu_ms": (cpu2 - cpu1) * 1e3}
        rec = {**drawn.stats.record(), "ms": round(float(drawn.stats.ms), 2), "total_ms": round((sent - t0) * 1e3, 2),
               **{k: round(v, 2) for k, v in stages.items()},
               "width": w, "height": h, "moving": moving, "method": settings.method, "client": self.name}
        cpu = (stages["render_cpu_ms"], stages["convert_cpu_ms"], stages["send_cpu_ms"])
        sample = Sample(w * h, (stages["render_ms"], stages["convert_ms"], stages["send_ms"]), moving,
                        cpu if getattr(self.worker, "software", False) else None)
        with self._cond:
            if settings is self._settings and (moving or drawn.stats.supersample == 1):
                self._history = add_sample(self._history, sample)
                self._fixed = fixed_costs(self._history, self._fixed)
            if moving:
                self._scale = scale
                self._moving_done = version
            else:
                rec["since_change_s"] = round(sent - self._last_change, 4)
                rec["refined"] = kind == "refine"
                self._moving_done = self._full_done = version
                if kind == "refine" or drawn.stats.supersample == settings.still_samples:
                    self._refined_done = version
        if drawn.note:
            self.on_note(drawn.note)
        rec = self.log.add(rec) if self.log is not None else {"t": round(sent, 4), **rec}
        self.on_frame(rec)
