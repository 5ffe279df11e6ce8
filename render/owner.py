"""The one base of every object that owns GL resources, and the helpers every renderer shares.

A :class:`GLOwner` is built from an explicit moderngl context (never released here: its creator
owns it, ``render.gl.gl_context``).  Every GL object it creates is registered with :meth:`own`
and freed by :meth:`release` -- idempotent, and called on leaving a ``with`` block; using an
owner after that raises ``released_error`` (a class attribute, so each family keeps its error
type).  Written once here, used by every renderer:

* :func:`mat4_bytes`: a numpy (4, 4) matrix as the column-major float32 bytes of a GLSL mat4;
* :func:`near_far`: the near / far planes of a view of an object box;
* :meth:`GLOwner.target`: the framebuffer cache (float32 colour textures + a depth texture,
  the few most recent sizes kept);
* :meth:`GLOwner.begin_frame` / :meth:`GLOwner.resolve_frame` / :meth:`GLOwner.read_frame`:
  a frame drawn with S x S samples per pixel and box-resolved on the GPU (``render.antialias``);
* :class:`FrameTimer`: synchronised wall and process-CPU time of the GL work of a frame;
* :func:`vertex_format`: the interleaved attribute layout of a program (removed attributes
  become padding).
"""

from __future__ import annotations

import time
from collections import OrderedDict
from typing import NamedTuple

import numpy as np

from capture.camera import Camera

#: Near/far planes: the box's eye-depth range grown by this share of its diagonal at both ends.
NEAR_FAR_MARGIN = 0.05
#: Near plane when the eye is inside the box (or the box reaches behind it): this share of the
#: box diagonal.
NEAR_FRACTION_INSIDE = 1e-3
#: Render targets kept per owner (most recently used first); older sizes are released.  Gather's frame
#: uses four (front z, second layer z and colour, colour), and the viewer alternates two sizes (moving, still).
MAX_TARGETS = 8


def mat4_bytes(m: np.ndarray) -> bytes:
    """Row-major numpy (4, 4) -> column-major float32 bytes for a GLSL ``mat4`` uniform."""
    return np.ascontiguousarray(np.asarray(m, dtype=np.float32).T).tobytes()


def near_far(eye: Camera, bounds: np.ndarray) -> tuple[float, float]:
    """Near / far planes (metres) of ``eye`` that hold the (2, 3) box ``bounds``: its eye-depth
    range grown by NEAR_FAR_MARGIN of the diagonal; near is NEAR_FRACTION_INSIDE of the diagonal
    when the eye is inside the box or the box reaches that close.  The microfacets also drop
    slices nearer than ``near`` (microfacet_common.glsl ``near_plane``)."""
    b = np.asarray(bounds, dtype=np.float64)
    corners = np.array([[b[i, 0], b[j, 1], b[k, 2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    z = eye.world_to_cam(corners)[:, 2]
    diag = float(np.linalg.norm(b[1] - b[0]))
    far = max(float(z.max()), 0.0) + NEAR_FAR_MARGIN * diag + 1e-6
    inside = np.all(eye.center >= b[0]) and np.all(eye.center <= b[1])
    near = float(z.min()) - NEAR_FAR_MARGIN * diag
    if inside or near <= NEAR_FRACTION_INSIDE * diag:
        near = NEAR_FRACTION_INSIDE * diag
    far = max(far, 2 * near)
    return near, far


def vertex_format(prog, attributes) -> tuple[str, list[str]]:
    """Buffer format and attribute names of an interleaved float vertex buffer with
    ``attributes`` ((name, float count), ...) for ``prog``: attributes the compiler removed
    become padding."""
    fmt, names = [], []
    for name, n in attributes:
        if name in prog:
            fmt.append(f"{n}f")
            names.append(name)
        else:
            fmt.append(f"{4 * n}x")
    return " ".join(fmt), names


class Target(NamedTuple):
    """A framebuffer and its attachments: float32 colour textures (``colours``) and a depth
    texture (``depth``, None when made without)."""

    fbo: object
    colours: tuple
    depth: object | None

    @property
    def size(self) -> tuple[int, int]:
        return tuple(self.fbo.size)

    def read_colour(self, index: int = 0) -> np.ndarray:
        """(H, W[, C]) float32 colour attachment ``index`` in framebuffer row order (bottom first)."""
        tex = self.colours[index]
        W, H = tex.size
        a = np.frombuffer(tex.read(), np.float32)
        return a.reshape(H, W, tex.components) if tex.components > 1 else a.reshape(H, W)

    def read_depth(self) -> np.ndarray:
        """(H, W) float32 window depth in [0, 1] (1 = cleared), framebuffer row order."""
        W, H = self.depth.size
        return np.frombuffer(self.depth.read(), np.float32).reshape(H, W)

    def release(self) -> None:
        self.fbo.release()
        for t in self.colours:
            t.release()
        if self.depth is not None:
            self.depth.release()


class FrameTimer:
    """``with FrameTimer(ctx) as t:`` the GL work inside, synchronised (``ctx.finish()`` on
    entry and exit); then ``t.ms`` (wall) and ``t.cpu_ms`` (process CPU time, llvmpipe's threads
    included: the cost independent of other load on the machine).

    With ``laps=True``, ``t.lap(name)`` synchronises and books the wall / CPU time since the
    previous lap (or the start) under ``name``: the per-pass breakdown ``t.laps``
    ({name: (ms, cpu_ms)}, summed over repeated names).  Without, ``lap`` does nothing (no
    synchronisation inside the frame)."""

    def __init__(self, ctx, laps: bool = False) -> None:
        self.ctx = ctx
        self.ms = self.cpu_ms = 0.0
        self.timing_laps = bool(laps)
        self.laps: dict[str, tuple[float, float]] = {}

    def __enter__(self) -> FrameTimer:
        self.ctx.finish()
        self._t0 = self._lt = time.perf_counter()
        self._c0 = self._lc = time.process_time()
        return self

    def lap(self, name: str) -> None:
        if not self.timing_laps:
            return
        self.ctx.finish()
        t, c = time.perf_counter(), time.process_time()
        ms, cpu = self.laps.get(name, (0.0, 0.0))
        self.laps[name] = (ms + (t - self._lt) * 1e3, cpu + (c - self._lc) * 1e3)
        self._lt, self._lc = t, c

    def __exit__(self, *exc) -> None:
        self.ctx.finish()
        self.ms = (time.perf_counter() - self._t0) * 1e3
        self.cpu_ms = (time.process_time() - self._c0) * 1e3


class GLOwner:
    """Base of every owner of GL objects (see the module docstring).

    Subclasses call ``super().__init__(ctx)`` first, register what they create with
    :meth:`own` (or replace it with :meth:`free` + :meth:`own`), and call
    :meth:`check_alive` at the top of their public methods.
    """

    #: Exception raised when an owner is used after release().
    released_error: type[Exception] = RuntimeError

    def __init__(self, ctx) -> None:
        self.ctx = ctx
        self._owned: list = []
        self._targets: OrderedDict = OrderedDict()
        self._resolver = None
        self._frame = None  # (width, height, factor, big target, resolved target or None)
        self._released = False

    # ------------------------------------------------------------------ lifecycle
    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.release()

    @property
    def alive(self) -> bool:
        """False once release() ran."""
        return not self._released

    def check_alive(self) -> None:
        if self._released:
            raise self.released_error(f"{type(self).__name__} used after release()")

    def own(self, obj):
        """Register ``obj`` (a GL object or another owner) to be released with this owner."""
        self._owned.append(obj)
        return obj

    def free(self, *objs) -> None:
        """Release the given owned objects now (None entries are skipped)."""
        for o in objs:
            if o is None:
                continue
            self._owned = [x for x in self._owned if x is not o]
            o.release()

    def release(self) -> None:
        """Free every GL object of this owner (idempotent)."""
        if self._released:
            return
        self._released = True
        for t in self._targets.values():
            t.release()
        self._targets.clear()
        self._frame = None
        for o in reversed(self._owned):
            o.release()
        self._owned.clear()

    # ------------------------------------------------------------------ targets
    def target(self, width: int, height: int, colours: tuple[int, ...] = (4,), depth: bool = True,
               name: str = "") -> Target:
        """The cached framebuffer of this size and layout: one float32 colour texture per entry of
        ``colours`` (its component count) and, if ``depth``, a depth texture (NEAREST filtering,
        so they can be fetched by the resolve); ``name`` tells apart two targets of one layout that a
        frame needs at once."""
        key = (int(width), int(height), tuple(colours), bool(depth), str(name))
        if key in self._targets:
            self._targets.move_to_end(key)
            return self._targets[key]
        ctx = self.ctx
        cols = tuple(ctx.texture((key[0], key[1]), c, dtype="f4") for c in key[2])
        dep = ctx.depth_texture((key[0], key[1])) if depth else None
        for t in cols + ((dep,) if dep is not None else ()):
            t.filter = (ctx.NEAREST, ctx.NEAREST)
        tgt = Target(ctx.framebuffer(list(cols), dep), cols, dep)
        self._targets[key] = tgt
        while len(self._targets) > MAX_TARGETS:
            self._targets.popitem(last=False)[1].release()
        return tgt

    # ------------------------------------------------------------------ supersampled frames
    def begin_frame(self, width: int, height: int, factor: int = 1, colours: tuple[int, ...] = (4,)) -> Target:
        """Bind, clear (colour 0, depth 1) and return the target of a ``width`` x ``height`` frame
        drawn with ``factor`` x ``factor`` samples per pixel (the target is ``factor`` times the
        size: draw with ``camera.scaled(factor)``); depth test on, everything else off.
        Colour attachment 0 must hold rgb premultiplied over black and the coverage in alpha."""
        from render.antialias import check_factor

        f = check_factor(factor)
        tgt = self.target(width * f, height * f, colours)
        tgt.fbo.use()
        self.ctx.viewport = (0, 0, width * f, height * f)
        tgt.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        self.ctx.enable_only(self.ctx.DEPTH_TEST)
        self.ctx.depth_func = "<"
        self._frame = (width, height, f, tgt, None)
        return tgt

    def resolve_frame(self) -> None:
        """Box-resolve the frame on the GPU (render.antialias; nothing to do with one sample)."""
        width, height, f, big, _ = self._frame
        if f == 1:
            return
        if self._resolver is None:
            from render.antialias import Resolver

            self._resolver = self.own(Resolver(self.ctx))
        self._frame = (width, height, f, big, self._resolver.resolve(big, f))

    def read_frame(self) -> tuple[np.ndarray, np.ndarray]:
        """The resolved frame in framebuffer row order: (H, W, 4) float32 colour (rgb over black,
        alpha = share of the samples drawn) and (H, W) float32 window depth of the nearest sample
        (1 = nothing drawn)."""
        _, _, f, big, small = self._frame
        if f == 1:
            return big.read_colour(0), big.read_depth()
        if small is None:
            raise RuntimeError("read_frame() before resolve_frame()")
        return small.read_colour(0), small.read_colour(1)

    def frame_samples(self) -> tuple[np.ndarray, np.ndarray]:
        """The last frame's unresolved samples (twin tests): (H f, W f, 4) colour and (H f, W f)
        window depth, framebuffer row order."""
        big = self._frame[3]
        return big.read_colour(0), big.read_depth()
