"""The sure colour sources' own colour (capture.matting_known step 2; issue 30, stops 63 and 81).

The known-background matte seeks each partial pixel's colour F among the colours of the nearest sure foreground: the
depth's opaque pixels and those whose alpha bound is above ``capture.matting_known.SOURCE_ALPHA``.  They were taken
as opaque (F = C).  A conifer's depth-opaque pixels are not: their colour carries (1 - a) B, which made the candidates
pale and the kept views' alpha about 0.04 high where a frame saw the background (docs/matting.md, stop 63).  With
SOURCE_COVERAGE below 1 a source's colour is unmixed as F = B + (C - B) / max(bound, SOURCE_COVERAGE): never below
the bound, so F stays in [0, 1].

**Their coverage measured per view** (stop 81, :func:`estimated_coverage`).  A depth-opaque pixel of coverage c shows
C = c F + (1 - c) B.  Over a view's depth-opaque pixels whose background is known, the needles' own colour F does not
follow the background behind them, so the slope of C on B (least squares, pooled over the three channels) is their
mean transparency 1 - c.  Path-traced conifers at 640 x 480: slope 0.05-0.15 per view against a true 0.06-0.08; the
same conifer at 320 x 240, where a depth pixel holds needles and gaps: 0.10-0.29 against 0.19-0.22, and taken as
opaque there the candidates were twice the needles' colour and the kept views' alpha 0.10 high (docs/matting.md
"The sources' coverage measured"). Where the slope is at least TRANSPARENCY_MIN the view's sources are unmixed at
1 - slope (the slope capped at TRANSPARENCY_MAX); below it, or with too few sources or too little spread of the
background behind them to measure a slope, they stay opaque (SOURCE_COVERAGE), as before.  **Off by default**
(ESTIMATE_COVERAGE): held out it raised PSNR and lowered SSIM on some conifers, as stop 63's fixed coverage did.
"""

from __future__ import annotations

import numpy as np

from capture.matting_fast import channel_max

#: The coverage the sure colour sources are unmixed at where the background is known (module docstring);
#: 1.0: taken as opaque (F = C), the rule before.
SOURCE_COVERAGE = 1.0
#: Measure each view's sources' coverage (:func:`estimated_coverage`); False: SOURCE_COVERAGE in every view.  Off:
#: it failed its rule, written before two fresh 320 x 240 conifers were rendered (+0.3 dB and at most 0.01 SSIM
#: lost on each): +0.09 dB on one, +1.50 dB with SSIM -0.023 on the other (docs/matting.md "The sources' coverage
#: measured").
ESTIMATE_COVERAGE = False
#: The least measured transparency (the slope of C on B) acted on: below it the sources count as opaque.
TRANSPARENCY_MIN = 0.1
#: The most transparency a view's sources are given (the slope capped here): coverage at least 1 - this.
TRANSPARENCY_MAX = 0.5
#: The least spread of the background behind the sources (standard deviation, linear, pooled over the channels)
#: for a slope: before a plain background C barely moves with B and the slope is noise.
SPREAD_MIN = 0.02
#: The least sources (depth-opaque, background known, nothing clipped) for a slope.
SLOPE_SOURCES = 50


def estimated_coverage(image: np.ndarray, background: np.ndarray, sources: np.ndarray,
                       clip_level: float) -> tuple[float | None, float | None]:
    """(coverage or None, slope or None) of a view's depth-opaque colour ``sources`` (h, w) bool whose background
    ``background`` (h, w, 3) is known: the slope of the photo ``image`` on the background over those of them where
    neither reaches ``clip_level`` (module docstring).  Coverage None (the sources opaque) with ESTIMATE_COVERAGE off,
    fewer than SLOPE_SOURCES of them, a spread under SPREAD_MIN (slope None there) or a slope under TRANSPARENCY_MIN."""
    if not ESTIMATE_COVERAGE:
        return None, None
    C, B = np.asarray(image), np.asarray(background)
    s = np.asarray(sources, bool) & (channel_max(C) < clip_level) & (channel_max(B) < clip_level)
    n = int(np.count_nonzero(s))
    if n < SLOPE_SOURCES:
        return None, None
    x, y = B[s].astype(np.float64), C[s].astype(np.float64)
    x -= x.mean(0)
    y -= y.mean(0)
    sxx = float(np.sum(x * x))
    if sxx < 3 * n * SPREAD_MIN ** 2:
        return None, None
    slope = float(np.sum(x * y)) / sxx
    if slope < TRANSPARENCY_MIN:
        return None, slope
    return 1.0 - min(slope, TRANSPARENCY_MAX), slope


def source_coverage(lower: np.ndarray, sources: np.ndarray, coverage: float | None = None) -> np.ndarray:
    """(h, w) the coverage the sure colour ``sources`` are unmixed at: max(bound ``lower``, ``coverage``) there
    (None: SOURCE_COVERAGE), 1 elsewhere (module docstring)."""
    c = SOURCE_COVERAGE if coverage is None else coverage
    return np.where(sources, np.maximum(lower, c), 1.0)


def source_colours(image: np.ndarray, background: np.ndarray, lower: np.ndarray, sources: np.ndarray,
                   known: np.ndarray, coverage: float | None = None) -> np.ndarray:
    """(h, w, 3) ``image`` with the ``sources``' colour unmixed where the background is ``known``:
    clip(B + (C - B) / :func:`source_coverage`, 0, 1); the image itself when the coverage is 1 (the rule
    before, bit for bit).  The working-resolution path's sources (capture.matting_scale)."""
    if (SOURCE_COVERAGE if coverage is None else coverage) >= 1.0:
        return image
    C, B = np.asarray(image, np.float64), np.asarray(background, np.float64)
    a = source_coverage(lower, np.asarray(sources, bool) & np.asarray(known, bool), coverage)
    return np.clip(B + (C - B) / a[..., None], 0.0, 1.0).astype(np.asarray(image).dtype)
