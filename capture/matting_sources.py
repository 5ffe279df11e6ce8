"""The sure colour sources' own colour (capture.matting_known step 2; issue 30, stop 63).

The known-background matte seeks each partial pixel's colour F among the colours of the nearest sure foreground: the
depth's opaque pixels and those whose alpha bound is above ``capture.matting_known.SOURCE_ALPHA``.  They were taken
as opaque (F = C).  A conifer's depth-opaque pixels are not: their colour carries (1 - a) B, which made the candidates
pale and the kept views' alpha about 0.04 high where a frame saw the background (docs/matting.md, stop 63).  With
SOURCE_COVERAGE below 1 a source's colour is unmixed as F = B + (C - B) / max(bound, SOURCE_COVERAGE): never below
the bound, so F stays in [0, 1].
"""

from __future__ import annotations

import numpy as np

#: The coverage the sure colour sources are unmixed at where the background is known (module docstring);
#: 1.0: taken as opaque (F = C), the rule before.
SOURCE_COVERAGE = 1.0


def source_coverage(lower: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """(h, w) the coverage the sure colour ``sources`` are unmixed at: max(bound ``lower``, SOURCE_COVERAGE) there,
    1 elsewhere (module docstring)."""
    return np.where(sources, np.maximum(lower, SOURCE_COVERAGE), 1.0)


def source_colours(image: np.ndarray, background: np.ndarray, lower: np.ndarray, sources: np.ndarray,
                   known: np.ndarray) -> np.ndarray:
    """(h, w, 3) ``image`` with the ``sources``' colour unmixed where the background is ``known``:
    clip(B + (C - B) / :func:`source_coverage`, 0, 1); the image itself when SOURCE_COVERAGE is 1 (the rule
    before, bit for bit).  The working-resolution path's sources (capture.matting_scale)."""
    if SOURCE_COVERAGE >= 1.0:
        return image
    C, B = np.asarray(image, np.float64), np.asarray(background, np.float64)
    a = source_coverage(lower, np.asarray(sources, bool) & np.asarray(known, bool))
    return np.clip(B + (C - B) / a[..., None], 0.0, 1.0).astype(np.asarray(image).dtype)
