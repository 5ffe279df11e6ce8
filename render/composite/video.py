"""MP4 video files: the one writer of the project (``write_mp4``).

H.264 in an MP4 container through imageio-ffmpeg (its wheel ships the ffmpeg binary, so nothing
is downloaded at run time).  Written atomically (capture.atomic): an interrupted export leaves
no half-written video.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

#: imageio-ffmpeg quality (0-10, 10 = best; ~5 is its default): 8 keeps thin strands crisp.
MP4_QUALITY = 8
#: yuv420p needs even frame sizes: odd ones are padded by repeating the last column / row.
MACRO_BLOCK = 2


def _even(img: np.ndarray) -> np.ndarray:
    H, W = img.shape[:2]
    pad = ((0, H % MACRO_BLOCK), (0, W % MACRO_BLOCK), (0, 0))
    return np.pad(img, pad, mode="edge") if any(p[1] for p in pad) else img


def write_mp4(frames: Iterable[np.ndarray], path: str | Path, fps: float, quality: int = MP4_QUALITY) -> int:
    """Write ``frames`` ((H, W, 3) uint8 sRGB, all one size; odd sizes padded to even) as an
    H.264 MP4 at ``fps`` frames per second.  Returns the number of frames written.

    The file appears only when every frame was written (capture.atomic.atomic_write); an empty
    sequence or frames of different sizes raise ValueError and leave nothing behind.
    """
    import imageio_ffmpeg

    from capture.atomic import atomic_write

    if not fps > 0:
        raise ValueError(f"fps must be > 0, got {fps}")
    path = Path(path)
    n = 0
    with atomic_write(path) as tmp:
        writer, size = None, None
        try:
            for frame in frames:
                img = np.asarray(frame)
                if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
                    raise ValueError(f"{path}: frames must be (H, W, 3) uint8, got {img.dtype} {img.shape}")
                if size is None:
                    size = img.shape[:2]
                    evened = _even(img)
                    writer = imageio_ffmpeg.write_frames(str(tmp), (evened.shape[1], evened.shape[0]), fps=fps,
                                                         quality=quality, macro_block_size=MACRO_BLOCK,
                                                         ffmpeg_log_level="error")
                    writer.send(None)
                elif img.shape[:2] != size:
                    raise ValueError(f"{path}: frame {n} is {img.shape[1]}x{img.shape[0]}, the first was "
                                     f"{size[1]}x{size[0]}")
                writer.send(np.ascontiguousarray(_even(img)))
                n += 1
            if n == 0:
                raise ValueError(f"{path}: no frames to write")
        finally:
            if writer is not None:
                writer.close()
    return n
