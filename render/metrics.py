"""Image metrics for held-out evaluation: PSNR and SSIM (scikit-image) on 8-bit sRGB, over the
full image and inside a mask, the sharpness ratio, plus the hole fraction of a rendering inside
the object.

PSNR rewards blur (a 0.8 px Gaussian blur of a point splatting gains 1-2 dB on fur while the
strands turn to felt), so every score comes with :func:`sharpness_ratio`: the RMS of the
Laplacian of the rendering's grey image over the reference's, inside the mask (1 = as crisp as
the photo; < 1 blurred; > 1 noisier or over-sharpened).

All functions take linear float images or 8-bit sRGB images; linear input is converted with
``capture.scan.to_uint8_srgb`` first, so every score is computed on what a PNG would hold.
"""

from __future__ import annotations

import numpy as np

from capture.scan import to_uint8_srgb

#: Data range of 8-bit images.
PEAK = 255.0
#: SSIM window (scikit-image default 7; must be odd and <= the image's smaller side).
SSIM_WIN = 7
#: PSNR reported for identical images (instead of +inf, so JSON stays valid).
PSNR_IDENTICAL = 100.0
#: Grey image of the sharpness figure: Rec. 601 luma of the 8-bit sRGB values.
LUMA_WEIGHTS = (0.299, 0.587, 0.114)


def as_srgb8(img: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 sRGB: uint8 input is returned as is, float input is taken as linear."""
    img = np.asarray(img)
    if img.dtype == np.uint8:
        return img
    return to_uint8_srgb(img)


def _check(a: np.ndarray, b: np.ndarray) -> None:
    if a.shape != b.shape:
        raise ValueError(f"image shapes differ: {a.shape} vs {b.shape}")


def psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """PSNR in dB of two images on 8-bit sRGB (peak 255), over the pixels of ``mask`` (H, W)
    if given; PSNR_IDENTICAL when equal; NaN for an empty mask."""
    a8, b8 = as_srgb8(a), as_srgb8(b)
    _check(a8, b8)
    d = a8.astype(np.float64) - b8.astype(np.float64)
    if mask is not None:
        d = d[np.asarray(mask, bool)]
    if d.size == 0:
        return float("nan")
    mse = float(np.mean(d * d))
    if mse == 0:
        return PSNR_IDENTICAL
    return float(10.0 * np.log10(PEAK * PEAK / mse))


def ssim(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Mean SSIM (scikit-image, channel axis last, 8-bit data range) over the image, or over
    the pixels of ``mask`` (mean of the SSIM map there); NaN for an empty mask."""
    from skimage.metrics import structural_similarity

    a8, b8 = as_srgb8(a), as_srgb8(b)
    _check(a8, b8)
    win = min(SSIM_WIN, *(s - (1 - s % 2) for s in a8.shape[:2]))
    if win < 3:
        raise ValueError(f"image {a8.shape[:2]} too small for SSIM")
    val, smap = structural_similarity(a8, b8, channel_axis=-1, data_range=PEAK, win_size=win, full=True)
    if mask is None:
        return float(val)
    m = np.asarray(mask, bool)
    if not m.any():
        return float("nan")
    return float(smap.mean(axis=-1)[m].mean())


def grey(img: np.ndarray) -> np.ndarray:
    """(H, W) float64 grey image (LUMA_WEIGHTS) of the 8-bit sRGB values, 0..255."""
    return as_srgb8(img).astype(np.float64) @ np.asarray(LUMA_WEIGHTS)


def laplacian_rms(img: np.ndarray, mask: np.ndarray) -> float:
    """RMS over ``mask`` of the Laplacian (scipy.ndimage.laplace: the 5-point stencil, edges
    reflected) of the grey image, in 8-bit units; NaN for an empty mask."""
    from scipy import ndimage

    m = np.asarray(mask, bool)
    if not m.any():
        return float("nan")
    lap = ndimage.laplace(grey(img))
    return float(np.sqrt(np.mean(lap[m] ** 2)))


def sharpness_ratio(reference: np.ndarray, rendered: np.ndarray, mask: np.ndarray) -> float:
    """laplacian_rms(rendered) / laplacian_rms(reference) over ``mask`` (1 = as crisp as the
    reference); NaN for an empty mask or a flat reference."""
    ref = laplacian_rms(reference, mask)
    if not ref > 0:
        return float("nan")
    return laplacian_rms(rendered, mask) / ref


def foreground(img: np.ndarray, alpha: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool foreground: ``alpha`` if given, else any non-black 8-bit channel."""
    if alpha is not None:
        return np.asarray(alpha, bool)
    return as_srgb8(img).max(axis=-1) > 0


def hole_fraction(reference_fg: np.ndarray, rendered_fg: np.ndarray) -> float:
    """Share of the reference foreground that the rendering leaves empty (0 = no hole)."""
    ref = np.asarray(reference_fg, bool)
    n = int(ref.sum())
    if n == 0:
        return 0.0
    return float((ref & ~np.asarray(rendered_fg, bool)).sum() / n)


def largest_interior_hole(reference_fg: np.ndarray, rendered_fg: np.ndarray, erode: int = 2) -> int:
    """Pixels of the largest connected hole strictly inside the object: the reference
    foreground eroded by ``erode`` pixels (so silhouette disagreement is not counted),
    minus the rendered foreground; 4-connected components."""
    from scipy import ndimage

    ref = np.asarray(reference_fg, bool)
    inner = ndimage.binary_erosion(ref, iterations=erode) if erode > 0 else ref
    holes = inner & ~np.asarray(rendered_fg, bool)
    if not holes.any():
        return 0
    lab, n = ndimage.label(holes)
    return int(np.bincount(lab.ravel())[1:].max())


def compare(reference: np.ndarray, rendered: np.ndarray, ref_fg: np.ndarray | None = None,
            rendered_fg: np.ndarray | None = None) -> dict:
    """All scores of one view: psnr, ssim (full), psnr_masked, ssim_masked and sharpness (the
    sharpness ratio) inside the union of the reference and rendered foregrounds (default: their
    non-black 8-bit pixels, see :func:`foreground`), hole_fraction and largest_hole (pixels)."""
    rf = foreground(reference, ref_fg)
    ff = foreground(rendered, rendered_fg)
    union = rf | ff
    return {"psnr": psnr(reference, rendered), "ssim": ssim(reference, rendered),
            "psnr_masked": psnr(reference, rendered, union), "ssim_masked": ssim(reference, rendered, union),
            "sharpness": sharpness_ratio(reference, rendered, union),
            "hole_fraction": hole_fraction(rf, ff), "largest_hole": largest_interior_hole(rf, ff)}
