"""The sure colour sources' own colour (capture.matting_known step 2; issue 30, stops 63 and 81).

The known-background matte seeks each partial pixel's colour F among the colours of the nearest sure foreground: the
depth's opaque pixels and those whose alpha bound is above ``capture.matting_known.SOURCE_ALPHA``.  They were taken
as opaque (F = C).  A conifer's depth-opaque pixels are not: their colour carries (1 - a) B, which made the candidates
pale and the kept views' alpha about 0.04 high where a frame saw the background (docs/matting.md, stop 63).  With
SOURCE_COVERAGE below 1 a source's colour is unmixed as F = B + (C - B) / max(bound, SOURCE_COVERAGE): never below
the bound, so F stays in [0, 1].

**Their coverage measured over the capture** (stop 81: :func:`view_slope`, :func:`capture_coverage`).  A depth-opaque
pixel of coverage c shows C = c F + (1 - c) B.  Over a view's depth-opaque pixels before a background some frame saw,
the needles' own colour F does not follow the room behind them, so the slope of C on B (least squares, pooled over
the three channels) is their mean transparency 1 - c.  Path-traced conifers at 640 x 480: slopes 0.04-0.15 per view
against a true 0.06-0.08; the same conifer at 320 x 240, where a depth pixel holds needles and gaps: 0.10-0.29 against
0.19-0.22, and taken as opaque there the candidates were twice the needles' colour and the kept views' alpha 0.10
high (docs/matting.md "A conifer at 320 x 240 in a room").  A view whose depth-opaque pixels are a solid body (a fur
ball: its back-lit rim's colour does follow the background) gives no slope.  The median of the views' slopes, where
it is at least TRANSPARENCY_MIN, gives every view's sources the coverage 1 - SLOPE_SHARE x median: half the measured
transparency (in full, the held-out SSIM fell on one conifer).  Otherwise, or with too few sources, too little spread
of the background behind them or too few views with a slope, they stay opaque (SOURCE_COVERAGE), as before.
"""

from __future__ import annotations

import numpy as np

from capture.matting_fast import channel_max

#: The coverage the sure colour sources are unmixed at where the background is known (module docstring);
#: 1.0: taken as opaque (F = C), the rule before.
SOURCE_COVERAGE = 1.0
#: Measure the sources' coverage over the capture (:func:`view_slope`, :func:`capture_coverage`; the pipeline's matte
#: stage); False: SOURCE_COVERAGE in every view.  Off: it failed the rules written before the captures that tested it
#: (docs/matting.md "A conifer at 320 x 240 in a room"): +0.67 dB on a fresh 320 x 240 conifer orbit, none on one
#: before a plain studio (nothing fired), and SSIM -0.011 on two 640 x 480 conifer turntables where it fired.
ESTIMATE_COVERAGE = False
#: The least measured transparency (the median of the views' slopes of C on B) acted on: below it the sources count
#: as opaque.
TRANSPARENCY_MIN = 0.1
#: The most transparency the sources are given (the median slope capped here).
TRANSPARENCY_MAX = 0.5
#: The least spread of the background behind the sources (standard deviation, linear, pooled over the channels)
#: for a slope: before a plain background C barely moves with B and the slope is noise.
SPREAD_MIN = 0.02
#: The least sources (depth-opaque, background known, nothing clipped) for a slope.
SLOPE_SOURCES = 50
#: The least views with a slope for a capture's coverage (:func:`capture_coverage`).
SLOPE_VIEWS = 3
#: The share of the measured transparency given to the sources (:func:`capture_coverage`): half.  In full the
#: kept views' alpha lost its bias and the held-out SSIM fell on one low-resolution conifer (docs/matting.md).
SLOPE_SHARE = 0.5


def view_slope(image: np.ndarray, background: np.ndarray, sources: np.ndarray, clip_level: float) -> float | None:
    """The slope of the photo ``image`` on the plate ``background`` (h, w, 3) over a view's depth-opaque colour
    ``sources`` (h, w) bool whose background is known, those of them where neither reaches ``clip_level`` (module
    docstring); None with ESTIMATE_COVERAGE off, fewer than SLOPE_SOURCES of them, a spread of the background under
    SPREAD_MIN, or sources that are a solid body (:func:`solid`)."""
    if not ESTIMATE_COVERAGE:
        return None
    C, B = np.asarray(image), np.asarray(background)
    s = np.asarray(sources, bool) & (channel_max(C) < clip_level) & (channel_max(B) < clip_level)
    n = int(np.count_nonzero(s))
    if n < SLOPE_SOURCES or solid(np.asarray(sources, bool)):
        return None
    x, y = B[s].astype(np.float64), C[s].astype(np.float64)
    x -= x.mean(0)
    y -= y.mean(0)
    sxx = float(np.sum(x * x))
    if sxx < 3 * n * SPREAD_MIN ** 2:
        return None
    return float(np.sum(x * y)) / sxx


def solid(sources: np.ndarray) -> bool:
    """Whether a view's depth-opaque ``sources`` (h, w) bool are a solid body rather than branches: at least
    capture.matting_rim.THICK_SHARE of them survive the opening by RIM_FRACTION of the width (a fur ball's disc, whose
    back-lit rim's colour follows the background behind it: the slope is no coverage there)."""
    from capture.matting_rim import RIM_FRACTION, THICK_SHARE, _opening

    fg = np.asarray(sources, bool)
    r = max(1, int(round(RIM_FRACTION * fg.shape[1])))
    return bool(np.count_nonzero(_opening(fg, r)) >= THICK_SHARE * np.count_nonzero(fg))


def capture_coverage(slopes) -> tuple[float | None, float | None]:
    """(coverage or None, median or None) of a capture's views' :func:`view_slope` values (None where a view has
    none): the median of those given, with at least SLOPE_VIEWS of them; the coverage 1 - SLOPE_SHARE x the median
    (capped at TRANSPARENCY_MAX) where the median is at least TRANSPARENCY_MIN, else None (opaque sources)."""
    have = [float(k) for k in slopes if k is not None]
    if len(have) < SLOPE_VIEWS:
        return None, None
    med = float(np.median(have))
    if med < TRANSPARENCY_MIN:
        return None, med
    return 1.0 - SLOPE_SHARE * min(med, TRANSPARENCY_MAX), med


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
