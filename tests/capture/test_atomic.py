"""Atomic writes (capture.atomic): a failed write leaves the previous file or folder intact and
no temporary behind; a successful one replaces it."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from capture.atomic import atomic_dir, atomic_write
from capture.imageio import read_exr, write_exr, write_png


class Boom(RuntimeError):
    pass


def test_atomic_write_replaces_on_success(tmp_path):
    p = tmp_path / "a" / "x.txt"
    with atomic_write(p) as tmp:
        assert tmp.parent == p.parent and tmp.suffix == ".txt" and tmp != p
        tmp.write_text("one")
    with atomic_write(p) as tmp:
        tmp.write_text("two")
    assert p.read_text() == "two"
    assert sorted(q.name for q in p.parent.iterdir()) == ["x.txt"]


def test_atomic_write_failure_keeps_previous_file(tmp_path):
    p = tmp_path / "x.npy"
    np.save(p, np.arange(3))
    with pytest.raises(Boom):
        with atomic_write(p) as tmp:
            np.save(tmp, np.arange(5))
            raise Boom()
    np.testing.assert_array_equal(np.load(p), np.arange(3))
    assert [q.name for q in tmp_path.iterdir()] == ["x.npy"]


def test_atomic_write_failure_without_previous_file(tmp_path):
    with pytest.raises(Boom):
        with atomic_write(tmp_path / "new.bin") as tmp:
            tmp.write_bytes(b"partial")
            raise Boom()
    assert list(tmp_path.iterdir()) == []


def test_writers_failing_midway_leave_the_old_file(tmp_path, monkeypatch):
    import OpenEXR

    p = tmp_path / "d.exr"
    write_exr(p, np.ones((4, 6), np.float32))

    class HalfWrite:  # writes part of the file, then fails like a full disk
        def __init__(self, header, channels):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def write(self, name):
            with open(name, "wb") as f:
                f.write(b"v/1\x01 partial")
            raise OSError("No space left on device")

    with monkeypatch.context() as m:
        m.setattr(OpenEXR, "File", HalfWrite)
        with pytest.raises(OSError, match="No space"):
            write_exr(p, np.zeros((4, 6), np.float32))
    np.testing.assert_array_equal(read_exr(p), np.ones((4, 6), np.float32))
    q = tmp_path / "c.png"
    write_png(q, np.zeros((4, 6, 3), np.uint8))
    with pytest.raises(cv2.error):
        write_png(q, np.zeros((4, 6, 3), np.complex64))  # cv2 cannot encode complex pixels
    assert q.is_file()
    assert sorted(x.name for x in tmp_path.iterdir()) == ["c.png", "d.exr"]


def test_atomic_dir_replaces_on_success_and_keeps_old_on_failure(tmp_path):
    out = tmp_path / "model"
    with atomic_dir(out) as tmp:
        (tmp / "a.txt").write_text("v1")
    assert (out / "a.txt").read_text() == "v1"
    with pytest.raises(Boom):
        with atomic_dir(out) as tmp:
            (tmp / "a.txt").write_text("v2")
            (tmp / "b.txt").write_text("v2")
            raise Boom()
    assert sorted(q.name for q in out.iterdir()) == ["a.txt"]
    assert (out / "a.txt").read_text() == "v1"
    assert [q.name for q in tmp_path.iterdir()] == ["model"]
    with atomic_dir(out) as tmp:
        (tmp / "b.txt").write_text("v3")
    assert sorted(q.name for q in out.iterdir()) == ["b.txt"]
    assert [q.name for q in tmp_path.iterdir()] == ["model"]


def test_written_file_gets_a_normal_files_mode(tmp_path):
    """mkstemp creates 0600 files: the renamed result must be readable like any file the process creates."""
    import os

    from capture.atomic import atomic_write

    with atomic_write(tmp_path / "a.txt") as tmp:
        tmp.write_text("x")
    (tmp_path / "b.txt").write_text("x")
    assert os.stat(tmp_path / "a.txt").st_mode & 0o777 == os.stat(tmp_path / "b.txt").st_mode & 0o777


def test_built_folder_gets_a_normal_folders_mode(tmp_path):
    import os

    from capture.atomic import atomic_dir

    with atomic_dir(tmp_path / "d") as tmp:
        (tmp / "f").write_text("x")
    (tmp_path / "e").mkdir()
    assert os.stat(tmp_path / "d").st_mode & 0o777 == os.stat(tmp_path / "e").st_mode & 0o777
