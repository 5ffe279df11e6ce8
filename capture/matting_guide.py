"""The known-background matte's Laplacian guide at one brightness (capture.matting_known step 3; issue 30, stop 63).

The closed-form matting Laplacian (Levin et al. 2008; pymatting's) regularises each window's colour covariance by
``capture.matting_known.CF_EPSILON``, an absolute variance in the image's units.  The matte works on linear colour, so
the same object before a darker room, or under a shorter exposure, gets a smoother matte: before a dark forest (mean
linear 0.05) the Laplacian's windows hold variances of the order of epsilon and its alpha came out in blobs, while the
courtyard's crops (about 0.3) were what epsilon was chosen on.  With LAPLACIAN_LEVEL the guide is the crop scaled to
that mean brightness, ``image * LAPLACIAN_LEVEL / mean(image)``: the Laplacian of a crop then does not change with its
exposure (the data term still reads the linear colour).  None: the crop as it is, the rule before.
"""

from __future__ import annotations

import numpy as np

#: The mean linear brightness the Laplacian's guide is scaled to (module docstring); None: not scaled.
LAPLACIAN_LEVEL: float | None = None
#: A crop darker than this on average is scaled as if it were this bright (a black frame: no division by 0).
MIN_MEAN = 1e-3


def laplacian_guide(image: np.ndarray) -> np.ndarray:
    """(h, w, 3) the guide the matting Laplacian of ``image`` (h, w, 3, linear) is built on (module docstring):
    ``image`` itself when LAPLACIAN_LEVEL is None."""
    if LAPLACIAN_LEVEL is None:
        return image
    return np.asarray(image, np.float64) * (LAPLACIAN_LEVEL / max(float(np.mean(image)), MIN_MEAN))
