"""The plain RGB-D point splatter of issue 11 as a rendering method (``points`` in render.methods).

Every kept pixel with a depth is a coloured world point; a frame splats the points of the
``N_VIEWS`` kept cameras nearest in viewing angle with a z-buffer in 2 x 2-pixel splats and
averages the colours within 4 mm of the front depth, weighted by 1 / angle
(``render/points/reference.py`` holds the algorithm, in vectorised numpy).  It is the baseline
every evaluation shows beside the microfacets: one sample per pixel whatever
``RenderOptions.supersample`` says (it reads no option), so it is exactly the splatter the issue
measured.
"""

from __future__ import annotations

import time

import numpy as np

from capture.camera import Camera
from render.crops import crop_f16
from render.frame import Frame, FrameStats
from render.methods import Renderer, RenderOptions
from render.points import reference as pr


class LazyClouds:
    """The views' clouds (render.points.reference.Cloud), each back-projected from its crop
    (render.crops.crop_f16) when first asked for: a frame reads only its ``N_VIEWS`` nearest."""

    def __init__(self, rgbz):
        self._rgbz = rgbz
        self._cams = tuple(rgbz.cameras)
        self._clouds: dict[int, pr.Cloud] = {}

    def __len__(self) -> int:
        return len(self._cams)

    def __getitem__(self, i) -> pr.Cloud:
        i = int(i)
        if i not in self._clouds:
            self._clouds[i] = pr.back_project_crop(self._cams[i], *crop_f16(self._rgbz, i))
        return self._clouds[i]

    @property
    def loaded(self) -> int:
        """Views back-projected so far."""
        return len(self._clouds)


class PointsRenderer(Renderer):
    """The point splatter of one model (numpy; owns no GL object).

    Args:
        ctx: moderngl context (unused: the interface of every method).
        rgbz: the kept views (volume.model.RgbzImages), back-projected one crop at a time
            (``rgbz.crop(n)``, float16 values: render.crops.crop_f16); with a matte the points
            carry premultiplied colour + alpha and the frame the averaged alpha.
        bounds: (2, 3) object box; its centre is where viewing angles are measured.
        options: default per-frame options (none is read).
    """

    name = "points"

    def __init__(self, ctx, rgbz, bounds, options: RenderOptions | None = None):
        super().__init__(ctx, options)
        self.cameras = tuple(rgbz.cameras)
        if not self.cameras:
            raise ValueError("points renderer: the model has no input camera")
        self.centre = np.asarray(bounds, np.float64).mean(axis=0)
        self.clouds = LazyClouds(rgbz)

    @classmethod
    def from_model(cls, ctx, model, options: RenderOptions | None = None) -> PointsRenderer:
        """Splatter of a volume.model.Model's RGBz images (its kept views and their depth), read
        crop by crop (render.crops): never the full stacks."""
        return cls(ctx, model.rgbz, model.bounds, options)

    def _render(self, eye: Camera, options: RenderOptions, read: bool) -> Frame:
        t0, c0 = time.perf_counter(), time.process_time()
        rgb, cov, depth, n = pr.points_frame(eye, self.clouds, self.cameras, self.centre)
        stats = FrameStats((time.perf_counter() - t0) * 1e3, (time.process_time() - c0) * 1e3, supersample=1,
                           facets=n)
        if not read:
            return Frame.empty(eye.width, eye.height, stats)
        return Frame(rgb, cov, depth, stats)
