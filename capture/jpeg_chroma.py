"""Frames stored as JPEGs with subsampled chroma (a phone's 4:2:0), and what the known-background matte allows them.

A JPEG stores the colour difference (Cb, Cr of the sRGB-encoded values) at half the resolution in one or both
directions; the decoder smooths it back.  Near an edge of colour, a pixel's chroma is then partly its
neighbours': a background pixel beside a dark green needle turns a little green, by far more than the sensor's
noise, while its luma (stored at full resolution) stays right.  The known-background matte reads every colour
difference C - B beyond the noise as coverage (capture.matting_known step 1, the alpha bound), so such a frame
grows a pale halo of false alpha around every needle and the trimap widens into the room (docs/real_cameras.md:
JPEG quality 90 at 4:2:0 cost the path-traced conifer turntable 1.41 dB held out, most of it this).

* :func:`subsampled_chroma`: whether an image file is a JPEG whose chroma is stored at a lower resolution than
  its luma (its start-of-frame header's sampling factors; no pixel is decoded).
* :func:`chroma_allowance`: per pixel and channel, how far the decoded chroma may be off: CHROMA_SHARE of the
  range of Cb and of Cr over the CHROMA_WINDOW x CHROMA_WINDOW pixels around it (the reach of the 2 x 2 blocks
  and the decoder's upsampling), carried into linear R, G, B through the JFIF matrix and the sRGB curve's slope.
  Zero where the chroma is flat: a frame's plain background keeps the noise it had.
capture.matting_known.alpha_lower_bound adds that allowance to the noise for frames whose chroma is subsampled
(capture.matting.MatteConfig.subsampled).

Only the bound and what follows it (the trimap's widening, the colour sources) use the allowance; the candidates'
alpha still fits the whole colour difference.  Taking the chroma difference out of the matte altogether (C moved
to B's chroma, less the allowance) was measured and is worse: alpha MSE 0.033 -> 0.039 (docs/real_cameras.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: Side (pixels) of the window whose chroma range bounds a pixel's chroma error: a 2 x 2 block and the decoder's
#: upsampling reach two pixels each way.
CHROMA_WINDOW = 5
#: Share of the window's chroma range allowed as error (0.5 and 1.0 gave the same held-out scores within
#: 0.01 dB on the JPEG conifer turntable; the smaller keeps more of a faint needle's bound).
CHROMA_SHARE = 0.5
#: JFIF: R' = Y + 1.402 Cr, G' = Y - 0.344136 Cb - 0.714136 Cr, B' = Y + 1.772 Cb (sRGB-encoded values in [0, 1]).
JFIF_FROM_CB = np.array([0.0, 0.344136, 1.772])
JFIF_FROM_CR = np.array([1.402, 0.714136, 0.0])
#: Start-of-frame markers (baseline, progressive, lossless, arithmetic; not DHT 0xC4, JPG 0xC8, DAC 0xCC).
_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
#: The most segments read before the frame header (a JPEG's EXIF, ICC, XMP and thumbnail blocks come first).
_MAX_SEGMENTS = 64


def subsampled_chroma(path) -> bool:
    """Whether the image file ``path`` is a JPEG whose chroma components are sampled less often than its luma
    (4:2:0, 4:2:2, 4:1:1).  False for any other file, a grey JPEG, 4:4:4, or a header it cannot read.  Reads the
    segments' headers only, skipping their bodies, up to the start-of-frame segment."""
    try:
        with open(Path(path), "rb") as f:
            if f.read(2) != b"\xff\xd8":
                return False
            for _ in range(_MAX_SEGMENTS):
                head = f.read(4)
                while len(head) >= 2 and head[0] == 0xFF and head[1] == 0xFF:  # fill bytes before a marker
                    head = head[1:] + f.read(1)
                if len(head) < 4 or head[0] != 0xFF:
                    return False
                marker, size = head[1], int.from_bytes(head[2:4], "big")
                if marker in _SOF:
                    return _sampling_subsampled(f.read(max(size - 2, 0)))
                if marker == 0xDA or size < 2:  # a scan before any frame header, or a broken length
                    return False
                f.seek(size - 2, 1)
    except OSError:
        return False
    return False


def _sampling_subsampled(sof: bytes) -> bool:
    """From a start-of-frame segment's body: more than one component, and a later one sampled less often than
    the first (the luma) in either direction."""
    if len(sof) < 6:
        return False
    n = sof[5]
    comps = [sof[6 + 3 * k:9 + 3 * k] for k in range(n)]
    if n < 3 or any(len(c) < 3 for c in comps):
        return False
    h0, v0 = comps[0][1] >> 4, comps[0][1] & 15
    return any((c[1] >> 4) < h0 or (c[1] & 15) < v0 for c in comps[1:])


def chroma_allowance(image: np.ndarray) -> np.ndarray:
    """(h, w, 3) float64 linear: how far each channel of the linear ``image`` (h, w, 3) may be off where its
    chroma was subsampled (module docstring); 0 where Cb and Cr are flat over the window."""
    from scipy import ndimage

    from capture.scan import linear_to_srgb

    E = np.asarray(linear_to_srgb(image), np.float64)
    R, G, B = E[..., 0], E[..., 1], E[..., 2]
    cb = -0.168736 * R - 0.331264 * G + 0.5 * B
    cr = 0.5 * R - 0.418688 * G - 0.081312 * B

    def spread(p):
        return ndimage.maximum_filter(p, CHROMA_WINDOW) - ndimage.minimum_filter(p, CHROMA_WINDOW)

    enc = CHROMA_SHARE * (spread(cb)[..., None] * JFIF_FROM_CB + spread(cr)[..., None] * JFIF_FROM_CR)
    slope = np.where(E <= 0.04045, 1 / 12.92, 2.4 / 1.055 * np.power((np.maximum(E, 0.04045) + 0.055) / 1.055, 1.4))
    return enc * slope
