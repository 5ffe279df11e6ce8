"""What every renderer returns: one :class:`Frame` (rgb, alpha, depth, stats).

Clients (``furrow render``, ``furrow eval``, the benchmarks, the viewer, batch) read only these
fields, whatever the method (``render.methods``).  What every method reports is the time and the
samples per pixel; a count of primitives drawn (``facets``) is optional, and a method with more to
report subclasses :class:`FrameStats` (the microfacets add the level, resolution and slice spacing).
"""

from __future__ import annotations

from dataclasses import KW_ONLY, dataclass

import numpy as np

from capture.camera import gl_ndc_depth_to_z, gl_rows_to_image


def straight_colour(premult: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32 straight colour of a premultiplied one: premult / alpha where alpha > 0,
    else 0."""
    a = np.asarray(alpha, np.float32)[..., None]
    return np.where(a > 0, np.asarray(premult, np.float32) / np.maximum(a, np.float32(1e-12)), 0.0).astype(np.float32)


def composite_over(premult: np.ndarray, alpha: np.ndarray, background) -> np.ndarray:
    """(H, W, 3) float32 ``premult + (1 - alpha) background`` in linear light (Porter-Duff over;
    ``background`` a (3,) colour or an (H, W, 3) image)."""
    bg = np.asarray(background, np.float32)
    return (np.asarray(premult, np.float32) + (1.0 - np.asarray(alpha, np.float32))[..., None] * bg).astype(np.float32)


@dataclass(frozen=True)
class FrameStats:
    """The cost of one frame.

    Attributes:
        ms: wall time of the frame's GL work in milliseconds, synchronised (ctx.finish() before
            and after), read-back excluded.
        cpu_ms: process CPU time over the same interval (llvmpipe's threads included): the cost
            independent of other load on the machine.
        supersample: samples per pixel and axis the frame was drawn with (keyword).
        facets: primitives drawn (microfacet slices, mesh triangles, points), for a method that
            counts them; None = not reported (keyword).
        alpha_pull: the pull d gather gave the frame's coverage, alpha a - d a (1 - a) and the colour with it
            (render.gather.alpha_mass; 0 = as drawn), for a method that holds its alpha's mass; None = not reported
            (keyword).
        fine_depth: 1 where the frame's depth took 1-pixel splats first, 0 where not (render.gather.fine_depth), for a
            method that decides it; None = not reported (keyword).
        partial_share: the share of the model's matte pixels that are partial, on which "auto" decided that
            (render.gather.fine_depth.partial_share; NaN without a matte); None = not reported (keyword).
    """

    ms: float
    cpu_ms: float
    _: KW_ONLY
    supersample: int
    facets: int | None = None
    alpha_pull: float | None = None
    fine_depth: float | None = None
    partial_share: float | None = None

    def record(self) -> dict:
        """The numbers as a flat JSON-ready dict (per-frame records of render_stats.json and of
        ``furrow eval``); ``facets``, ``alpha_pull``, ``fine_depth`` and ``partial_share`` only where the method
        reports them."""
        out = {"ms": float(self.ms), "cpu_ms": float(self.cpu_ms), "supersample": int(self.supersample)}
        if self.facets is not None:
            out["facets"] = int(self.facets)
        for k in ("alpha_pull", "fine_depth", "partial_share"):
            if getattr(self, k) is not None:
                out[k] = float(getattr(self, k))
        return out


@dataclass(frozen=True)
class Frame:
    """One rendered frame (image rows top first).

    Attributes:
        rgb: (H, W, 3) float32 linear colour, PREMULTIPLIED by ``alpha`` (i.e. the frame over
            black; black = nothing drawn; with supersampling the mean over the pixel's samples).
        alpha: (H, W) float32 in [0, 1], the soft matte: the share of the pixel's samples drawn
            times the opacity the method gives them (a model with a matte, volume.model.RgbzImages
            .alpha, gives fringe pixels a partial alpha; without one a single-sample frame is 0 / 1).
        depth: (H, W) float32 z-depth in metres of the nearest drawn sample, 0 where nothing
            was drawn.
        stats: the frame's cost (:class:`FrameStats` or a method's subclass).

    Compositing over a background B (linear, same units) is ``rgb + (1 - alpha) B``
    (:meth:`over`); the straight colour PNG stores is ``rgb / alpha`` (:meth:`straight`).
    """

    rgb: np.ndarray
    alpha: np.ndarray
    depth: np.ndarray
    stats: FrameStats

    def __post_init__(self) -> None:
        rgb = np.ascontiguousarray(self.rgb, dtype=np.float32)
        cov = np.ascontiguousarray(self.alpha, dtype=np.float32)
        dep = np.ascontiguousarray(self.depth, dtype=np.float32)
        if rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f"frame rgb must be (H, W, 3), got {rgb.shape}")
        if cov.shape != rgb.shape[:2] or dep.shape != rgb.shape[:2]:
            raise ValueError(f"frame alpha {cov.shape} and depth {dep.shape} must be {rgb.shape[:2]}")
        object.__setattr__(self, "rgb", rgb)
        object.__setattr__(self, "alpha", cov)
        object.__setattr__(self, "depth", dep)

    @property
    def mask(self) -> np.ndarray:
        """(H, W) bool foreground: alpha > 0 (something drawn)."""
        return self.alpha > 0

    def straight(self) -> np.ndarray:
        """(H, W, 3) float32 straight (un-premultiplied) colour: rgb / alpha, 0 where alpha = 0."""
        return straight_colour(self.rgb, self.alpha)

    def over(self, background) -> np.ndarray:
        """(H, W, 3) float32 the frame composited over ``background`` (a linear (3,) colour or an
        (H, W, 3) image): rgb + (1 - alpha) background."""
        return composite_over(self.rgb, self.alpha, background)

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return self.rgb.shape[1], self.rgb.shape[0]

    @classmethod
    def empty(cls, width: int, height: int, stats: FrameStats) -> Frame:
        """A frame with nothing read back (timing-only renders): black, uncovered, no depth."""
        return cls(np.zeros((height, width, 3), np.float32), np.zeros((height, width), np.float32),
                   np.zeros((height, width), np.float32), stats)

    @classmethod
    def from_gl(cls, rgba: np.ndarray, depth01: np.ndarray, near: float, far: float, stats: FrameStats) -> Frame:
        """Frame from a resolved read-back in framebuffer row order (render.owner.GLOwner.read_frame):
        (H, W, 4) premultiplied colour with the alpha in alpha, (H, W) window depth in [0, 1] of the
        projection with planes ``near`` / ``far``."""
        img = gl_rows_to_image(rgba)
        alpha = img[..., 3]
        depth = gl_ndc_depth_to_z(gl_rows_to_image(depth01), near, far).astype(np.float32)
        depth[alpha <= 0] = 0.0
        return cls(img[..., :3], alpha, depth, stats)
