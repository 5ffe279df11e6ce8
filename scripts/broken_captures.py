"""Copies of a transforms.json capture broken the way a user's capture can be (docs/capture_formats.md, "Depth
that does not agree with its poses"): each a full copy (no links) under OUT/NAME.

    PYTHONPATH=. .venv/bin/python scripts/broken_captures.py CAPTURE OUT [NAME ...]

Names (default: all): rgba, rgb16, gray (the colour files re-encoded); unit10, unit2 (depth_unit_scale_factor
x 0.1, x 2); flipgl (the poses' y and z axes negated: OpenCV axes read as OpenGL's); invpose,
invcv (world-to-camera matrices where camera-to-world ones belong, in OpenGL / OpenCV axes); focal15, focal07
(fl_x, fl_y x 1.5, x 0.7; also focal08, focal09, focal11, focal12, focal125, focal20);
cx0 (principal point at (0, 0)); intr2, intr05 (fl_x, fl_y, cx, cy x 2, x 0.5: the
intrinsics of an image twice / half the size); shufdepth (each frame given the next frame's depth file); posemm,
pose05, pose3 (the poses' translations x 1000, x 0.5, x 3); rotscale (the rotations x 1.3: not rigid); flipdepth,
mirrordepth (each depth map upside down, left to right); range (each depth pixel the distance along its ray from the
camera's centre, not along the optical axis); disparity (1000 / z in metres: an
iPhone's disparity stored as millimetres); scaledrift, scaledrift5 (each frame's depth times its own factor within 15 %,
5 % either way: a monocular network's); blur (every sixth frame's colour and matte blurred along a line
2 % of the width: a shaken phone; blurphys: a blown-out channel stays blown out); vignette, vignette15 (the kept
frames darkened towards their corners, 0.7 / 0.85 of the centre's linear colour there: an uncorrected lens); jpeg90,
jpeg75 (the kept frames as JPEGs of that quality, 4:2:0: a phone's; jpeg90full: 4:4:4); lateralca (red and
blue magnified by 1 +- 0.003: a lens's lateral colour); flipcolour (each colour
image and matte upside down, the depth not).
Then ``furrow eval OUT/NAME --holdout 2 --methods gather`` for each.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import cv2
import numpy as np


def _frames(edit):
    def e(tj):
        for f in tj["frames"]:
            edit(f)
    return e


def _pose(edit):
    def e(f):
        m = np.array(f["transform_matrix"], np.float64)
        edit(m)
        f["transform_matrix"] = m.tolist()
    return _frames(e)


def _unit(k):
    def e(tj):
        tj["depth_unit_scale_factor"] = k * tj.get("depth_unit_scale_factor", 0.001)
    return e


def _focal(k):
    def e(tj):
        for d in [tj, *tj["frames"]]:  # shared intrinsics or each frame's
            for key in ("fl_x", "fl_y"):
                if key in d:
                    d[key] *= k
    return e


def _intrinsics(k):
    def e(tj):
        for d in [tj, *tj["frames"]]:  # the intrinsics of an image k times the size
            for key in ("fl_x", "fl_y", "cx", "cy"):
                if key in d:
                    d[key] *= k
    return e


def _shuffle_depth(d: Path, tj: dict) -> None:
    fr = tj["frames"]
    data = [(d / f["depth_file_path"]).read_bytes() for f in fr]
    for i, f in enumerate(fr):
        (d / f["depth_file_path"]).write_bytes(data[(i + 1) % len(fr)])


def _depth_maps(edit):
    def e(d: Path, tj: dict) -> None:
        for f in tj["frames"]:
            p = d / f["depth_file_path"]
            z = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
            cv2.imwrite(str(p), edit(z, {**tj, **f}))
    return e


def _masks(edit):
    def e(d: Path, tj: dict) -> None:
        for f in tj["frames"]:
            if f.get("mask_path"):
                p = d / f["mask_path"]
                cv2.imwrite(str(p), np.ascontiguousarray(edit(cv2.imread(str(p), cv2.IMREAD_UNCHANGED))))
    return e


def _range(z: np.ndarray, f: dict) -> np.ndarray:
    """The distance along each pixel's ray, the depth's own pixel grid scaled from the colour's intrinsics."""
    from capture.camera import cv_from_corner, resample_pixel_coords

    h, w = z.shape
    u = (resample_pixel_coords(np.arange(w), f["w"] / w) - cv_from_corner(f["cx"])) / f["fl_x"]
    v = (resample_pixel_coords(np.arange(h), f["h"] / h) - cv_from_corner(f["cy"])) / f["fl_y"]
    r = z * np.sqrt(1.0 + u[None, :] ** 2 + v[:, None] ** 2)
    return np.clip(np.rint(r), 0, 65535).astype(z.dtype)


def _disparity(z: np.ndarray, f: dict) -> np.ndarray:
    """Disparity where depth belongs: 1 / z in 1/m, times 1000 (an iPhone's AVDepthData read as disparity and
    stored as if it were millimetres); 0 kept."""
    v = z > 0
    out = np.zeros_like(z)
    out[v] = np.clip(np.rint(1e6 / z[v].astype(np.float64)), 1, 65535)
    return out


def _scale_drift(k: float):
    """Each frame's depth times its own factor within ``k`` either way (a monocular network's metric depth, whose
    scale drifts from frame to frame), seeded by the file's name."""
    import zlib

    def e(z: np.ndarray, f: dict) -> np.ndarray:
        x = np.random.default_rng(zlib.crc32(f["depth_file_path"].encode())).uniform(np.log(1 - k), np.log(1 + k))
        return np.clip(np.rint(z * np.exp(x)), 0, 65535).astype(z.dtype)
    return e


def _blur(blown_stays: bool):
    return lambda d, tj: _blur_frames(d, tj, blown_stays)


def _blur_frames(d: Path, tj: dict, blown_stays: bool = False) -> None:
    """Every sixth frame's colour and matte (i % 6 == 0: every third of the views ``furrow eval --holdout 2`` keeps)
    blurred along a line 2 % of the image's width long, at an angle seeded by the file's name (a shaken phone: the
    matte of a blurred photo is the blurred matte); ``blown_stays``: a colour channel blown out in the frame stays
    blown out (the light is smeared before the sensor clips it)."""
    import zlib

    for i, f in enumerate(tj["frames"]):
        if i % 6:
            continue
        for key in ("file_path", "mask_path"):
            if not f.get(key):
                continue
            p = d / f[key]
            im = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
            n = max(3, int(round(0.02 * im.shape[1])) | 1)
            k = np.zeros((n, n), np.float32)
            k[n // 2] = 1.0 / n
            a = np.random.default_rng(zlib.crc32(f["file_path"].encode())).uniform(0.0, 180.0)
            k = cv2.warpAffine(k, cv2.getRotationMatrix2D(((n - 1) / 2, (n - 1) / 2), a, 1.0), (n, n))
            out = cv2.filter2D(im, -1, k / k.sum(), borderType=cv2.BORDER_REFLECT)
            cv2.imwrite(str(p), np.where(im >= 254, im, out) if blown_stays and key == "file_path" else out)


def _kept_frames(d: Path, tj: dict, flags: int = cv2.IMREAD_UNCHANGED):
    """(frame entry, colour file, its image) of every frame ``furrow eval --holdout 2`` keeps (i % 2 == 0)."""
    for f in tj["frames"][0::2]:
        p = d / f["file_path"]
        yield f, p, cv2.imread(str(p), flags)


def _vignette(k: float):
    """Every frame ``furrow eval --holdout 2`` keeps (i % 2 == 0) darkened towards its corners as an uncorrected
    lens does: the linear colour times 1 - k r^2, r the distance from the image's centre over the half-diagonal
    (k 0.3: 0.7 at the corners, half a stop), a channel blown out in the frame left so (the lens darkens the light
    before the sensor clips it); the held-out frames stay the scene's own radiance."""
    return lambda d, tj: _vignette_files(d, tj, k)


def _vignette_files(d: Path, tj: dict, k: float) -> None:
    from capture.scan import srgb_to_linear, to_uint8_srgb

    for _, p, im in _kept_frames(d, tj):
        h, w = im.shape[:2]
        y, x = np.mgrid[0:h, 0:w].astype(np.float32)
        r2 = ((x - (w - 1) / 2) ** 2 + (y - (h - 1) / 2) ** 2) / (((w - 1) / 2) ** 2 + ((h - 1) / 2) ** 2)
        lin = srgb_to_linear(im[..., :3].astype(np.float32) / 255.0) * (1.0 - k * r2)[..., None]
        blown = im[..., :3] >= 254  # the lens darkens the light before the sensor clips: blown out stays blown out
        im[..., :3] = np.where(blown, im[..., :3], to_uint8_srgb(lin))
        cv2.imwrite(str(p), im)


def _lateral_ca(k: float):
    """Every frame ``furrow eval --holdout 2`` keeps (i % 2 == 0) with a lens's lateral chromatic aberration: red
    magnified by 1 + k about the image's centre, blue by 1 - k, in linear light (k 0.003: 1.2 pixels at a 640x480
    frame's corners); the held-out frames stay as rendered."""
    def e(d: Path, tj: dict) -> None:
        from capture.scan import srgb_to_linear, to_uint8_srgb

        for _, p, im in _kept_frames(d, tj, cv2.IMREAD_COLOR):
            h, w = im.shape[:2]
            lin = srgb_to_linear(im.astype(np.float32) / 255.0)
            y, x = np.mgrid[0:h, 0:w].astype(np.float32)
            cx, cy = (w - 1) / 2, (h - 1) / 2
            for c, m in ((2, 1.0 + k), (0, 1.0 - k)):  # BGR: red, blue
                lin[..., c] = cv2.remap(np.ascontiguousarray(lin[..., c]), cx + (x - cx) / m, cy + (y - cy) / m,
                                        cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
            cv2.imwrite(str(p), to_uint8_srgb(lin))
    return e


def _jpeg(quality: int, full_chroma: bool = False):
    """Every frame ``furrow eval --holdout 2`` keeps (i % 2 == 0) written as a JPEG of ``quality`` with OpenCV's
    defaults (4:2:0 chroma: a phone's; ``full_chroma``: 4:4:4), its ``file_path`` renamed; the held-out frames stay
    PNG."""
    flags = [cv2.IMWRITE_JPEG_QUALITY, int(quality)] + \
        ([cv2.IMWRITE_JPEG_SAMPLING_FACTOR, cv2.IMWRITE_JPEG_SAMPLING_FACTOR_444] if full_chroma else [])

    def e(d: Path, tj: dict) -> None:
        for f, p, im in _kept_frames(d, tj, cv2.IMREAD_COLOR):
            q = p.with_suffix(".jpg")
            cv2.imwrite(str(q), im, flags)
            p.unlink()
            f["file_path"] = str(Path(f["file_path"]).with_suffix(".jpg"))
        (d / "transforms.json").write_text(json.dumps(tj, indent=1))
    return e


def _scale_t(k):
    def e(m):
        m[:3, 3] *= k
    return e


def _flip(m):
    m[:3, 1:3] *= -1


def _invert(m):
    m[:] = np.linalg.inv(m)


def _invert_cv(m):
    m[:] = np.linalg.inv(m)
    m[1:3, :] *= -1  # the y and z rows negated: OpenCV axes


def _rot13(m):
    m[:3, :3] *= 1.3


VARIANTS = {
    "rgba": {"image": lambda im: cv2.cvtColor(im, cv2.COLOR_BGR2BGRA)},
    "rgb16": {"image": lambda im: im.astype(np.uint16) * 257},
    "gray": {"image": lambda im: cv2.cvtColor(im, cv2.COLOR_BGR2GRAY)},
    "unit10": {"meta": _unit(0.1)},
    "unit2": {"meta": _unit(2.0)},
    "flipgl": {"meta": _pose(_flip)},
    "invpose": {"meta": _pose(_invert)},
    "invcv": {"meta": _pose(_invert_cv)},
    "focal15": {"meta": _focal(1.5)},
    "focal07": {"meta": _focal(0.7)},
    **{f"focal{n}": {"meta": _focal(k)} for n, k in (("08", 0.8), ("09", 0.9), ("11", 1.1), ("12", 1.2),
                                                      ("125", 1.25), ("20", 2.0))},
    "cx0": {"meta": _frames(lambda f: f.update(cx=0.0, cy=0.0))},
    "intr2": {"meta": _intrinsics(2.0)},
    "intr05": {"meta": _intrinsics(0.5)},
    "shufdepth": {"files": _shuffle_depth},
    "posemm": {"meta": _pose(_scale_t(1000.0))},
    "pose05": {"meta": _pose(_scale_t(0.5))},
    "pose3": {"meta": _pose(_scale_t(3.0))},
    "rotscale": {"meta": _pose(_rot13)},
    "flipdepth": {"files": _depth_maps(lambda z, f: np.ascontiguousarray(z[::-1]))},
    "mirrordepth": {"files": _depth_maps(lambda z, f: np.ascontiguousarray(z[:, ::-1]))},
    "range": {"files": _depth_maps(_range)},
    "disparity": {"files": _depth_maps(_disparity)},
    "scaledrift": {"files": _depth_maps(_scale_drift(0.15))},
    "scaledrift5": {"files": _depth_maps(_scale_drift(0.05))},
    "blur": {"files": _blur(False)},
    "blurphys": {"files": _blur(True)},
    "vignette": {"files": _vignette(0.3)},
    "vignette15": {"files": _vignette(0.15)},
    "jpeg90": {"files": _jpeg(90)},
    "jpeg75": {"files": _jpeg(75)},
    "jpeg90full": {"files": _jpeg(90, True)},
    "lateralca": {"files": _lateral_ca(0.003)},
    "flipcolour": {"image": lambda im: np.ascontiguousarray(im[::-1]), "files": _masks(lambda m: m[::-1])},
}


def broken_copy(src: Path, out: Path, name: str) -> Path:
    """OUT/NAME: a copy of the capture ``src`` broken as ``name`` (module docstring)."""
    v = VARIANTS[name]
    d = out / name
    if d.exists():
        shutil.rmtree(d)
    shutil.copytree(src, d, symlinks=False)
    tj = json.loads((d / "transforms.json").read_text())
    if "meta" in v:
        v["meta"](tj)
    (d / "transforms.json").write_text(json.dumps(tj, indent=1))
    if "image" in v:
        for f in tj["frames"]:
            p = d / f["file_path"]
            cv2.imwrite(str(p), v["image"](cv2.imread(str(p), cv2.IMREAD_UNCHANGED)))
    if "files" in v:
        v["files"](d, tj)
    return d


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("capture", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("names", nargs="*", choices=[[], *VARIANTS], default=[])
    a = ap.parse_args()
    for name in a.names or VARIANTS:
        print(broken_copy(a.capture, a.out, name))


if __name__ == "__main__":
    main()
