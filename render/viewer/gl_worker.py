"""The one thread that owns the viewer's GL context and every GL object in it.

An EGL context is current in one thread at a time, and llvmpipe already spreads one frame over
all cores, so every client's session (render.viewer.session) hands its frames to this thread as
jobs: ``worker.submit(fn, wanted)`` runs ``fn(scene)`` here and returns a Future.  A job whose
``wanted()`` is false when its turn comes (a newer camera arrived) is dropped unrun; its Future
gets None.  :meth:`GLWorker.close` releases every renderer, the compositor and the context on
this thread, then ends it.

On a machine without a GPU the context is Mesa's llvmpipe, whose rasteriser threads take every
core by default; :func:`llvmpipe_threads` (``furrow view --gl-threads``) leaves one to the
browser, whose software WebGL decodes and draws every frame on the same cores (docs/viewer.md).
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Future

import numpy as np

from render.owner import GLOwner

#: Width (pixels) and supersampling of the warm-up frames of a new renderer.
WARM_UP_WIDTH = 64
WARM_UP_SUPERSAMPLE = 2
#: Seconds close() waits for the job in progress before giving up on the thread.
CLOSE_TIMEOUT_S = 30.0
#: Cores left to other processes (a browser on the same machine) by the default llvmpipe thread count.
FREE_CORES = 1
#: GL renderer names (GL_RENDERER, lower case) of software rasterisers: their frames cost CPU time.
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "swiftshader")


def is_software(ctx) -> bool:
    """Whether ``ctx`` rasterises on the CPU (Mesa llvmpipe and the like: SOFTWARE_RENDERERS)."""
    name = str(ctx.info.get("GL_RENDERER", "")).lower()
    return any(s in name for s in SOFTWARE_RENDERERS)


@contextlib.contextmanager
def llvmpipe_threads(threads: int | None = None) -> Iterator[int]:
    """``with llvmpipe_threads(n) as n:`` Mesa llvmpipe's rasteriser thread count
    (``LP_NUM_THREADS``) set for the block, restored after it.  Mesa reads it when the process
    makes its first GL context, so that context must be made inside (it keeps the count for the
    process's life; restoring only keeps it from child processes).  ``threads`` (>= 1), or by
    default the cores less FREE_CORES (at least 1); an ``LP_NUM_THREADS`` already in the
    environment is kept.  No effect on a GPU driver.  Yields the count in effect."""
    before = os.environ.get("LP_NUM_THREADS")
    if before is not None:
        yield int(before)
        return
    if threads is None:
        threads = max(1, (os.cpu_count() or 1) - FREE_CORES)
    if int(threads) < 1:
        raise ValueError(f"llvmpipe threads must be >= 1, got {threads}")
    os.environ["LP_NUM_THREADS"] = str(int(threads))
    try:
        yield int(threads)
    finally:
        os.environ.pop("LP_NUM_THREADS", None)


class GLScene(GLOwner):
    """The model's GL side, made on the GL thread: one renderer per method (created through the
    registry on first use, kept), the compositor, the environment maps (cached per name and
    rotation) and their spherical-Gaussian fits for the ground shadow (one per map, made once:
    seconds of work that composite_frame would otherwise redo every frame).

    Args:
        ctx: the context (owned by the GLWorker).
        model: a volume.model.Model.
    """

    def __init__(self, ctx, model) -> None:
        super().__init__(ctx)
        self.model = model
        self._renderers: dict = {}
        self._compositor = None
        self._envs: dict = {}
        self._fits: list = []  # (env, fit) pairs, looked up by the env's identity
        self.up = None

    def renderer(self, name: str):
        """The ``name`` method's renderer of the model (render.methods.create_renderer)."""
        self.check_alive()
        if name not in self._renderers:
            from render.methods import create_renderer

            r = self.own(create_renderer(name, self.ctx, self.model))
            self._warm_up(r)
            self._renderers[name] = r
        return self._renderers[name]

    def _warm_up(self, renderer) -> None:
        """Draw two tiny frames (one and WARM_UP_SUPERSAMPLE samples per pixel) so that the
        shaders are compiled before the first timed frame (llvmpipe compiles on first draw)."""
        cam = self.model.rgbz.cameras[0]
        cam = cam.scaled(min(1.0, WARM_UP_WIDTH / cam.width))
        for s in (1, WARM_UP_SUPERSAMPLE):
            renderer.render(cam, supersample=s)

    def compositor(self):
        """The environment compositor (one for every client)."""
        self.check_alive()
        if self._compositor is None:
            from render.viewer.views import make_compositor

            self._compositor = self.own(make_compositor(self.ctx))
        return self._compositor

    def envmap(self, name: str, rotation_deg: float = 0.0, convention: str = "furrow"):
        """The environment map ``name`` (bundled name or .exr/.hdr path, laid out in ``convention``) turned
        by ``rotation_deg`` about its up axis (cached: the compositor re-uploads only a new map)."""
        key = (name, float(rotation_deg), convention)
        if key not in self._envs:
            from render.shading.envmap import named_envmap

            self._envs[key] = named_envmap(name, convention, rotation_deg)
        return self._envs[key]

    def shadow_fit(self, env):
        """The SG fit of ``env`` that lights the ground shadow (render.composite.ground_shadow.shadow_sg_fit, as
        composite_frame fits it), made once per map."""
        for e, fit in self._fits:
            if e is env:
                return fit
        from render.composite.ground_shadow import shadow_sg_fit

        fit = shadow_sg_fit(env)
        self._fits.append((env, fit))
        return fit

    def rig_up(self) -> np.ndarray:
        """(3,) the capture rig's up direction (capture.orbit.estimate_up of the model's cameras)."""
        if self.up is None:
            from capture.orbit import estimate_up

            self.up = estimate_up(self.model.rgbz.cameras)
        return self.up


class GLWorker:
    """The GL thread (see the module docstring).

    Args:
        model: the model to draw.
        create_context: makes the context on the GL thread (default render.gl.create_context).
    Raises whatever creating the context raised (render.gl.GLUnavailable) from the constructor.
    """

    def __init__(self, model, create_context: Callable | None = None) -> None:
        if create_context is None:
            from render.gl import create_context
        self._model = model
        self._create = create_context
        self._jobs: queue.Queue = queue.Queue()
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self.scene: GLScene | None = None
        #: True on a software rasteriser (:func:`is_software`): the sessions model frame cost in CPU time.
        self.software = False
        self.released = False
        self._closing = False
        self._thread = threading.Thread(target=self._run, name="furrow-gl", daemon=True)
        self._thread.start()
        self._ready.wait()
        if self._error is not None:
            raise self._error

    def submit(self, fn: Callable, wanted: Callable[[], bool] | None = None) -> Future:
        """Run ``fn(scene)`` on the GL thread (in submission order); skip it (result None) when
        ``wanted()`` is false by then."""
        fut: Future = Future()
        if self._closing:
            fut.set_exception(RuntimeError("the GL worker is closed"))
            return fut
        self._jobs.put((fn, wanted, fut))
        return fut

    def call(self, fn: Callable, timeout: float | None = None):
        """``submit(fn).result(timeout)``."""
        return self.submit(fn).result(timeout)

    def _run(self) -> None:
        try:
            ctx = self._create()
        except BaseException as e:  # reported by the constructor
            self._error = e
            self._ready.set()
            return
        self.scene = GLScene(ctx, self._model)
        self.software = is_software(ctx)
        self._ready.set()
        try:
            while True:
                item = self._jobs.get()
                if item is None:
                    break
                fn, wanted, fut = item
                if not fut.set_running_or_notify_cancel():
                    continue
                if wanted is not None and not wanted():
                    fut.set_result(None)
                    continue
                try:
                    fut.set_result(fn(self.scene))
                except BaseException as e:  # handed to the waiting session
                    fut.set_exception(e)
        finally:
            self._drain()
            self.scene.release()
            ctx.release()
            self.released = True

    def _drain(self) -> None:
        while True:
            try:
                item = self._jobs.get_nowait()
            except queue.Empty:
                return
            if item is not None:
                item[2].cancel()

    def close(self, timeout: float = CLOSE_TIMEOUT_S) -> bool:
        """Release every GL object and the context (on the GL thread) and end it; idempotent.
        Returns True when the thread ended within ``timeout``."""
        self._closing = True
        if self._thread.is_alive():
            self._jobs.put(None)
            self._thread.join(timeout)
        return not self._thread.is_alive()
