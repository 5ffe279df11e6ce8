"""A furrow scan set opens in nerfstudio at the right depth (issue 14 item 1).

``nerfstudio_points`` reads a transforms.json the way nerfstudio's ``nerfstudio`` dataparser and
its depth datasets do, written here from their documented behaviour and independent of
``capture.io``: intrinsics ``fl_x fl_y cx cy w h`` (global or per frame), ``transform_matrix``
camera-to-world in OpenGL axes, ``file_path`` / ``depth_file_path`` relative to the json,
depth read with ``cv2.imread(..., IMREAD_ANYDEPTH)`` times the dataparser option
``depth_unit_scale_factor`` (default 1e-3; the json's own keys are never consulted), rays through
pixel centres at (i + 0.5, j + 0.5), depth along the camera's -z axis.  The dataparser's optional
re-orientation / re-centring / auto-scale are all off (``--orientation-method none
--center-method none --auto-scale-poses False``), so its world is the file's world.
"""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from capture.io import read_scanset, write_transforms
from tests.capture.test_io import sphere_scanset

#: nerfstudio's default ``--depth-unit-scale-factor`` (metres per stored unit).
NERFSTUDIO_DEPTH_SCALE = 1e-3
#: Agreement required between the two readers (issue 14: 0.5 mm).
AGREE_M = 5e-4


def nerfstudio_points(tj_path, depth_scale: float = NERFSTUDIO_DEPTH_SCALE) -> list[np.ndarray]:
    """Per frame: (H, W, 3) world points (NaN where depth is 0), read nerfstudio's way."""
    meta = json.loads(tj_path.read_text())
    out = []
    for fr in meta["frames"]:
        g = {k: float(fr.get(k, meta.get(k))) for k in ("fl_x", "fl_y", "cx", "cy", "w", "h")}
        c2w = np.asarray(fr["transform_matrix"], np.float64)[:3]
        raw = cv2.imread(str(tj_path.parent / fr["depth_file_path"]), cv2.IMREAD_ANYDEPTH)
        z = raw.astype(np.float64) * depth_scale
        H, W = int(g["h"]), int(g["w"])
        j, i = np.mgrid[0:H, 0:W].astype(np.float64)
        dirs = np.stack([(i + 0.5 - g["cx"]) / g["fl_x"], -(j + 0.5 - g["cy"]) / g["fl_y"], -np.ones_like(i)], -1)
        pts = (dirs * z[..., None]) @ c2w[:, :3].T + c2w[:, 3]
        pts[z <= 0] = np.nan
        out.append(pts)
    return out


@pytest.mark.parametrize("fmt", ["png", "png-0.1mm"])
def test_default_scan_set_reads_in_nerfstudio_like_in_furrow(tmp_path, fmt):
    ss = sphere_scanset(n=3, w=64, h=48)
    write_transforms(ss, tmp_path / "s", depth_format=fmt)
    meta = json.loads((tmp_path / "s" / "transforms.json").read_text())
    unit = {"png": 1e-3, "png-0.1mm": 1e-4}[fmt]
    assert meta["depth_unit_scale_factor"] == unit
    assert not any("depth_unit_scale_factor" in f for f in meta["frames"])  # one key, at the top
    ours = read_scanset(tmp_path / "s")
    # nerfstudio run as its users would: the default scale for our default millimetres, and
    # --depth-unit-scale-factor 1e-4 for the 0.1 mm variant
    theirs = nerfstudio_points(tmp_path / "s" / "transforms.json", depth_scale=unit)
    for scan, orig, pts in zip(ours.scans, ss.scans, theirs):
        p_ours, m = scan.camera.depth_to_points(scan.depth)
        assert np.array_equal(m, np.isfinite(pts[..., 0]))
        assert np.abs(pts[m] - p_ours).max() < AGREE_M
        # and both are within the quantisation (half a unit along z, stretched along the ray)
        p_true = orig.camera.depth_to_points(orig.depth)[0]
        ray_stretch = np.linalg.norm(orig.camera.pixel_rays(orig.camera.pixel_grid()[m]), axis=1)
        assert np.all(np.linalg.norm(pts[m] - p_true, axis=1) <= 0.5 * unit * ray_stretch + 1e-7)


def test_nerfstudio_default_scale_misreads_tenth_millimetres(tmp_path):
    """Why the default changed: 0.1 mm PNG read at nerfstudio's default scale is 10x too deep."""
    ss = sphere_scanset(n=1, w=64, h=48)
    write_transforms(ss, tmp_path / "s", depth_format="png-0.1mm")
    pts = nerfstudio_points(tmp_path / "s" / "transforms.json")[0]
    cam = ss.scans[0].camera
    m = np.isfinite(pts[..., 0])
    z = cam.world_to_cam(pts[m])[:, 2]
    np.testing.assert_allclose(z / ss.scans[0].depth[m], 10.0, rtol=2e-3)


def test_old_per_frame_units_still_read(tmp_path):
    """Scan sets written before the change (0.1 mm PNG, the factor inside each frame) still read."""
    ss = sphere_scanset(n=2, w=64, h=48)
    write_transforms(ss, tmp_path / "s", depth_format="png-0.1mm")
    p = tmp_path / "s" / "transforms.json"
    meta = json.loads(p.read_text())
    for f in meta["frames"]:
        f["depth_unit_scale_factor"] = meta["depth_unit_scale_factor"]
    meta["depth_unit_scale_factor"] = 1.0  # a per-frame key wins over the global one
    p.write_text(json.dumps(meta))
    back = read_scanset(p)
    for a, b in zip(ss.scans, back.scans):
        assert np.abs(a.depth - b.depth).max() <= 0.5e-4 + 1e-7
