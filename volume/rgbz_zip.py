"""A compact rgbz.npz put together from members deflated elsewhere (issue 32): the RGBz stage's
workers deflate their own views' crops, the main process only copies the deflated bytes.

``volume.rgbz_store.save_crops`` (the reference) deflates every view's arrays in the process that
writes the file: 72 views at 1280x960 spent 3.0 s of the main process in zlib after the pool had
finished (docs/speed.md, round 13).  Here a worker makes each member with :func:`deflated_member`
(the ``.npy`` bytes ``numpy.lib.format.write_array`` writes, raw deflate at
``volume.rgbz_store.CROPS_DEFLATE_LEVEL``, their CRC-32) and writes its view's members as a
small zip file of their own (:func:`write_zip`); the main process reads them back as they are
(:func:`read_members`, no inflating) and writes them, in order, into the model's file
(:func:`write_zip`).  The file is a plain zip archive of deflated ``.npy`` members, as
``numpy.savez_compressed`` writes: ``numpy.load`` (and ``volume.rgbz_store.CropFile``) read it
unchanged, and every decoded array is the one the reference stores (tests/volume/test_rgbz_zip.py).

Zip64 is not written: :func:`fits` says whether an archive of these members stays within the
plain format's limits (4 GiB, 65,535 members); the caller takes the reference otherwise.
"""

from __future__ import annotations

import io
import struct
import time
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: The plain zip format's limits (no zip64): offsets and sizes below 4 GiB, at most 65,535 members.
ZIP_MAX_BYTES = 0xFFFFFFFF
ZIP_MAX_MEMBERS = 0xFFFF
#: Zip version 2.0 (deflate) written as "made by" and "needed to extract"; made by a Unix system.
_VERSION, _UNIX = 20, 3
#: Permission bits of a member (what zipfile gives one written with ``ZipFile.open(name, "w")``).
_EXTERNAL_ATTR = 0o600 << 16


@dataclass(frozen=True)
class Member:
    """One deflated member: its ``name`` (``v3_srgb.npy``), the raw deflate ``data``, the CRC-32 and
    the size of the bytes it inflates to."""

    name: str
    data: bytes
    crc: int
    size: int

    @property
    def sizes(self) -> tuple[str, int, int]:
        """(name, deflated bytes, inflated bytes): what :func:`fits` reads."""
        return self.name, len(self.data), self.size


def npy_bytes(array: np.ndarray) -> bytes:
    """The ``.npy`` file of ``array`` (what ``numpy.savez`` stores as a member)."""
    from numpy.lib import format as npformat

    buf = io.BytesIO()
    npformat.write_array(buf, np.ascontiguousarray(array), allow_pickle=False)
    return buf.getvalue()


def deflated_member(name: str, array: np.ndarray, level: int) -> Member:
    """The member ``name + '.npy'`` holding ``array``, deflated at ``level`` (zlib, raw stream as zip stores it)."""
    raw = npy_bytes(array)
    c = zlib.compressobj(level, zlib.DEFLATED, -15)
    return Member(name + ".npy", c.compress(raw) + c.flush(), zlib.crc32(raw), len(raw))


def fits(sizes) -> bool:
    """Whether members of ``sizes`` ((name, deflated bytes, inflated bytes) each: :func:`stored`,
    :meth:`Member.sizes`) make a zip archive within the plain format's limits (module docstring)."""
    sizes = list(sizes)
    total = sum(30 + 46 + 2 * len(name.encode()) + packed for name, packed, _ in sizes) + 22
    return len(sizes) <= ZIP_MAX_MEMBERS and total <= ZIP_MAX_BYTES and all(n <= ZIP_MAX_BYTES for _, _, n in sizes)


def _dos_time() -> tuple[int, int]:
    """(time, date) of now in the zip format's (DOS) fields."""
    t = time.localtime(time.time())
    dos_time = (t.tm_hour << 11) | (t.tm_min << 5) | (t.tm_sec // 2)
    return dos_time, ((t.tm_year - 1980) << 9) | (t.tm_mon << 5) | t.tm_mday


def write_zip(path: Path, members) -> None:
    """Write ``members`` (an iterable of :class:`Member`, consumed one at a time) as a zip archive at
    ``path`` (via a temporary name, renamed); ValueError past the plain format's limits."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    dtime, ddate = _dos_time()
    central = []
    with open(tmp, "wb") as fh:
        for m in members:
            name = m.name.encode("ascii")
            offset = fh.tell()
            if len(central) >= ZIP_MAX_MEMBERS or offset + len(m.data) > ZIP_MAX_BYTES or m.size > ZIP_MAX_BYTES:
                raise ValueError(f"{path}: past the zip format's limits without zip64")
            fh.write(struct.pack(zipfile.structFileHeader, zipfile.stringFileHeader, _VERSION, 0, 0,
                                 zipfile.ZIP_DEFLATED, dtime, ddate, m.crc, len(m.data), m.size, len(name), 0))
            fh.write(name)
            fh.write(m.data)
            central.append(struct.pack(zipfile.structCentralDir, zipfile.stringCentralDir, _VERSION, _UNIX, _VERSION,
                                       0, 0, zipfile.ZIP_DEFLATED, dtime, ddate, m.crc, len(m.data), m.size,
                                       len(name), 0, 0, 0, 0, _EXTERNAL_ATTR, offset) + name)
        start = fh.tell()
        for rec in central:
            fh.write(rec)
        size = fh.tell() - start
        if fh.tell() > ZIP_MAX_BYTES:
            raise ValueError(f"{path}: past the zip format's limits without zip64")
        fh.write(struct.pack(zipfile.structEndArchive, zipfile.stringEndArchive, 0, 0, len(central), len(central),
                             size, start, 0))
    tmp.rename(path)


def stored(path: Path) -> list[tuple[str, int, int]]:
    """(name, deflated bytes, inflated bytes) of each member of the zip archive at ``path``, its data not read."""
    with zipfile.ZipFile(path) as zf:
        return [(i.filename, i.compress_size, i.file_size) for i in zf.infolist()]


def read_members(path: Path) -> list[Member]:
    """The members of the zip archive at ``path`` as stored (deflated, not inflated); ValueError for a
    member that is not deflated."""
    out = []
    with zipfile.ZipFile(path) as zf, open(path, "rb") as fh:
        for info in zf.infolist():
            if info.compress_type != zipfile.ZIP_DEFLATED:
                raise ValueError(f"{path}: member {info.filename} is not deflated")
            fh.seek(info.header_offset)
            head = struct.unpack(zipfile.structFileHeader, fh.read(zipfile.sizeFileHeader))
            fh.seek(head[-2] + head[-1], io.SEEK_CUR)  # the local header's name and extra field
            out.append(Member(info.filename, fh.read(info.compress_size), info.CRC, info.file_size))
    return out
