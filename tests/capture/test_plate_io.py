"""Plates the user shot (capture.plate_io, ``--background-plates DIR``) against the true background.

The room of the turntable scene (tests/plate_scenes.py) written as the user's camera would write it
(8-bit sRGB PNG, 16-bit PNG, or one larger image for every frame), read back and drawn into each
view by the user path of capture.plate.background_plates.  Tolerances: half an 8-bit sRGB step in
linear light at the top of the range is 0.5 / 255 x 2.28 = 0.0045; the 16-bit step is 256 x
smaller; a plate at twice the frame's size (each pixel of the room repeated 2 x 2) is area-resized
back exactly, so it too is within the 8-bit tolerance (measured 0.0041).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from capture.imageio import ScanIOError, write_png
from capture.plate import PlateConfig, background_plates
from capture.plate_io import read_user_plates
from capture.scan import linear_to_srgb, to_uint8_srgb
from tests import plate_scenes as ps

#: |plate - truth| (linear) after an 8-bit sRGB round trip and a 16-bit one.
TOL_8BIT = 0.0045
TOL_16BIT = 1e-4


def _scans(views):
    """What read_user_plates reads of a scan: its name and its camera's size."""
    return [SimpleNamespace(name=f"images/r0_v{i:03d}.png", camera=v.camera) for i, v in enumerate(views)]


def _write_8bit(folder, names, img):
    folder.mkdir(exist_ok=True)
    for n in names:
        write_png(folder / f"{n}.png", to_uint8_srgb(img))


def test_one_plate_per_frame_by_name_through_the_user_path(tmp_path):
    views, room, _, _ = ps.turntable_capture(n=6)
    scans = _scans(views)
    _write_8bit(tmp_path / "plates", [f"r0_v{i:03d}" for i in range(len(views))], room)
    user = read_user_plates(tmp_path / "plates", scans)
    assert all(np.abs(u - room).max() <= TOL_8BIT for u in user)
    plates, rec = background_plates(views, PlateConfig(mode="user"), user=user)
    assert rec["mode"] == "user" and rec["band_known_mean"] == 1.0
    for p in plates:
        assert p.method == "user" and np.abs(p.background - room).max() <= TOL_8BIT


def test_sixteen_bit_plate_is_read_linear(tmp_path):
    views, room, _, _ = ps.turntable_capture(n=3)
    (tmp_path / "p").mkdir()
    code = np.round(linear_to_srgb(room) * 65535).astype(np.uint16)
    import cv2

    cv2.imwrite(str(tmp_path / "p" / "empty_room.png"), np.ascontiguousarray(code[..., ::-1]))
    user = read_user_plates(tmp_path / "p", _scans(views))
    assert len(user) == 3 and all(np.abs(u - room).max() <= TOL_16BIT for u in user)


def test_one_larger_plate_serves_every_frame(tmp_path):
    views, room, _, _ = ps.turntable_capture(n=4)
    big = np.repeat(np.repeat(room, 2, axis=0), 2, axis=1)  # the same room at twice the resolution
    _write_8bit(tmp_path / "p", ["empty"], big)
    user = read_user_plates(tmp_path / "p", _scans(views))
    for u in user:
        assert u.shape == room.shape
        assert np.abs(u - room).max() <= TOL_8BIT


def test_bad_plates_name_the_file_and_the_problem(tmp_path):
    views, room, _, _ = ps.turntable_capture(n=3)
    scans = _scans(views)
    with pytest.raises(ScanIOError, match="must be a folder"):
        read_user_plates(tmp_path / "missing", scans)
    (tmp_path / "empty").mkdir()
    with pytest.raises(ScanIOError, match="no plate images"):
        read_user_plates(tmp_path / "empty", scans)
    _write_8bit(tmp_path / "some", ["r0_v000", "r0_v001"], room)
    with pytest.raises(ScanIOError, match="no plate for frame 'images/r0_v002.png'"):
        read_user_plates(tmp_path / "some", scans)
    _write_8bit(tmp_path / "wide", ["all"], np.concatenate([room, room], axis=1))
    with pytest.raises(ScanIOError, match=r"all\.png: plate is 192x72 but frame .* \(another aspect ratio"):
        read_user_plates(tmp_path / "wide", scans)
