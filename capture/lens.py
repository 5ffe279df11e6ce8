"""Lens distortion: the models furrow reads, and undistortion to a pinhole camera at read time.

furrow's renderer and volume stage are pinhole only (capture.camera).  A capture whose lens has
distortion (nerfstudio ``camera_model`` OPENCV / OPENCV_FISHEYE, COLMAP SIMPLE_RADIAL, RADIAL,
OPENCV, OPENCV_FISHEYE, FULL_OPENCV) is undistorted once, when it is read, with OpenCV:

* the new pinhole camera keeps the distorted camera's matrix K and image size (default ``keep``):
  each pixel is resampled once, from the distorted pixel that sees the same ray, and nothing is
  rescaled; output pixels whose ray falls outside the distorted image (the corners, for barrel
  distortion) have colour 0, depth 0 (no measurement) and alpha 0.  Measured on the OPENCV conifer
  (docs/real_cameras.md): ``keep`` scores within 0.1 dB of the pinhole capture where ``crop`` lost
  0.26 dB (its zoom resamples every pixel a second time at another scale);
* ``crop`` is what nerfstudio's full-image data manager makes of it:
  ``cv2.getOptimalNewCameraMatrix(K, D, size, alpha=0)`` and the crop to its valid-pixel rectangle
  for the radial-tangential models, and
  ``cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(balance=0)`` at the same size for the
  fisheye one: every output pixel sees the scene, the corners of the distorted image are lost, the
  focal length grows.  ``full`` (alpha = 1, balance = 1) keeps every source pixel at the same image
  size, the focal length shrinks; pixels outside the distorted image are empty as with ``keep``;
* colour is resampled bilinearly in linear light, the alpha matte bilinearly, depth edge-aware
  (:func:`remap_depth`): bilinear only where the four source samples agree, else the nearest one,
  so no depth is ever averaged across an edge.

All pixel coordinates here are OpenCV's (centre of the top-left pixel at 0, 0: capture.camera),
which is also what the ``cv2`` undistortion functions use; the half-pixel shift of nerfstudio /
COLMAP principal points is done by the readers (capture.camera.cv_from_corner) before this.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Lens models after reading: radial-tangential (cv2 coefficient order k1 k2 p1 p2 [k3 [k4 k5 k6]])
#: and OpenCV's fisheye (k1 k2 k3 k4, equidistant).
PERSPECTIVE = "OPENCV"
FISHEYE = "OPENCV_FISHEYE"
#: nerfstudio transforms.json ``camera_model`` values furrow reads.
NERFSTUDIO_MODELS = ("PINHOLE", "SIMPLE_PINHOLE", "OPENCV", "OPENCV_FISHEYE")
#: COLMAP camera models furrow reads: name -> names of the extra (distortion) parameters, in order.
COLMAP_MODELS = {
    "SIMPLE_PINHOLE": (), "PINHOLE": (),
    "SIMPLE_RADIAL": ("k1",), "RADIAL": ("k1", "k2"),
    "OPENCV": ("k1", "k2", "p1", "p2"), "OPENCV_FISHEYE": ("k1", "k2", "k3", "k4"),
    "FULL_OPENCV": ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
}
#: Undistortion choices (module docstring); the default keeps K (no second rescale).
UNDISTORT_MODES = ("keep", "crop", "full")
DEFAULT_UNDISTORT = "keep"
#: One line per mode, for --help.
UNDISTORT_HELP = {"keep": "the camera matrix and size kept, each pixel resampled once (corners outside the lens's "
                          "image empty)",
                  "crop": "nerfstudio's: zoomed in until every pixel is valid, corners lost (a second rescale)",
                  "full": "zoomed out until every source pixel is kept, empty corners"}
#: Edge-aware depth resampling: the four source samples are interpolated only when
#: (max - min) <= this fraction of min (else the nearest sample is taken).
DEPTH_AGREE_REL = 0.01
#: The undistorted focal length must stay within this factor of the distorted one (else the
#: coefficients are absurd for the image: an error, not a camera of 1e300 pixels).
MAX_FOCAL_CHANGE = 8.0
#: Iterations / tolerance of the iterative point undistortion (cv2.undistortPoints with criteria).
UNDISTORT_ITERATIONS = 100
UNDISTORT_EPS = 1e-12


class LensError(ValueError):
    """An unsupported lens model or invalid coefficients (the caller adds the file)."""


@dataclass(frozen=True)
class Lens:
    """A lens distortion model.

    Attributes:
        model: :data:`PERSPECTIVE` (radial-tangential) or :data:`FISHEYE`.
        coeffs: the OpenCV distortion vector, unitless: perspective (k1, k2, p1, p2, k3, k4, k5,
            k6) padded with zeros; fisheye (k1, k2, k3, k4).
        source: the model's name as read (e.g. ``SIMPLE_RADIAL``), for messages and provenance.
    """

    model: str
    coeffs: tuple[float, ...]
    source: str = ""

    def __post_init__(self) -> None:
        n = 8 if self.model == PERSPECTIVE else 4 if self.model == FISHEYE else None
        if n is None:
            raise LensError(f"lens model {self.model!r} is not one of {PERSPECTIVE}, {FISHEYE}")
        c = tuple(float(x) for x in self.coeffs)
        if len(c) > n or not all(np.isfinite(c)):
            raise LensError(f"{self.model}: expected at most {n} finite coefficients, got {list(self.coeffs)}")
        object.__setattr__(self, "coeffs", c + (0.0,) * (n - len(c)))

    @property
    def fisheye(self) -> bool:
        return self.model == FISHEYE

    @property
    def dist(self) -> np.ndarray:
        """The coefficient vector as cv2 takes it (float64)."""
        return np.asarray(self.coeffs, np.float64)

    def record(self) -> dict:
        """JSON-able description (model, source, coefficients)."""
        return {"model": self.model, "source": self.source or self.model, "coeffs": list(self.coeffs)}


def lens_or_none(model: str, coeffs, source: str = "") -> Lens | None:
    """A Lens, or None when every coefficient is zero (a pinhole camera)."""
    coeffs = tuple(float(c) for c in coeffs)
    return Lens(model, coeffs, source) if any(c != 0 for c in coeffs) else None


def nerfstudio_lens(camera_model: str | None, value) -> Lens | None:
    """The lens of a transforms.json frame.  ``value(key)`` gives a distortion key's number
    (per frame or global) or None.  ``camera_model`` None: OPENCV when a coefficient is non-zero."""
    name = "OPENCV" if camera_model is None else str(camera_model)
    if name not in NERFSTUDIO_MODELS:
        raise LensError(f"camera_model {name!r} is not supported; supported: {', '.join(NERFSTUDIO_MODELS)}")
    v = {k: (value(k) or 0.0) for k in ("k1", "k2", "k3", "k4", "p1", "p2")}
    if name == "OPENCV_FISHEYE":
        bad = [k for k in ("p1", "p2") if v[k] != 0]
        if bad:
            raise LensError(f"camera_model OPENCV_FISHEYE has no tangential terms, but {bad[0]!r} is non-zero")
        return lens_or_none(FISHEYE, (v["k1"], v["k2"], v["k3"], v["k4"]), name)
    nonzero = [k for k, x in v.items() if x != 0]
    if name in ("PINHOLE", "SIMPLE_PINHOLE") and nonzero:
        raise LensError(f"camera_model {name} has no distortion, but {nonzero[0]!r} is non-zero "
                        "(write camera_model OPENCV or OPENCV_FISHEYE)")
    if v["k4"] != 0:
        raise LensError("camera_model OPENCV: 'k4' is non-zero; the radial-tangential model reads k1 k2 k3 p1 p2 "
                        "(nerfstudio does not undistort k4 either)")
    return lens_or_none(PERSPECTIVE, (v["k1"], v["k2"], v["p1"], v["p2"], v["k3"]), name)


def colmap_lens(model: str, extra) -> Lens | None:
    """The lens of a COLMAP camera from its model name and extra (distortion) parameters."""
    if model not in COLMAP_MODELS:
        raise LensError(f"COLMAP camera model {model} is not supported; supported: {', '.join(COLMAP_MODELS)}")
    names = COLMAP_MODELS[model]
    extra = tuple(float(e) for e in extra)
    if len(extra) != len(names):
        raise LensError(f"COLMAP camera model {model} needs {len(names)} distortion parameters "
                        f"({' '.join(names) or 'none'}), got {len(extra)}")
    if model == "OPENCV_FISHEYE":
        return lens_or_none(FISHEYE, extra, model)
    v = dict(zip(names, extra, strict=True))
    order = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
    return lens_or_none(PERSPECTIVE, tuple(v.get(k, 0.0) for k in order), model)


def nerfstudio_keys(lens: Lens | None) -> dict:
    """transforms.json keys (``camera_model`` and coefficients) of a lens (PINHOLE for None)."""
    if lens is None:
        return {"camera_model": "PINHOLE"}
    c = lens.coeffs
    if lens.fisheye:
        return {"camera_model": FISHEYE, "k1": c[0], "k2": c[1], "k3": c[2], "k4": c[3]}
    if any(c[5:]):
        raise LensError(f"{lens.source or lens.model}: k4-k6 cannot be written to transforms.json")
    return {"camera_model": PERSPECTIVE, "k1": c[0], "k2": c[1], "p1": c[2], "p2": c[3], "k3": c[4]}


# --------------------------------------------------------------------------- geometry
def distort_normalized(xy: np.ndarray, lens: Lens) -> np.ndarray:
    """(N, 2) ideal normalised image coordinates (x/z, y/z) -> distorted normalised ones (the
    forward model, OpenCV's equations)."""
    xy = np.asarray(xy, np.float64)
    x, y = xy[:, 0], xy[:, 1]
    c = lens.coeffs
    if lens.fisheye:
        r = np.hypot(x, y)
        th = np.arctan(r)
        th2 = th * th
        thd = th * (1 + th2 * (c[0] + th2 * (c[1] + th2 * (c[2] + th2 * c[3]))))
        s = np.where(r > 0, thd / np.where(r > 0, r, 1.0), 1.0)
        return np.stack([x * s, y * s], axis=1)
    k1, k2, p1, p2, k3, k4, k5, k6 = c
    r2 = x * x + y * y
    radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([xd, yd], axis=1)


def distort_pixels(uv: np.ndarray, K: np.ndarray, lens: Lens, K_new: np.ndarray | None = None) -> np.ndarray:
    """(N, 2) pixels of the pinhole camera ``K_new`` (default ``K``) -> pixels of the distorted
    camera (``K``, ``lens``) seeing the same rays."""
    K_new = K if K_new is None else K_new
    uv = np.asarray(uv, np.float64)
    xy = (uv - K_new[:2, 2]) / np.diag(K_new)[:2]
    d = distort_normalized(xy, lens)
    return d * np.diag(K)[:2] + K[:2, 2]


def undistort_pixels(uv: np.ndarray, K: np.ndarray, lens: Lens, K_new: np.ndarray | None = None) -> np.ndarray:
    """(N, 2) pixels of the distorted camera (``K``, ``lens``) -> pixels of the pinhole camera
    ``K_new`` (default ``K``): OpenCV's iterative undistortion, run to convergence."""
    import cv2

    K_new = K if K_new is None else K_new
    pts = np.asarray(uv, np.float64).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, UNDISTORT_ITERATIONS, UNDISTORT_EPS)
    if lens.fisheye:
        out = cv2.fisheye.undistortPoints(pts, K, lens.dist, P=K_new, criteria=crit)
    else:
        out = cv2.undistortPoints(pts, K, lens.dist, R=None, P=K_new, criteria=crit)
    return out.reshape(-1, 2)


def undistorted_camera(K: np.ndarray, lens: Lens, width: int, height: int,
                       mode: str = DEFAULT_UNDISTORT) -> tuple[np.ndarray, int, int]:
    """(K_new, width, height) of the pinhole camera a distorted one is undistorted to (module
    docstring: ``keep`` the same K and size, ``crop`` = nerfstudio's choice, ``full`` keeps every source
    pixel)."""

    if mode not in UNDISTORT_MODES:
        raise LensError(f"undistort mode must be one of {', '.join(UNDISTORT_MODES)}, got {mode!r}")
    K = np.asarray(K, np.float64)
    K_new, w, h = _new_camera(K, lens, (int(width), int(height)), mode)
    ratio = K_new[0, 0] / K[0, 0] if np.all(np.isfinite(K_new)) else np.inf
    if not 1 / MAX_FOCAL_CHANGE <= ratio <= MAX_FOCAL_CHANGE:
        raise LensError(f"{lens.source or lens.model} {list(lens.coeffs)}: undistortion changes the focal length "
                        f"by a factor {ratio:.3g} (distortion too strong for this image size?)")
    return K_new, w, h


def _new_camera(K: np.ndarray, lens: Lens, size: tuple[int, int], mode: str) -> tuple[np.ndarray, int, int]:
    import cv2

    if mode == "keep":
        return K.copy(), size[0], size[1]
    if lens.fisheye:
        balance = 0.0 if mode == "crop" else 1.0
        K_new = cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(K, lens.dist, size, np.eye(3),
                                                                       balance=balance)
        return np.asarray(K_new, np.float64), size[0], size[1]
    alpha = 0.0 if mode == "crop" else 1.0
    K_new, roi = cv2.getOptimalNewCameraMatrix(K, lens.dist, size, alpha)
    K_new = np.asarray(K_new, np.float64)
    if mode == "crop":
        x, y, w, h = (int(v) for v in roi)
        if w < 1 or h < 1:
            raise LensError(f"{lens.source or lens.model} {list(lens.coeffs)}: no valid pixel is left after "
                            "undistortion (distortion too strong for this image size?)")
        K_new[0, 2] -= x
        K_new[1, 2] -= y
        return K_new, w, h
    return K_new, size[0], size[1]


def undistort_maps(K: np.ndarray, lens: Lens, K_new: np.ndarray, width: int, height: int):
    """(map_x, map_y): (height, width) float32 source pixel coordinates in the distorted image of
    every pixel of the pinhole camera ``K_new`` (cv2.initUndistortRectifyMap / fisheye variant)."""
    import cv2

    size = (int(width), int(height))
    if lens.fisheye:
        mx, my = cv2.fisheye.initUndistortRectifyMap(K, lens.dist, np.eye(3), K_new, size, cv2.CV_32FC1)
    else:
        mx, my = cv2.initUndistortRectifyMap(K, lens.dist, None, K_new, size, cv2.CV_32FC1)
    return mx, my


def remap_bilinear(img: np.ndarray, mx: np.ndarray, my: np.ndarray) -> np.ndarray:
    """Bilinear resampling of a float image (H, W[, C]) at (mx, my); 0 outside it."""
    import cv2

    out = cv2.remap(np.ascontiguousarray(img, np.float32), mx, my, cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    return out.astype(np.float32)


def remap_depth(depth: np.ndarray, mx: np.ndarray, my: np.ndarray, rel: float = DEPTH_AGREE_REL) -> np.ndarray:
    """Edge-aware depth resampling at (mx, my): bilinear where the four source samples are all
    measured and agree within ``rel`` (relative), else the nearest sample (0 = no measurement
    stays 0); 0 outside the image.  No depth is ever averaged across an edge or a hole."""
    d = np.asarray(depth, np.float32)
    H, W = d.shape
    x0 = np.floor(mx).astype(np.int64)
    y0 = np.floor(my).astype(np.int64)
    fx = (mx - x0).astype(np.float32)
    fy = (my - y0).astype(np.float32)
    pad = np.pad(d, 1)  # index i + 1; the border ring is 0 = no measurement

    def at(xx, yy):
        return pad[np.clip(yy, -1, H) + 1, np.clip(xx, -1, W) + 1]

    d00, d10, d01, d11 = at(x0, y0), at(x0 + 1, y0), at(x0, y0 + 1), at(x0 + 1, y0 + 1)
    lo = np.minimum(np.minimum(d00, d10), np.minimum(d01, d11))
    hi = np.maximum(np.maximum(d00, d10), np.maximum(d01, d11))
    smooth = (lo > 0) & (hi - lo <= rel * lo)
    bil = (d00 * (1 - fx) + d10 * fx) * (1 - fy) + (d01 * (1 - fx) + d11 * fx) * fy
    nearest = at(np.floor(mx + 0.5).astype(np.int64), np.floor(my + 0.5).astype(np.int64))
    inside = (mx > -0.5) & (mx < W - 0.5) & (my > -0.5) & (my < H - 0.5)
    return np.where(inside, np.where(smooth, bil, nearest), 0.0).astype(np.float32)


def undistort_scan(scan, lens: Lens, K: np.ndarray, camera):
    """The Scan of distorted camera (``K``, ``lens``) resampled to the pinhole ``camera`` (its K,
    size and pose): colour bilinear in linear light (8-bit sRGB stays 8-bit sRGB), alpha bilinear,
    depth edge-aware (:func:`remap_depth`)."""
    from capture.scan import Scan, srgb_to_linear, to_uint8_srgb

    mx, my = undistort_maps(K, lens, camera.K, camera.width, camera.height)
    if scan.rgb.dtype == np.uint8:
        rgb = to_uint8_srgb(remap_bilinear(srgb_to_linear(scan.rgb.astype(np.float32) / 255.0), mx, my))
    else:
        rgb = remap_bilinear(scan.rgb, mx, my)
    alpha = None if scan.alpha is None else np.clip(remap_bilinear(scan.alpha, mx, my), 0.0, 1.0)
    return Scan(rgb, remap_depth(scan.depth, mx, my), camera, scan.name, alpha)
