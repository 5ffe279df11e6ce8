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

The bytes are the ones ``zipfile`` writes for the reference (``ZipFile.open(name, "w",
force_zip64=True)`` on a seekable file, as ``volume.rgbz_store._member`` calls it): version 4.5, the
date 1980-01-01 of a ``ZipInfo`` made from a name, sizes 0xFFFFFFFF in each local header with a zip64
extra field holding them, and a plain central directory; so a spilled run's rgbz.npz is the in-memory
run's byte for byte (tests/furrow/test_cmd_model.py).  Offsets and the member count are not written in
zip64: :func:`fits` says whether an archive of these members stays within the plain format's limits
(4 GiB, 65,535 members); the caller takes the reference otherwise.
"""

from __future__ import annotations

import io
import itertools
import struct
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from volume.rgbz_store import COMPACT_KEY, CROPS_DEFLATE_LEVEL, RgbzCrop, crop_arrays

#: The plain zip format's limits (no zip64): offsets and sizes below 4 GiB, at most 65,535 members.
ZIP_MAX_BYTES = 0xFFFFFFFF
ZIP_MAX_MEMBERS = 0xFFFF
#: Zip version 4.5 (zip64, what ``zipfile`` writes with ``force_zip64``) as "made by" and "needed to
#: extract"; made by a Unix system.
_VERSION, _UNIX = 45, 3
#: The DOS (time, date) of 1980-01-01 00:00: a ``zipfile.ZipInfo`` made from a name alone.
_DOS_TIME, _DOS_DATE = 0, (1 << 5) | 1
#: The local header's zip64 extra field: id 1, 16 bytes (the inflated and deflated sizes).
_ZIP64_EXTRA = "<HHQQ"
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
    total = sum(30 + 20 + 46 + 2 * len(name.encode()) + packed for name, packed, _ in sizes) + 22
    return len(sizes) <= ZIP_MAX_MEMBERS and total <= ZIP_MAX_BYTES and all(n <= ZIP_MAX_BYTES for _, _, n in sizes)


def write_zip(path: Path, members) -> None:
    """Write ``members`` (an iterable of :class:`Member`, consumed one at a time) as a zip archive at
    ``path`` (via a temporary name, renamed); ValueError past the plain format's limits."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    dtime, ddate = _DOS_TIME, _DOS_DATE
    central = []
    with open(tmp, "wb") as fh:
        for m in members:
            name = m.name.encode("ascii")
            offset = fh.tell()
            if len(central) >= ZIP_MAX_MEMBERS or offset + len(m.data) > ZIP_MAX_BYTES or m.size > ZIP_MAX_BYTES:
                raise ValueError(f"{path}: past the zip format's limits without zip64")
            fh.write(struct.pack(zipfile.structFileHeader, zipfile.stringFileHeader, _VERSION, 0, 0,
                                 zipfile.ZIP_DEFLATED, dtime, ddate, m.crc, 0xFFFFFFFF, 0xFFFFFFFF, len(name),
                                 struct.calcsize(_ZIP64_EXTRA)))
            fh.write(name)
            fh.write(struct.pack(_ZIP64_EXTRA, 1, 16, m.size, len(m.data)))
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


@dataclass(frozen=True)
class DeflatedCrop:
    """A view's crop whose members a worker deflated (this module): the zip file holding them,
    the crop's rectangle and depth range (what the model's file keeps of every view beside them)."""

    file: Path
    rect: tuple
    z0: float
    dz: float


def deflate_crop(path: Path, n: int, c: RgbzCrop, with_alpha: bool) -> DeflatedCrop:
    """Write view ``n``'s members (:func:`crop_arrays`), deflated as :func:`save_crops` deflates
    them, to the zip file ``path`` (this module); the :class:`DeflatedCrop` naming it."""
    write_zip(path, (deflated_member(name, a, CROPS_DEFLATE_LEVEL) for name, a in crop_arrays(n, c, with_alpha)))
    return DeflatedCrop(Path(path), c.rect, c.z0, c.dz)


def save_deflated_crops(path: Path, crops) -> bool:
    """Write the crops a worker deflated (:class:`DeflatedCrop`, in view order) as :func:`save_crops`
    writes them, their members copied as deflated (the same file), each
    view's file removed once copied; False, with nothing written or removed, when the archive would
    pass the zip format's plain limits (the caller then takes :func:`save_crops`)."""
    crops = list(crops)
    tail = [deflated_member(COMPACT_KEY, np.asarray([c.rect for c in crops], np.int64).reshape(-1, 4),
                            CROPS_DEFLATE_LEVEL),
            deflated_member("ranges", np.asarray([(c.z0, c.dz) for c in crops], np.float64).reshape(-1, 2),
                            CROPS_DEFLATE_LEVEL)]
    if not fits([x for c in crops for x in stored(c.file)] + [m.sizes for m in tail]):
        return False
    write_zip(path, itertools.chain((m for c in crops for m in read_members(c.file)), tail))  # a view at a time
    for c in crops:
        Path(c.file).unlink()
    return True
