"""The known-background matte's Laplacian guide at one brightness (capture.matting_known step 3; issue 30, stop 63).

The closed-form matting Laplacian (Levin et al. 2008; pymatting's) regularises each window's colour covariance by
``capture.matting_known.CF_EPSILON``, an absolute variance in the image's units.  The matte works on linear colour, so
the same object before a darker room, or under a shorter exposure, gets a smoother matte: before a dark forest (mean
linear 0.05) the Laplacian's windows hold variances of the order of epsilon and its alpha came out in blobs, while the
courtyard's crops (about 0.3) were what epsilon was chosen on.  With LAPLACIAN_LEVEL a crop darker than that on
average is brightened to it, ``image * LAPLACIAN_LEVEL / mean(image)``, for the Laplacian only (the data term still
reads the linear colour); a brighter crop is left as it is (scaling it down too cost the shaded courtyard turntables
0.08-0.13 dB).  Below the level, the Laplacian of a crop then does not change with its exposure.  Brightening every
dark crop gained every forest capture (+0.07 to +0.16 dB held out, SSIM +0.011 to +0.021) and lost two shaded
courtyard turntables 0.08 / 0.13 dB, so a view's guide is brightened only where a fifth of its band has a weak data
term before a background of the object's colour (:func:`view_guide`, WEAK_GATE: 0.24-0.36 before the forest,
0.04-0.05 before the shaded courtyards; docs/matting.md, stop 63).  None: the crop as it is, the rule before.
"""

from __future__ import annotations

import numpy as np

#: The mean linear brightness a darker crop's Laplacian guide is brightened to (module docstring); None: not scaled.
LAPLACIAN_LEVEL: float | None = 0.3
#: A view's guide is brightened only where at least this share of its matting band has a weak data term before a
#: background of nearly the object's colour (capture.matting_blind's record: ``weak`` / ``band``): there the data
#: cannot tell object from background and the Laplacian decides.  The same share furrow model warns at.
WEAK_GATE = 0.2
#: A crop darker than this on average is scaled as if it were this bright (a black frame: no division by 0).
MIN_MEAN = 1e-3


def laplacian_guide(image: np.ndarray) -> np.ndarray:
    """(h, w, 3) the guide the matting Laplacian of ``image`` (h, w, 3, linear) is built on (module docstring):
    ``image`` itself when LAPLACIAN_LEVEL is None."""
    if LAPLACIAN_LEVEL is None:
        return image
    gain = LAPLACIAN_LEVEL / max(float(np.mean(image)), MIN_MEAN)
    return image if gain <= 1.0 else np.asarray(image, np.float64) * gain


def view_guide(image: np.ndarray, blind_record: dict) -> np.ndarray:
    """The guide of one view's Laplacian: :func:`laplacian_guide` where the view's weak share (``blind_record``:
    capture.matting_blind.blind_prior's record, ``weak`` / ``band``) is at least WEAK_GATE, else ``image`` itself.
    Writes into ``blind_record`` whether the guide was brightened (``guided``: the matte record counts the views)."""
    share = blind_record.get("weak", 0) / max(blind_record.get("band", 0), 1)
    guide = laplacian_guide(image) if share >= WEAK_GATE else image
    blind_record["guided"] = guide is not image
    return guide
