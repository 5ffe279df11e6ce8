"""A sequence of multi-scale environment maps built offline and streamed frame by frame
(docs/methods.md §2 §4.4: an omnidirectional video -> one MSEM per frame, streamed from disk while
rendering). Frames are stored as float16 .npy volumes (memory-mapped on read) and uploaded into
one reused 3-D texture."""

from __future__ import annotations

import time
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from capture.atomic import atomic_write
from render.shading.envmap import EnvMap
from render.shading.msem import msem_build

#: Frame file pattern inside a video folder.
FRAME_NAME = "msem_{:05d}.npy"


def build_msem_video(frames: Iterable[EnvMap], s: int, out_dir, th: float = 0.001, **kw) -> dict:
    """Build one MSEM per environment frame and write them to ``out_dir`` (each file atomically).
    Returns {"paths": [...], "seconds": [...]} (build time per frame)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths, secs = [], []
    for i, env in enumerate(frames):
        t = time.perf_counter()
        vol = msem_build(env, s, th, **kw).volume.astype(np.float16)
        path = out / FRAME_NAME.format(i)
        with atomic_write(path) as tmp:
            np.save(tmp, vol)
        paths.append(path)
        secs.append(time.perf_counter() - t)
    return {"paths": paths, "seconds": secs}


class MsemStream:
    """Owns one RGB16F 3-D texture; ``frame(i)`` uploads frame i of a video folder into it."""

    def __init__(self, ctx, folder):
        import moderngl

        self.folder = Path(folder)
        self.paths = sorted(self.folder.glob("msem_*.npy"))
        if not self.paths:
            raise FileNotFoundError(f"MsemStream: no msem_*.npy frames in {self.folder}")
        first = np.load(self.paths[0], mmap_mode="r")
        s = first.shape[0]
        if first.shape != (s, s, s, 3):
            raise ValueError(f"MsemStream: {self.paths[0]} is not an (s, s, s, 3) volume: {first.shape}")
        self.size = s
        self.texture = ctx.texture3d((s, s, s), 3, dtype="f2")
        self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.texture.repeat_x = self.texture.repeat_y = self.texture.repeat_z = False
        self.current = -1

    def __len__(self) -> int:
        return len(self.paths)

    def frame(self, i: int):
        """Upload frame ``i`` (modulo the frame count) and return the texture."""
        i %= len(self.paths)
        if i != self.current:
            vol = np.load(self.paths[i], mmap_mode="r")
            if vol.shape != (self.size,) * 3 + (3,):
                raise ValueError(f"MsemStream: {self.paths[i]} has shape {vol.shape}, "
                                 f"expected {(self.size,) * 3 + (3,)}")
            self.texture.write(np.ascontiguousarray(np.transpose(vol, (2, 1, 0, 3)), np.float16).tobytes())
            self.current = i
        return self.texture

    def release(self) -> None:
        self.texture.release()
