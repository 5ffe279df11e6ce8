"""A short refinement of the Gaussians' opacities against the kept views' mattes (``furrow export
--splats OUT --refine N``; issue 33).

The construction (volume/splats.py) gives each Gaussian the matte alpha of its pixels, but a
Gaussian drawn with the reference's low pass covers more than its pixel: thin needles and strands
come out too wide and too opaque, and gaps between them fill.  Each iteration draws every kept
view (``draw(splats, cameras)``: the caller's renderer, the GL owner render/splat/gl.py from the
CLI or its numpy twin; volume imports no renderer) and compares the drawn alpha with the view's
matte at the pixel of every Gaussian the view sees (its centre's nearest pixel holds depth within
``tol`` of it, or none: the view saw the background there); the opacity is multiplied by the
exponential of the mean log ratio matte / drawn alpha over those views, each ratio clamped to
[1 / STEP_MAX, STEP_MAX].  Colours are not refined: a Jacobi step on the SH targets (the photo
minus the drawn colour at each Gaussian, refitted, with the opacities) sharpened the 320 x 240
plant (sharpness 0.60 -> 0.99) but left its held-out PSNR at 19.9 dB where the opacities alone
reached 21.0 (docs/splats.md).

An iteration is kept only when it lowers the kept views' alpha error (the mean squared difference
between drawn alpha and matte over the pixels with depth or matte); otherwise the refinement stops
there and says so (:class:`RefineReport`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from volume.splat_build import project
from volume.splats import OPACITY_MAX, OPACITY_MIN, Splats

#: Largest factor one view may move an opacity by in one iteration.
STEP_MAX = 2.0
#: Alphas below this are taken as this in the log ratio (an empty pixel is not -inf).
ALPHA_FLOOR = 0.02


@dataclass(frozen=True)
class RefineReport:
    """The kept views' alpha error (mean squared, over their pixels with depth or matte) before
    and after each accepted iteration, and whether the refinement stopped because an iteration
    did not lower it."""

    errors: tuple[float, ...]
    stopped: bool

    @property
    def iterations(self) -> int:
        return len(self.errors) - 1


def view_ratios(splats: Splats, cam, depth: np.ndarray, matte: np.ndarray, drawn: np.ndarray, tol: float):
    """(Gaussian indices, log(matte / drawn alpha)) of the Gaussians ``cam`` sees (module docstring):
    ``depth``, ``matte``, ``drawn`` are (H, W) full frames."""
    uv, z = project(cam, splats.positions.astype(np.float64))
    ui = np.round(np.nan_to_num(uv, nan=-1e9)).astype(np.int64)
    ok = (z > 0) & (ui[:, 0] >= 0) & (ui[:, 1] >= 0) & (ui[:, 0] < cam.width) & (ui[:, 1] < cam.height)
    idx = np.nonzero(ok)[0]
    x, y = ui[idx, 0], ui[idx, 1]
    d = depth[y, x]
    sees = (d <= 0) | (np.abs(d - z[idx]) < tol)
    idx, x, y = idx[sees], x[sees], y[sees]
    ratio = np.log(np.maximum(matte[y, x], ALPHA_FLOOR) / np.maximum(drawn[y, x], ALPHA_FLOOR))
    return idx, np.clip(ratio, -np.log(STEP_MAX), np.log(STEP_MAX))


def _pass(splats: Splats, model, frames: Iterable[np.ndarray], tol: float):
    """One pass over the kept views: (mean log ratio per Gaussian, its view count, alpha error)."""
    num, den = np.zeros(len(splats)), np.zeros(len(splats))
    err, count = 0.0, 0
    for n, drawn in enumerate(frames):
        _rgb, depth, alpha = model.rgbz.view(n)
        matte = (depth > 0).astype(np.float32) if alpha is None else alpha
        region = (depth > 0) | (matte > 0) | (drawn > 0)
        err += float(np.sum((drawn[region] - matte[region]) ** 2))
        count += int(region.sum())
        idx, r = view_ratios(splats, model.rgbz.cameras[n], depth, matte, np.asarray(drawn), tol)
        num[idx] += r
        den[idx] += 1.0
    return np.where(den > 0, num / np.maximum(den, 1.0), 0.0), err / max(count, 1)


def refine_opacities(splats: Splats, model, draw: Callable, iterations: int, tol: float = 0.003,
                     progress: Callable | None = None) -> tuple[Splats, RefineReport]:
    """``iterations`` opacity updates of ``splats`` against ``model``'s kept views (module
    docstring); ``draw(splats, cameras)`` yields each camera's drawn (H, W) alpha.  Returns the
    refined splats and the report."""
    if iterations < 0:
        raise ValueError(f"refine iterations must be >= 0, got {iterations}")
    track = progress or (lambda it, _desc: it)
    cams = list(model.rgbz.cameras)
    step, err = _pass(splats, model, draw(splats, track(cams, "refine: kept views")), tol)
    errors, stopped = [err], False
    for _ in range(iterations):
        o = np.clip(splats.opacities * np.exp(step), OPACITY_MIN, OPACITY_MAX).astype(np.float32)
        trial = dataclasses.replace(splats, opacities=o)
        next_step, next_err = _pass(trial, model, draw(trial, track(cams, "refine: kept views")), tol)
        if not next_err < errors[-1]:
            stopped = True
            break
        splats, step = trial, next_step
        errors.append(next_err)
    return splats, RefineReport(tuple(errors), stopped)
