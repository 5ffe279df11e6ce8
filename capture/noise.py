"""The frames' sensor noise, measured, and the plate stage's frames smoothed to it (issue 30).

The background plate (``capture.plate``) compares the frames' colours: a fixed camera's robust mode
takes the samples that agree to ``capture.plate_fixed.MODE_TOL`` (3 8-bit sRGB steps) as the
background, the frames' lines take their vertex from one frame's sample.  A path-traced room is
noise-free behind the object (its frames differ by 0.37 steps), a camera's is not: with independent
noise of 3 steps two clean samples of one pixel agree to 3 steps in every channel in about one pair
of seven, the robust mode knows half the pixels it knew, and the held-out conifer lost 1.2-1.5 dB
more than the clean capture before its room (docs/matting.md, "Sensor noise behind the object").

Here the noise is measured on the frames themselves, beyond the object (:func:`frame_noise`: the median
absolute value of the finest diagonal Haar detail, which a smooth background and the edges of an image
leave near zero and independent pixel noise fills; Donoho's estimator), and where the capture's noise is at
least NOISE_MIN_SIGMA the plate stage reads its frames smoothed by a bilateral filter
(:func:`smooth_frame`: a SMOOTH_DIAMETER window, neighbours weighted down by their colour difference on
the scale of SMOOTH_COLOUR times the noise).  It averages the noise away where the room is flat and
keeps an edge of the room's texture, or a needle, that stands above the noise: on the test scene's
blocky room (tests/plate_scenes.turntable_capture) a Gaussian that left one step of noise made the
plate worse than the noisy frames (band error 0.012 -> 0.028 linear), the bilateral filter better
(0.008; the band seen by the robust mode 21 % -> 39 %, 54 % clean).  Only the plate stage's copy is
smoothed: the matte, the colours and everything after them read the photos.  A clean capture (noise
below NOISE_MIN_SIGMA) is read as before, bit for bit.

Stop 61 (docs/matting.md): the noise is read at two scales (:func:`_level`; a camera's demosaicing and JPEG take it
out of the finest detail), on a capture that does not move also between frames (:func:`pair_noise`: a room's own
texture is the same in every frame and is not noise), and the plate stage checks the smoothing against doing nothing
before it uses it (capture.noise_check).
"""

from __future__ import annotations

import numpy as np

#: Frames whose measured noise (the capture's median, 8-bit sRGB steps) is below this are read as they
#: are.  The path-traced captures measure 0.00 (their 8-bit frames are smooth at the pixel scale); the
#: plate's agreement (MODE_TOL, 3 steps) starts to fail at noise of about 1.5 steps.
NOISE_MIN_SIGMA = 1.0
#: The bilateral filter's window (pixels, :func:`smooth_frame`) and the spatial scale of its weights (pixels):
#: nearly a 5 x 5 mean where the colours agree (noise of 3 steps left at about 0.6).
SMOOTH_DIAMETER = 5
SMOOTH_SPACE = 3.0
#: ... and the colour scale of its weights, this times the noise (OpenCV sums the channels' differences: two
#: samples of noise sigma differ by about 3.4 sigma over three channels).  On the test scene 3 to 5 were alike.
SMOOTH_COLOUR = 4.0
#: Frames measured at most (evenly spaced over the capture; each measurement reads one whole frame).
NOISE_FRAMES = 8
#: 2 x 2 blocks a frame's measurement reads at most (every k-th pair of rows: a 1920 x 1440 frame took 58 ms
#: whole, 8 of them half a second of a phone capture's plate stage).
NOISE_BLOCKS = 250_000
#: Median of |N(0, 1)|: a Gaussian's standard deviation is the median absolute value over this.
MAD_TO_SIGMA = 0.6745
#: The object is left out of the measurement: blocks within this fraction of the width of its depth (16 px at
#: 640).  A path-traced fur ball at 16 spp (its Monte Carlo noise and the hairs' texture, 35 % of the frame)
#: measured 0.74 over the whole frame, 5.9 on the object and 0.00 on its room.
NOISE_OBJECT_MARGIN = 16 / 640
#: Where the noise between frames (:func:`pair_noise`) is under this share of the frames' own fine detail, the detail
#: is the room's texture, not noise, and the capture's noise is the one between frames.  Independent noise reads
#: alike both ways (within 5 % at 1.5-5 steps); a fixed camera before a room with pixel-scale grain of 3.7 steps and
#: no noise read 3.71 / 0.00, and smoothing its frames made the test scene's plate 5 x worse (docs/matting.md).
TEXTURE_RATIO = 0.7
#: Read the noise at two scales too (:func:`_level`: the finest and that of the 2 x 2 means; the coarser taken where
#: COARSE_RATIO says): a camera's demosaicing and JPEG take the noise out of the finest detail (a camera-like copy
#: of a path-traced conifer, noise of about 3 steps through a Bayer mosaic, bilinear demosaicing and JPEG quality 90,
#: read 0.56 at the finest).
TWO_SCALES = True
#: ... where the coarser level reads over this times the finest.  Independent noise reads alike at both (within 5 %;
#: the larger of the two, taken always, read the orbit's noise of 1.5 steps 7 % high, and its smoothing then lost
#: the self-check); JPEG quality 90 and demosaicing read 3-4 x at the coarser level.
COARSE_RATIO = 1.25
#: Least background blocks for a frame's measurement (fewer: not measured; the median of 256 has a standard
#: error of about 8 %, and a 64 x 48 test frame keeps about 500).
NOISE_MIN_BLOCKS = 256


def frame_noise(rgb: np.ndarray, object_depth: np.ndarray | None = None) -> float:
    """Noise of one frame (H, W, 3) uint8 sRGB, in 8-bit steps: the median absolute value of the
    finest diagonal Haar detail (a - b - c + d) / 2 of each 2 x 2 block, over MAD_TO_SIGMA (Donoho's
    estimator; the detail of independent noise sigma has sigma, a smooth image's none), over at most
    NOISE_BLOCKS blocks (evenly spaced pairs of rows) and, given the object's depth (H, W; > 0 on the object),
    only the blocks beyond NOISE_OBJECT_MARGIN of it: the background the plate is made of.  NaN for a frame
    that is not 8-bit, smaller than 2 x 2, or with fewer than NOISE_MIN_BLOCKS such blocks.  A room's own
    texture at the pixel scale reads as noise here (:func:`pair_noise` tells them apart)."""
    x = np.asarray(rgb)
    if x.dtype != np.uint8 or x.ndim != 3 or x.shape[0] < 2 or x.shape[1] < 2:
        return float("nan")
    return _haar_noise(x.astype(np.int16), [object_depth])


def pair_noise(a: np.ndarray, b: np.ndarray, depth_a: np.ndarray | None = None,
               depth_b: np.ndarray | None = None) -> float:
    """Noise of two frames (H, W, 3) uint8 of a camera that did not move (8-bit steps): :func:`frame_noise`'s
    estimator on their difference a - b, over sqrt 2, beyond both objects' depths.  The room's texture is the same
    in both and leaves the difference, their independent noise does not; a slow change of exposure leaves next to
    no fine detail.  Where the camera moved the difference holds the room's detail of both frames and reads about
    as high as :func:`frame_noise` or higher.  NaN as :func:`frame_noise`, or for frames of other sizes."""
    x, y = np.asarray(a), np.asarray(b)
    if x.dtype != np.uint8 or y.dtype != np.uint8 or x.shape != y.shape or x.ndim != 3 or min(x.shape[:2]) < 2:
        return float("nan")
    return _haar_noise(x.astype(np.int16) - y.astype(np.int16), [depth_a, depth_b]) / np.sqrt(2.0)


def _haar_noise(x: np.ndarray, object_depths: list) -> float:
    """Donoho's estimate (:func:`frame_noise`) on ``x`` (H, W, 3) int16, beyond every given object depth: the larger
    of the finest level's and the next level's where that is over COARSE_RATIO times it (:func:`_level`; NaN there,
    too few blocks: the finest alone)."""
    fine = _level(x, object_depths, 2)
    coarse = _level(x, object_depths, 4) if TWO_SCALES else float("nan")
    return coarse if np.isfinite(coarse) and coarse > COARSE_RATIO * fine else fine


def _level(x: np.ndarray, object_depths: list, size: int) -> float:
    """The noise read from the diagonal Haar detail of ``size`` x ``size`` blocks (2: the pixels' (a - b - c + d) / 2;
    4: the same of the 2 x 2 means, times 2, which independent noise leaves at sigma and a demosaicing's or JPEG's
    correlation lowers less than the finest), in 8-bit steps, over at most NOISE_BLOCKS blocks beyond the objects."""
    h, w = x.shape[0] // size * size, x.shape[1] // size * size
    if h < size or w < size:
        return float("nan")
    step = max(1, -(-(h // size) * (w // size) // NOISE_BLOCKS))  # every step-th row of blocks (ceil division)
    y = x[:h, :w].reshape(h // size, size, w, 3)[::step].reshape(-1, w, 3).astype(np.int32)
    if size == 4:  # the 2 x 2 sums (four times the means)
        y = y[0::2, 0::2] + y[0::2, 1::2] + y[1::2, 0::2] + y[1::2, 1::2]
    detail = np.abs(y[0::2, 0::2] - y[0::2, 1::2] - y[1::2, 0::2] + y[1::2, 1::2])  # integers
    deps = [d for d in object_depths if d is not None]
    if deps:
        obj = np.logical_or.reduce([np.asarray(d)[:h, :w] > 0 for d in deps])
        near = _near_object(obj).reshape(h // size, size, w // size, size)[::step].any((1, 3))
        detail = detail[~near]
        if len(detail) < NOISE_MIN_BLOCKS:
            return float("nan")
    return grouped_median(detail) / (2.0 if size == 2 else 4.0) / MAD_TO_SIGMA


def grouped_median(v: np.ndarray) -> float:
    """The median of non-negative integers ``v`` read as rounded values of a continuous quantity: inside the
    integer where half the values are reached, linearly (bin k spans k - 0.5 to k + 0.5, bin 0 from 0 to 0.5).
    The plain median of 8-bit Haar details moves in steps of 0.74 noise steps (noise of 3 steps read 2.22 or 2.97
    by where the median fell); this one moves smoothly."""
    counts = np.bincount(np.asarray(v, np.int64).ravel())
    if not counts.sum():
        return float("nan")
    cum = np.cumsum(counts)
    half = 0.5 * cum[-1]
    k = int(np.searchsorted(cum, half))  # the first bin whose cumulative count reaches half
    lo, width = (0.0, 0.5) if k == 0 else (k - 0.5, 1.0)
    before = cum[k - 1] if k else 0
    return float(lo + width * (half - before) / counts[k])


def _near_object(obj: np.ndarray) -> np.ndarray:
    """(H, W) bool: within NOISE_OBJECT_MARGIN of the width of the ``obj`` pixels (a square dilation)."""
    import cv2

    r = max(1, round(NOISE_OBJECT_MARGIN * obj.shape[1]))
    return cv2.dilate(obj.astype(np.uint8), np.ones((2 * r + 1, 2 * r + 1), np.uint8)) > 0


def noise_frames(n: int) -> list[int]:
    """The frames of ``n`` that :func:`capture_noise` reads: at most NOISE_FRAMES, evenly spaced (the fixed
    plate's own rule, capture.plate_fixed.mode_frames)."""
    from capture.plate_fixed import mode_frames

    return mode_frames(n, None, NOISE_FRAMES)


def capture_noise(frames: list[np.ndarray], object_depths: list[np.ndarray] | None = None) -> float:
    """The capture's noise (8-bit steps; :func:`noise_parts`' chosen value)."""
    return noise_parts(frames, object_depths)[0]


def noise_parts(frames: list[np.ndarray], object_depths: list[np.ndarray] | None = None) -> tuple[float, float, float]:
    """(the capture's noise, the frames' own fine detail, the noise between frames), 8-bit steps: the median of
    :func:`frame_noise` over ``frames`` (H, W, 3) uint8 (the :func:`noise_frames` of a capture), each beyond its
    object's depth where ``object_depths`` are given, and the median of :func:`pair_noise` over consecutive
    frames.  The capture's noise is the noise between frames where that is under TEXTURE_RATIO of the frames'
    detail (a camera that did not move before a room with texture at the pixel scale: the texture is no noise),
    else the frames' detail; NaN when none is measured."""
    deps = [None] * len(frames) if object_depths is None else object_depths
    got = np.array([frame_noise(f, d) for f, d in zip(frames, deps, strict=True)])
    got = got[np.isfinite(got)]
    detail = float(np.median(got)) if len(got) else float("nan")
    pairs = np.array([pair_noise(frames[i], frames[i + 1], deps[i], deps[i + 1]) for i in range(len(frames) - 1)])
    pairs = pairs[np.isfinite(pairs)]
    between = float(np.median(pairs)) if len(pairs) else float("nan")
    chosen = between if np.isfinite(between) and between < TEXTURE_RATIO * detail else detail
    return chosen, detail, between


def smoothing(noise: float) -> float:
    """The colour scale (8-bit steps) of the bilateral filter for frames of ``noise`` 8-bit steps
    (SMOOTH_COLOUR x noise); 0 (the frames as they are) below NOISE_MIN_SIGMA or when not known."""
    if not np.isfinite(noise) or noise < NOISE_MIN_SIGMA:
        return 0.0
    return float(SMOOTH_COLOUR * noise)


def smooth_frame(rgb: np.ndarray, colour_scale: float) -> np.ndarray:
    """``rgb`` (H, W, 3) uint8 through OpenCV's bilateral filter (SMOOTH_DIAMETER, SMOOTH_SPACE and
    ``colour_scale`` 8-bit steps, :func:`smoothing`); the frame itself for ``colour_scale`` <= 0 or a frame
    that is not 8-bit."""
    if colour_scale <= 0 or np.asarray(rgb).dtype != np.uint8:
        return rgb
    import cv2

    return cv2.bilateralFilter(np.ascontiguousarray(rgb), SMOOTH_DIAMETER, float(colour_scale), SMOOTH_SPACE)


#: Frame files whose compression takes out the fine detail that :func:`frame_noise` reads: noise of 3 steps saved as
#: JPEG quality 90 read 0.74 at the finest level alone (stop 60); with the coarser level 1.99 (quality 80: 1.27), so a
#: JPEG capture that still reads under a step gets the note.
JPEG_SUFFIXES = (".jpg", ".jpeg")


def noise_note(noise: float, names) -> str | None:
    """What the record and the console say beside a measured ``noise`` (8-bit steps, NaN when not measured)
    of frames named ``names`` (their files): why it was not measured, or that JPEG frames may read low and so
    were not smoothed; None when the measurement can be taken as it is."""
    if not np.isfinite(noise):
        return (f"not measured (fewer than {NOISE_MIN_BLOCKS} background 2 x 2 blocks beside the object, or frames "
                "that are not 8-bit): the plate read the frames as they are")
    jpeg = [n for n in names if str(n).lower().endswith(JPEG_SUFFIXES)]
    if jpeg and noise < NOISE_MIN_SIGMA:
        return (f"measured on JPEG frames ({len(jpeg)} of {len(names)}): compression takes out the fine detail this "
                "measurement reads, so a noisy capture may read low and was not smoothed (--plate-denoise)")
    return None
