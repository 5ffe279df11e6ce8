"""Background plates the user shot (``furrow model --background-plates DIR``; issue 30).

The VFX practice: the same camera path without the object, or a fixed camera's view of the empty
room.  DIR holds either one image for every frame (a fixed camera) or one image per frame named
like the frame's colour image (``images/r0_v000.png`` -> ``DIR/r0_v000.png``; any of
PLATE_EXTENSIONS).  A plate must show what the frame shows after reading: the same size (or the
same aspect at another resolution: it is resized to the frame's), colour 8-bit / 16-bit sRGB or
linear EXR.  Plates of a capture whose frames are undistorted at read time must be undistorted
the same way (they are not: a lens model is not applied to them).
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
