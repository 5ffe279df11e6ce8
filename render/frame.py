"""What every renderer returns: one :class:`Frame` (rgb, coverage, depth, stats).

Clients (``furrow render``, ``furrow eval``, the benchmarks, the viewer, batch) read only these
fields, whatever the method (``render.methods``).  A method with more to report subclasses
:class:`FrameStats` (the microfacets add the level, resolution and slice spacing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import gl_ndc_depth_to_z, gl_rows_to_image


@dataclass(frozen=True)
class FrameStats:
    """The cost of one frame.

    Attributes:
        ms: wall time of the frame's GL work in milliseconds, synchronised (ctx.finish() before
            and after), read-back excluded.
        cpu_ms: process CPU time over the same interval (llvmpipe's threads included): the cost
            independent of other load on the machine.
        facets: primitives drawn (microfacet slices, mesh triangles).
        supersample: samples per pixel and axis the frame was drawn with.
    """

    ms: float
    cpu_ms: float
    facets: int
    supersample: int

    def record(self) -> dict:
        """The numbers as a flat JSON-ready dict (per-frame records of render_stats.json and of
        ``furrow eval``)."""
        return {"ms": float(self.ms), "cpu_ms": float(self.cpu_ms), "facets": int(self.facets),
                "supersample": int(self.supersample)}


@dataclass(frozen=True)
class Frame:
    """One rendered frame (image rows top first).

    Attributes:
        rgb: (H, W, 3) float32 linear colour, premultiplied over black (black = nothing drawn;
            with supersampling the mean over the pixel's samples).
        coverage: (H, W) float32 in [0, 1], the share of the pixel's samples drawn (0 or 1
            with one sample).
        depth: (H, W) float32 z-depth in metres of the nearest drawn sample, 0 where nothing
            was drawn.
        stats: the frame's cost (:class:`FrameStats` or a method's subclass).
    """

    rgb: np.ndarray
    coverage: np.ndarray
    depth: np.ndarray
    stats: FrameStats

    def __post_init__(self) -> None:
        rgb = np.ascontiguousarray(self.rgb, dtype=np.float32)
        cov = np.ascontiguousarray(self.coverage, dtype=np.float32)
        dep = np.ascontiguousarray(self.depth, dtype=np.float32)
        if rgb.ndim != 3 or rgb.shape[2] != 3:
            raise ValueError(f"frame rgb must be (H, W, 3), got {rgb.shape}")
        if cov.shape != rgb.shape[:2] or dep.shape != rgb.shape[:2]:
            raise ValueError(f"frame coverage {cov.shape} and depth {dep.shape} must be {rgb.shape[:2]}")
        object.__setattr__(self, "rgb", rgb)
        object.__setattr__(self, "coverage", cov)
        object.__setattr__(self, "depth", dep)

    @property
    def alpha(self) -> np.ndarray:
        """(H, W) bool foreground: any sample drawn."""
        return self.coverage > 0

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
        (H, W, 4) colour with the coverage in alpha, (H, W) window depth in [0, 1] of the
        projection with planes ``near`` / ``far``."""
        img = gl_rows_to_image(rgba)
        coverage = img[..., 3]
        depth = gl_ndc_depth_to_z(gl_rows_to_image(depth01), near, far).astype(np.float32)
        depth[coverage <= 0] = 0.0
        return cls(img[..., :3], coverage, depth, stats)
