"""Radiance RGBE (.hdr) reader and writer (flat and new-style run-length scanlines).

imageio's FreeImage plugin is usually absent, so furrow reads .hdr itself. Only the common
``-Y H +X W`` orientation (top row first) is supported; anything else raises naming the file.
Format: Greg Ward, "Real Pixels", Graphics Gems II (1991).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from capture.atomic import atomic_write

_RES = re.compile(rb"^-Y\s+(\d+)\s+\+X\s+(\d+)\s*$")


def read_rgbe(path) -> np.ndarray:
    """(H, W, 3) float32 linear RGB of a Radiance .hdr file."""
    path = Path(path)
    raw = path.read_bytes()
    pos = 0

    def line() -> bytes:
        nonlocal pos
        end = raw.find(b"\n", pos)
        if end < 0:
            raise ValueError(f"{path}: truncated header")
        s = raw[pos:end]
        pos = end + 1
        return s

    first = line()
    if not (first.startswith(b"#?RADIANCE") or first.startswith(b"#?RGBE")):
        raise ValueError(f"{path}: not a Radiance .hdr file (starts with {first[:16]!r})")
    while True:
        s = line()
        if s.strip() == b"":
            break
        if s.startswith(b"FORMAT=") and s.strip() != b"FORMAT=32-bit_rle_rgbe":
            raise ValueError(f"{path}: unsupported {s.decode(errors='replace')}")
    m = _RES.match(line())
    if not m:
        raise ValueError(f"{path}: unsupported resolution line (only '-Y H +X W')")
    h, w = int(m.group(1)), int(m.group(2))
    buf = np.frombuffer(raw, np.uint8, offset=pos)
    # fewest bytes h x w pixels can take: run-length scanlines (4-byte header, runs of <= 127 per
    # channel, 2 bytes each) or flat 4-byte pixels -- checked before allocating h x w x 4 bytes
    least = h * min(4 * w, 4 + 8 * -(-w // 127))
    if h < 1 or w < 1 or buf.size < least:
        raise ValueError(f"{path}: header says {w}x{h} pixels but only {buf.size} bytes of pixel data follow "
                         f"(truncated or corrupt)")
    rgbe = np.empty((h, w, 4), np.uint8)
    i = 0
    for y in range(h):
        if (8 <= w < 32768 and i + 4 <= buf.size and buf[i] == 2 and buf[i + 1] == 2
                and not (buf[i + 2] & 0x80)):
            if (int(buf[i + 2]) << 8 | int(buf[i + 3])) != w:
                raise ValueError(f"{path}: scanline {y} width mismatch")
            i += 4
            for c in range(4):
                x = 0
                while x < w:
                    if i >= buf.size:
                        raise ValueError(f"{path}: truncated pixel data at row {y}")
                    n = int(buf[i])
                    i += 1
                    if n > 128:
                        n -= 128
                        if x + n > w or i >= buf.size:
                            raise ValueError(f"{path}: bad run at row {y}")
                        rgbe[y, x:x + n, c] = buf[i]
                        i += 1
                    else:
                        if n == 0 or x + n > w or i + n > buf.size:
                            raise ValueError(f"{path}: bad literal at row {y}")
                        rgbe[y, x:x + n, c] = buf[i:i + n]
                        i += n
                    x += n
        else:  # flat (uncompressed) scanline
            if i + 4 * w > buf.size:
                raise ValueError(f"{path}: truncated pixel data at row {y}")
            rgbe[y] = buf[i:i + 4 * w].reshape(w, 4)
            i += 4 * w
    return rgbe_to_float(rgbe)


def rgbe_to_float(rgbe: np.ndarray) -> np.ndarray:
    """(..., 4) uint8 RGBE -> (..., 3) float32: (m + 0.5) * 2^(e - 136); e == 0 means black."""
    e = rgbe[..., 3].astype(np.int32)
    scale = np.where(e > 0, np.ldexp(1.0, e - 136), 0.0)
    return ((rgbe[..., :3].astype(np.float64) + 0.5) * scale[..., None]).astype(np.float32)


def float_to_rgbe(rgb: np.ndarray) -> np.ndarray:
    """(..., 3) float -> (..., 4) uint8 RGBE (shared exponent of the largest channel)."""
    rgb = np.maximum(np.asarray(rgb, np.float64), 0)
    mx = rgb.max(-1)
    m, e = np.frexp(mx)  # mx = m * 2^e, m in [0.5, 1)
    ok = mx >= 1e-32
    scale = np.where(ok, 256.0 / np.where(ok, np.ldexp(1.0, e), 1.0), 0.0)
    out = np.zeros(rgb.shape[:-1] + (4,), np.uint8)
    out[..., :3] = np.clip(np.floor(rgb * scale[..., None]), 0, 255).astype(np.uint8)
    out[..., 3] = np.where(ok, np.clip(e + 128, 0, 255), 0).astype(np.uint8)
    return out


def _rle_channel(a: np.ndarray) -> bytes:
    out = bytearray()
    i, n = 0, len(a)
    while i < n:
        j = i
        while j < n and j - i < 127 and a[j] == a[i]:
            j += 1
        if j - i >= 3:
            out += bytes([128 + j - i, a[i]])
            i = j
            continue
        k = i  # literal run until a run of >= 3 starts
        while k < n and k - i < 128:
            if k + 2 < n and a[k] == a[k + 1] == a[k + 2]:
                break
            k += 1
        out += bytes([k - i]) + bytes(a[i:k])
        i = k
    return bytes(out)


def write_rgbe(path, rgb: np.ndarray) -> Path:
    """Write (H, W, 3) linear RGB as a run-length-encoded Radiance .hdr (atomic)."""
    path = Path(path)
    rgb = np.asarray(rgb)
    h, w = rgb.shape[:2]
    px = float_to_rgbe(rgb)
    body = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {h} +X {w}\n".encode())
    for y in range(h):
        if 8 <= w < 32768:
            body += bytes([2, 2, w >> 8, w & 255])
            for c in range(4):
                body += _rle_channel(px[y, :, c])
        else:
            body += px[y].tobytes()
    with atomic_write(path) as tmp:
        tmp.write_bytes(body)
    return path
