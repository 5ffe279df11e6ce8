"""Background plates the user shot (``furrow model --background-plates DIR``; issue 30).

The VFX practice: the same camera path without the object, or a fixed camera's view of the empty
room.  DIR holds either one image for every frame (a fixed camera) or one image per frame named
like the frame's colour image (``images/r0_v000.png`` -> ``DIR/r0_v000.png``; any of
PLATE_EXTENSIONS).  A plate must show what the frame shows after reading: the same size (or the
same aspect at another resolution: it is resized to the frame's), colour 8-bit / 16-bit sRGB or
linear EXR.  Plates of a capture whose frames are undistorted at read time must be undistorted
the same way (they are not: a lens model is not applied to them).  :func:`user_plates` brings them
into each view's exposure (:func:`user_gains`) for capture.plate.background_plates.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from capture.imageio import ScanIOError, read_color
from capture.scan import srgb_to_linear

#: Image files taken as plates.
PLATE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr")
#: Largest difference of aspect ratio (relative) for a plate to be resized to its frame.
ASPECT_TOL = 0.01


def _linear(path: Path) -> np.ndarray:
    """(H, W, 3) float32 linear colour of a plate image (capture.imageio.read_color: 8-bit sRGB is
    decoded, 16-bit PNG and EXR come linear)."""
    img = read_color(path)
    if img.dtype == np.uint8:
        return srgb_to_linear(img.astype(np.float32) / 255.0)
    return np.clip(img, 0.0, None).astype(np.float32)


def _fit(plate: np.ndarray, shape: tuple[int, int], path: Path, frame: str) -> np.ndarray:
    """``plate`` at the frame's (H, W) size; ScanIOError naming the file when it cannot be."""
    import cv2

    h, w = plate.shape[:2]
    H, W = shape
    if (h, w) == (H, W):
        return plate
    if abs((w / h) / (W / H) - 1.0) > ASPECT_TOL:
        raise ScanIOError(f"{path}: plate is {w}x{h} but frame {frame!r} is {W}x{H} (another aspect ratio)")
    interp = cv2.INTER_AREA if w > W else cv2.INTER_LINEAR
    return cv2.resize(plate, (W, H), interpolation=interp).astype(np.float32)


def plate_files(folder: Path) -> list[Path]:
    """The plate images in ``folder`` (PLATE_EXTENSIONS), sorted; ScanIOError when there is none."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ScanIOError(f"{folder}: --background-plates must be a folder of plate images")
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in PLATE_EXTENSIONS and p.is_file())
    if not files:
        raise ScanIOError(f"{folder}: no plate images ({', '.join(PLATE_EXTENSIONS)})")
    return files


def read_user_plates(folder: Path, scans) -> list[np.ndarray]:
    """Per scan (``Scan`` / ``SpilledScan``: its ``name`` and ``camera``) its plate, (H, W, 3) float32
    linear (module docstring); one image in ``folder`` serves every frame."""
    files = plate_files(folder)
    by_stem = {p.stem: p for p in files}
    single = _linear(files[0]) if len(files) == 1 else None
    out = []
    for s in scans:
        shape = (s.camera.height, s.camera.width)
        if single is not None:
            out.append(_fit(single, shape, files[0], s.name))
            continue
        stem = Path(s.name).stem
        if stem not in by_stem:
            raise ScanIOError(f"{folder}: no plate for frame {s.name!r} (looked for {stem} + one of "
                              f"{', '.join(PLATE_EXTENSIONS)}; or leave one image for every frame)")
        out.append(_fit(_linear(by_stem[stem]), shape, by_stem[stem], s.name))
    return out


def user_gains(views, user: list[np.ndarray]) -> np.ndarray:
    """(V, 3) gain of each view (capture.plate.PlateView) relative to its user plate (the plate's exposure:
    gain 1), fitted on the view's confidently background pixels."""
    from capture.plate import GAIN_MIN_SAMPLES, _usable, source_mask

    g = np.ones((len(views), 3))
    for i, (v, u) in enumerate(zip(views, user, strict=True)):
        m = source_mask(v.object_depth)
        o = v.linear[m].astype(np.float64)
        p = np.asarray(u, np.float64)[m]
        ok = _usable(o) & _usable(p)
        if ok.sum() >= GAIN_MIN_SAMPLES:
            g[i] = np.exp(np.median(np.log(p[ok]) - np.log(o[ok]), axis=0))
    return g


def user_plates(views, user: list[np.ndarray]) -> tuple[list, dict]:
    """(capture.plate.Plate per view, the record): the user's plates in each view's exposure (:func:`user_gains`),
    their errors on the held-back ring; a plate that cannot beat the view's own nearby background is refused
    (capture.plate_gate)."""
    from capture.plate import _error, _plate, ring_pixels
    from capture.plate_gate import gate_plates, gate_record
    from capture.plate_record import plate_record

    g = user_gains(views, user)
    plates, rings = [], []
    for i, (v, u) in enumerate(zip(views, user, strict=True)):
        r = ring_pixels(v.object_depth)
        o, q = v.linear[r[:, 1], r[:, 0]].astype(np.float64), np.asarray(u)[r[:, 1], r[:, 0]] / g[i]
        rings.append((v.linear, v.object_depth, r, o, q))
        plates.append(_plate(v, np.asarray(u, np.float32) / g[i], np.ones(np.shape(v.object_depth), bool),
                             _error(o, q), "user"))
    plates, gate = gate_plates(rings, plates)
    return plates, gate_record(plate_record("user", plates, g, {}), gate)
