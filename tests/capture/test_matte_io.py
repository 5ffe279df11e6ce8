"""Mattes on disk: transforms.json mask_path (binary, 8-bit soft, 16-bit) and RGBA colour alpha (capture.matte_io)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from capture.imageio import ScanIOError
from capture.io import read_scanset, write_transforms
from capture.matte_io import MATTE_SHARE_RATIO, matte_depth_shares, matte_verdict
from tests.scenes import make_scanset, ring_cameras, sphere_scene


@pytest.fixture()
def capture(tmp_path):
    ss = make_scanset(sphere_scene(), ring_cameras(2, 32, 24))
    return write_transforms(ss, tmp_path / "cap"), ss


def _set_masks(tj, masks: dict):
    meta = json.loads(tj.read_text())
    for i, rel in masks.items():
        meta["frames"][i]["mask_path"] = rel
    tj.write_text(json.dumps(meta))


def test_mask_path_binary_soft_and_16_bit(capture):
    tj, ss = capture
    soft = np.linspace(0, 255, 32 * 24).reshape(24, 32).astype(np.uint8)
    cv2.imwrite(str(tj.parent / "soft.png"), soft)
    cv2.imwrite(str(tj.parent / "bin.png"), (soft > 100).astype(np.uint8))
    _set_masks(tj, {0: "soft.png", 1: "bin.png"})
    s0, s1 = read_scanset(tj).scans
    assert np.allclose(s0.alpha, soft / 255.0, atol=1e-6)
    assert set(np.unique(s1.alpha)) == {0.0, 1.0}
    cv2.imwrite(str(tj.parent / "deep.png"), (soft.astype(np.uint16) * 257))
    _set_masks(tj, {0: "deep.png"})
    assert np.allclose(read_scanset(tj).scans[0].alpha, soft / 255.0, atol=1e-6)


def test_bad_masks_are_named(capture):
    tj, _ = capture
    cv2.imwrite(str(tj.parent / "small.png"), np.zeros((5, 5), np.uint8))
    _set_masks(tj, {0: "small.png"})
    with pytest.raises(ScanIOError, match="small.png: mask is 5x5 but its colour image is 32x24"):
        read_scanset(tj)
    _set_masks(tj, {0: "missing.png"})
    with pytest.raises(ScanIOError, match="missing.png: mask not found"):
        read_scanset(tj)
    _set_masks(tj, {0: 3})
    with pytest.raises(ScanIOError, match="'mask_path' must be a non-empty file path string"):
        read_scanset(tj)


def test_rgba_colour_supplies_its_alpha_unless_opaque(capture):
    tj, ss = capture
    meta = json.loads(tj.read_text())
    img = cv2.imread(str(tj.parent / meta["frames"][0]["file_path"]))
    a = np.zeros((24, 32), np.uint8)
    a[5:15, 8:20] = 200
    cv2.imwrite(str(tj.parent / meta["frames"][0]["file_path"]), np.dstack([img, a]))
    cv2.imwrite(str(tj.parent / meta["frames"][1]["file_path"]), np.dstack([img, np.full_like(a, 255)]))
    s0, s1 = read_scanset(tj).scans
    assert np.allclose(s0.alpha, a / 255.0) and s1.alpha is None
    # a written capture keys its mattes as mask_path and reads them back
    out = write_transforms(read_scanset(tj), tj.parent.parent / "again")
    fr = json.loads(out.read_text())["frames"]
    assert fr[0]["mask_path"] == "masks/cam_000.png" and "mask_path" not in fr[1]
    assert np.allclose(read_scanset(out).scans[0].alpha, a / 255.0, atol=0.5 / 255)


def _depth_and_matte(room: str):
    """An object's depth (a disc, 0.3 m) and its matte (soft at the rim), and behind it a wall at 0.6 m: none
    (``room`` "none"), on the top third of the frame ("part": a room or a table in the depth), or everywhere else
    ("all": a phone's LiDAR)."""
    yy, xx = np.mgrid[0:60, 0:80]
    r = np.hypot(yy - 30, xx - 40)
    alpha = np.clip(15.5 - r, 0.0, 1.0).astype(np.float32)
    depth = np.where(r < 15, 0.3, 0.0).astype(np.float32)
    wall = {"none": np.zeros_like(yy, bool), "part": yy < 22, "all": np.ones_like(yy, bool)}[room]
    return alpha, np.where((depth == 0) & wall, 0.6, depth).astype(np.float32)


@pytest.mark.parametrize("room", ["none", "part", "all"])
def test_inverted_mattes_are_told_by_the_depth(room):
    """Mattes whose object has depth and whose rest has less (or, with depth everywhere, is farther) are right;
    inverted (1 - alpha), the verdict says so; no matte, no verdict."""
    alpha, depth = _depth_and_matte(room)
    fg, bg, zf, zb = matte_depth_shares(alpha, depth)
    assert fg > 0.95 and zf == pytest.approx(0.3) and (bg > 0.9) == (room == "all")
    right = matte_verdict([(fg, bg, zf, zb)] * 3)
    assert right["views"] == 3 and not right["inverted"] and "cover the object" in right["message"], right
    wrong = matte_verdict([matte_depth_shares(1.0 - alpha, depth)] * 3)
    assert wrong["inverted"] and "inverted" in wrong["message"], wrong
    assert matte_verdict([None, None]) is None and MATTE_SHARE_RATIO == 0.5
