"""Scans kept on disk, read back one view at a time: peak memory bounded whatever the number of frames (issue 24).

A phone capture of 200 frames at 1920x1440 holds about 4 GB as Scans (8-bit colour plus float32
depth at the colour's size), and twice that once the matte stage has made float32 foregrounds.
:class:`ScanSpill` owns a temporary folder; :meth:`ScanSpill.keep` writes a Scan there and hands
back a :class:`SpilledScan`, which reads like a Scan (``rgb``, ``depth``, ``alpha``, ``camera``,
``name``, ``linear_rgb``, ``srgb8``, ``valid``, ``points()``) but holds only its camera and file
name.  Its arrays are read from disk when asked for; the last READ_CACHE_VIEWS views read stay
in memory (a stage reads a view's colour, depth and matte one after the other).

Nothing is lost or rounded: every array is stored as it is (same dtype, same values), so a
pipeline run over spilled scans gives the same model, bit for bit, as over Scans in memory
(tests/capture/test_scan_store.py).  Depth and matte, zero away from the object once the extent
stage has run, are stored as the bounding box of their non-zero pixels.

Stages that make new scans (reading, extent, matte, photometric gains, working scale) take a
``keep`` callable and pass each new Scan through it: :func:`keep_in_memory` (the identity) or
``spill.keep``.  :func:`spill_for` chooses by the size of the capture.
"""

from __future__ import annotations

import shutil
import struct
import tempfile
import threading
import zipfile
from collections import OrderedDict
from pathlib import Path

import numpy as np

from capture.sampling import mask_box
from capture.scan import Scan, srgb8_to_linear, to_uint8_srgb

#: Views whose arrays stay in memory after being read (each is at most colour + depth + matte).
READ_CACHE_VIEWS = 4
#: ``--spill auto``: scans go to disk when the capture's frames would take more than this in memory
#: (8-bit colour + float32 depth per pixel, counted over every frame: 128 MiB is 62 frames at 640x480,
#: 15 at 1280x960).  The matte stage's float foregrounds are 3x that again: a 72-view 1280x960 plant
#: peaked at 5.3 GB in memory and 1.2 GB spilled, with the same model; an 18-view 1280x960 one at
#: 1.66 GB in memory against 1.08 GB for 36 views spilled (furrow bench model --scale).
SPILL_AUTO_BYTES = 1 << 27
#: Bytes per pixel of a Scan read from an 8-bit image with depth (3 colour + 4 depth).
SCAN_BYTES_PER_PIXEL = 7
#: An array a new scan holds as it was read from an earlier file of the spill folder (the extent's
#: colour, the matte's depth) is stored as that file's name, not written again (:func:`write_scan`;
#: files leave the folder only with it).  False: every array written (the reference); the same arrays
#: read back either way (tests/capture/test_scan_store.py).
SPILL_REFERENCES = True
#: Spilled arrays are read in place from their (uncompressed) .npz file (:func:`_open_spilled`): each
#: member's .npy data from its offset, without zipfile's CRC-32 over every byte read (the files are this
#: run's own, written a moment before).  False: ``np.load`` (the reference).  The same arrays either way
#: (tests/capture/test_scan_store.py).
SPILL_READ_IN_PLACE = True
#: A new scan's float colour that is, outside one box, bit for bit the linear colour of an 8-bit colour read lately
#: from the folder (the matte's foreground: the photo's own colour away from the object) is stored as that
#: file's name, the box and the box's pixels (:func:`_rgb_base`), when the box is at most RGB_BASE_MAX_SHARE of
#: the frame.  Every byte written here is memory the system must hand over: on this machine (a VM whose freed
#: pages go back to its host) fresh page-cache pages cost 0.14-0.34 GB/s, and the 72-view 1280x960 capture
#: spilled 1.81 GB, 1.06 GB of it the matte's full-frame float colour (docs/speed.md round 22).  False: the
#: whole float colour written (the reference); the same arrays read back either way
#: (tests/capture/test_scan_store.py).
SPILL_RGB_BASE = True
#: The largest share of the frame :data:`SPILL_RGB_BASE`'s box may cover (beyond it the colour is written whole).
RGB_BASE_MAX_SHARE = 0.6
#: :func:`_rgb_base` first compares every RGB_BASE_STRIDE-th row and column (a colour of another view
#: differs nearly everywhere): the whole frame only where that sample's box, scaled, is under twice the limit.
RGB_BASE_STRIDE = 8
#: ``--spill`` choices (:func:`spill_for`).
SPILL_MODES = ("auto", "always", "never")


def keep_in_memory(scan: Scan) -> Scan:
    """The ``keep`` of a pipeline that holds its scans in memory: the scan itself."""
    return scan


def scan_has_alpha(scan) -> bool:
    """Whether a Scan or SpilledScan has a matte, without reading a spilled one's arrays."""
    return scan.has_alpha if isinstance(scan, SpilledScan) else scan.alpha is not None


def _crop(a: np.ndarray) -> tuple[np.ndarray, tuple[int, int, int, int]]:
    """(bounding-box crop of the non-zero pixels of a (H, W) map, (y0, x0, H, W))."""
    box = mask_box(a != 0)
    if box is None:
        return a[:0, :0].copy(), (0, 0, *a.shape)
    y0, y1, x0, x1 = box
    return np.ascontiguousarray(a[y0:y1, x0:x1]), (y0, x0, *a.shape)


def _sources(scan, folder: Path, readers) -> dict:
    """{key: a file of ``folder`` whose array ``key`` ('rgb', 'depth', 'alpha'), as a reader keeps it
    (read lately), is bit for bit the one ``scan`` holds}: the arrays a stage kept unchanged (a Scan
    holds its own copies, so the values are compared, not the objects)."""
    if isinstance(scan, SpilledScan):
        return {}
    held = {key: getattr(scan, key) for key in ("rgb", "depth", "alpha")}
    out = {}
    for rd in readers:
        with _READ_LOCK:
            cached = list(rd._cache.items())
        for f, arrays in cached:
            if f.parent != folder:
                continue
            for key, a in held.items():
                if a is not None and key not in out and _same_bits(arrays.get(key), a):
                    out[key] = f
    return out


def _rgb_base(rgb: np.ndarray, folder: Path, readers) -> tuple | None:
    """(the name of a file of ``folder`` whose 8-bit colour, as a reader keeps it, gives ``rgb`` (H, W, 3)
    float32 bit for bit outside a box, the box's pixels, (y0, x0, H, W)) with the smallest such box, or None
    (SPILL_RGB_BASE off, another dtype, no such colour, or every box over RGB_BASE_MAX_SHARE of the frame)."""
    if not SPILL_RGB_BASE or rgb.dtype != np.float32 or rgb.ndim != 3:
        return None
    bits = np.ascontiguousarray(rgb).view(np.uint32)
    best, limit = None, RGB_BASE_MAX_SHARE * rgb.shape[0] * rgb.shape[1]
    k = RGB_BASE_STRIDE
    sub = np.s_[::k, ::k]
    for rd in readers:
        with _READ_LOCK:
            cached = list(rd._cache.items())
        for f, arrays in cached:
            base = arrays.get("rgb")
            if f.parent != folder or base is None or base.dtype != np.uint8 or base.shape != rgb.shape:
                continue
            sample = _differ_box(srgb8_to_linear(np.ascontiguousarray(base[sub])), np.ascontiguousarray(bits[sub]))
            if _box_area(sample) * k * k > 2 * limit:
                continue  # another view's colour: the sample tells (a few ms)
            box = _differ_box(srgb8_to_linear(base), bits) or (0, 0, 0, 0)
            if _box_area(box) <= limit and (best is None or _box_area(box) < best[0]):
                best = (_box_area(box), f, box)
    if best is None:
        return None
    _, f, (y0, y1, x0, x1) = best
    return np.array(f.name), np.ascontiguousarray(rgb[y0:y1, x0:x1]), np.array((y0, x0, *rgb.shape[:2]), np.int64)


def _differ_box(linear: np.ndarray, bits: np.ndarray) -> tuple[int, int, int, int] | None:
    """(row0, row1, col0, col1) of the box around the pixels where float32 ``linear`` (h, w, 3) and the uint32
    ``bits`` of a colour differ, None where none does: capture.sampling.mask_box of the (h, w x 3) values, its
    columns brought back to pixels (its reductions then run over rows of w x 3 values, not over each pixel's
    three: ten times faster at 1280x960)."""
    h, w = bits.shape[:2]
    box = mask_box((np.ascontiguousarray(linear).view(np.uint32) != bits).reshape(h, w * 3))
    return None if box is None else (box[0], box[1], box[2] // 3, (box[3] - 1) // 3 + 1)


def _box_area(box) -> int:
    return 0 if box is None else (box[1] - box[0]) * (box[3] - box[2])


def _same_bits(a, b) -> bool:
    """Whether arrays ``a`` and ``b`` have the same shape, dtype and bytes (NaN and -0.0 included)."""
    if a is None or b is None or a.shape != b.shape or a.dtype != b.dtype:
        return False
    if a is b:
        return True
    x, y = np.ascontiguousarray(a).reshape(-1).view(np.uint8), np.ascontiguousarray(b).reshape(-1).view(np.uint8)
    step = max(1, len(x) // 4096)
    return bool(np.array_equal(x[::step], y[::step]) and np.array_equal(x, y))  # a sample first: most differ


class _InPlaceNpz:
    """An uncompressed .npz's members read in place (SPILL_READ_IN_PLACE): ``files`` and ``z[key]`` as
    ``np.load``'s NpzFile; owns the open file."""

    def __init__(self, f: Path):
        self._fh = open(f, "rb")
        try:
            with zipfile.ZipFile(self._fh) as z:
                infos = z.infolist()
            self._offsets = {zi.filename.removesuffix(".npy"): self._data_offset(f, zi) for zi in infos}
        except BaseException:
            self._fh.close()
            raise
        self.files = list(self._offsets)

    def _data_offset(self, f: Path, zi: zipfile.ZipInfo) -> int:
        self._fh.seek(zi.header_offset)
        head = self._fh.read(30)
        if zi.compress_type != zipfile.ZIP_STORED or head[:4] != b"PK\x03\x04":
            raise ValueError(f"{f}: member {zi.filename} is not a stored zip member; not a scan spill file")
        name_len, extra_len = struct.unpack("<HH", head[26:30])
        return zi.header_offset + 30 + name_len + extra_len

    def __getitem__(self, key: str) -> np.ndarray:
        self._fh.seek(self._offsets[key])
        return np.lib.format.read_array(self._fh, allow_pickle=False)

    def __enter__(self) -> _InPlaceNpz:
        return self

    def __exit__(self, *exc) -> None:
        self._fh.close()


def _open_spilled(f: Path):
    """The spilled file ``f`` opened for reading its arrays (SPILL_READ_IN_PLACE, else ``np.load``)."""
    return _InPlaceNpz(f) if SPILL_READ_IN_PLACE else np.load(f)


def _read_array(f: Path, key: str) -> np.ndarray | None:
    """Array ``key`` of the spilled file ``f`` ('rgb', 'depth' or 'alpha'; None for a missing matte),
    following a stored file name (write_scan) to the file that holds it."""
    with _open_spilled(f) as z:
        if key + "_ref" in z.files:
            return _read_array(f.parent / str(z[key + "_ref"]), key)
        if key == "rgb":
            if "rgb_base_ref" not in z.files:
                return z["rgb"]
            out = srgb8_to_linear(_read_array(f.parent / str(z["rgb_base_ref"]), "rgb"))
            y0, x0 = (int(v) for v in z["rgb_box"][:2])
            crop = z["rgb"]
            out[y0:y0 + crop.shape[0], x0:x0 + crop.shape[1]] = crop
            return out
        return _uncrop(z[key], z[key + "_box"]) if key + "_box" in z.files else None


def _uncrop(c: np.ndarray, box) -> np.ndarray:
    y0, x0, H, W = box
    out = np.zeros((H, W), c.dtype)
    out[y0:y0 + c.shape[0], x0:x0 + c.shape[1]] = c
    return out


def write_scan(f: Path, scan, readers=()) -> SpilledScan:
    """Write ``scan`` (a Scan or a SpilledScan) to the file ``f`` (via a temporary name, renamed) and
    hand back the :class:`SpilledScan` that reads it (bound to this process's :func:`reader`; a
    :class:`ScanSpill` adopts it).  What :meth:`ScanSpill.keep` does, callable in a worker process
    that was handed a file name (:meth:`ScanSpill.reserve`).  With SPILL_REFERENCES, an array the
    scan holds as it was read from an earlier file of the folder (by this process's reader or one
    of ``readers``) is stored as that file's name."""
    f = Path(f)
    rgb = np.asarray(scan.rgb)
    sources = _sources(scan, f.parent, (reader(), *readers)) if SPILL_REFERENCES else {}
    alpha = scan.alpha
    arrays = {}
    for key, a in (("rgb", rgb), ("depth", scan.depth), ("alpha", alpha)):
        if a is None:
            continue
        if key in sources:
            arrays[key + "_ref"] = np.array(sources[key].name)
        elif key == "rgb" and (based := _rgb_base(rgb, f.parent, (reader(), *readers))) is not None:
            arrays["rgb_base_ref"], arrays["rgb"], arrays["rgb_box"] = based
        elif key == "rgb":
            arrays["rgb"] = rgb
        else:
            arrays[key], box = _crop(np.asarray(a))
            arrays[key + "_box"] = np.array(box, np.int64)
    tmp = f.with_suffix(".tmp.npz")
    np.savez(tmp, **arrays)
    tmp.rename(f)
    return SpilledScan(reader(), f, scan.camera, scan.name, alpha is not None, rgb.dtype)


class SpillReader:
    """Reads spilled scans' arrays back, each one only when asked for, the last READ_CACHE_VIEWS
    views' arrays kept (module docstring).  Owns nothing on disk: :class:`ScanSpill` is the reader
    that owns its folder; a worker process reads the files it is handed with :func:`reader`."""

    def __init__(self):
        self._cache: OrderedDict[Path, dict] = OrderedDict()

    def _arrays(self, f: Path) -> dict:
        with _READ_LOCK:  # threads read side by side (the plate stage's views): the cache's order under a lock
            if f in self._cache:
                self._cache.move_to_end(f)
                return self._cache[f]
            if not f.parent.is_dir():
                raise RuntimeError(f"{f.parent}: the scan spill folder was closed or removed; its scans are gone")
            arrays = self._cache[f] = {}
            while len(self._cache) > READ_CACHE_VIEWS:
                self._cache.popitem(last=False)
            return arrays

    def array(self, sp: SpilledScan, key: str) -> np.ndarray | None:
        """One array of ``sp`` ('rgb', 'depth' or 'alpha'; None for a missing matte), read alone."""
        arrays = self._arrays(sp.file)
        if key not in arrays:
            arrays[key] = _read_array(sp.file, key)
        return arrays[key]

    def load(self, sp: SpilledScan) -> Scan:
        """The Scan ``sp`` reads (from the read cache when it was read lately)."""
        arrays = self._arrays(sp.file)
        if "scan" not in arrays:
            rgb, depth = self.array(sp, "rgb"), self.array(sp, "depth")
            alpha = self.array(sp, "alpha") if sp.has_alpha else None
            arrays["scan"] = Scan(rgb, depth, sp.camera, sp.name, alpha)  # validated again: cheap next to the read
        return arrays["scan"]


_READER: SpillReader | None = None
#: SpillReader's cache is reordered under this lock (a file's arrays, once handed out, stay valid when evicted).
_READ_LOCK = threading.Lock()


def reader() -> SpillReader:
    """This process's reader of spilled scans handed to it (a worker of the pipeline's pool)."""
    global _READER
    if _READER is None:
        _READER = SpillReader()
    return _READER


class ScanSpill(SpillReader):
    """A temporary folder of scans (module docstring); removed by :meth:`close` or on leaving ``with``."""

    def __init__(self, root: str | Path | None = None):
        super().__init__()
        self.path = Path(tempfile.mkdtemp(prefix="furrow-scans-", dir=root))
        self._n = 0

    def reserve(self) -> Path:
        """A new file name in the folder, for a scan written elsewhere (:func:`write_scan` in a worker)."""
        f = self.path / f"{self._n:06d}.npz"
        self._n += 1
        return f

    def keep(self, scan) -> SpilledScan:
        """Write ``scan`` (a Scan or a SpilledScan) to the folder; the SpilledScan that reads it back.
        A SpilledScan already in the folder (this spill's, or one a worker wrote there) is adopted as it
        is (its colour gains too: :meth:`SpilledScan.with_gain`)."""
        if isinstance(scan, SpilledScan) and scan.file.parent == self.path:
            if scan.spill is not self:
                scan = SpilledScan(self, scan.file, scan.camera, scan.name, scan.has_alpha, scan.rgb_dtype, scan.gains)
            return scan
        sp = write_scan(self.reserve(), scan, (self,))
        return SpilledScan(self, sp.file, sp.camera, sp.name, sp.has_alpha, sp.rgb_dtype)

    def close(self) -> None:
        self._cache.clear()
        shutil.rmtree(self.path, ignore_errors=True)

    def __enter__(self) -> ScanSpill:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _spilled_in_this_process(file, camera, name, has_alpha, rgb_dtype, gains=()) -> SpilledScan:
    return SpilledScan(reader(), Path(file), camera, name, has_alpha, rgb_dtype, gains)


class SpilledScan:
    """A Scan on disk (module docstring): the same attributes, its arrays read on access (each
    array alone: a stage that reads only the depth never reads the colour).  Pickled as its file
    name and camera: a worker process reads it with its own :func:`reader`."""

    __slots__ = ("spill", "file", "camera", "name", "has_alpha", "rgb_dtype", "gains")

    def __init__(self, spill: SpillReader, file: Path, camera, name: str, has_alpha: bool, rgb_dtype, gains=()):
        self.spill, self.file, self.camera, self.name = spill, file, camera, name
        self.has_alpha, self.rgb_dtype = has_alpha, np.dtype(rgb_dtype)
        self.gains = tuple(gains)

    def __reduce__(self):
        return _spilled_in_this_process, (str(self.file), self.camera, self.name, self.has_alpha, self.rgb_dtype.str,
                                          self.gains)

    def with_gain(self, gain: np.ndarray) -> SpilledScan:
        """This scan with its float32 colour times ``gain`` (3,) float32, the product made on each read
        (``rgb * gain``, after any earlier gains in turn: the values ``Scan(rgb * gain, ...)`` would
        store) and nothing written: the same file (capture.photometric.GAINS_ON_READ)."""
        if self.rgb_dtype != np.float32:
            raise ValueError(f"with_gain: float32 colour only, {self.name} has {self.rgb_dtype}")
        g = np.asarray(gain)
        if g.dtype != np.float32 or g.shape != (3,):
            raise ValueError(f"with_gain: gain must be (3,) float32, got {g.shape} {g.dtype}")
        return SpilledScan(self.spill, self.file, self.camera, self.name, self.has_alpha, self.rgb_dtype,
                           (*self.gains, g.copy()))

    def load(self) -> Scan:
        """The Scan itself (in memory)."""
        if self.gains:
            return Scan(self.rgb, self.depth, self.camera, self.name, self.alpha)
        return self.spill.load(self)

    @property
    def rgb(self) -> np.ndarray:
        rgb = self.spill.array(self, "rgb")
        for g in self.gains:
            rgb = rgb * g
        return rgb

    @property
    def depth(self) -> np.ndarray:
        return self.spill.array(self, "depth")

    @property
    def alpha(self) -> np.ndarray | None:
        return self.spill.array(self, "alpha") if self.has_alpha else None

    @property
    def linear_rgb(self) -> np.ndarray:
        rgb = self.rgb
        return srgb8_to_linear(rgb) if rgb.dtype == np.uint8 else rgb

    @property
    def srgb8(self) -> np.ndarray:
        rgb = self.rgb
        return rgb if rgb.dtype == np.uint8 else to_uint8_srgb(rgb)

    @property
    def valid(self) -> np.ndarray:
        return self.depth > 0

    def points(self) -> np.ndarray:
        return self.camera.depth_to_points(self.depth)[0]


def spill_for(n_pixels: int, mode: str = "auto", root: str | Path | None = None) -> ScanSpill | None:
    """The ScanSpill for a capture of ``n_pixels`` pixels over all its frames (None: keep the scans
    in memory): ``mode`` 'always', 'never' or 'auto' (on disk above SPILL_AUTO_BYTES)."""
    if mode not in SPILL_MODES:
        raise ValueError(f"--spill must be auto, always or never, got {mode!r}")
    if mode == "never" or (mode == "auto" and n_pixels * SCAN_BYTES_PER_PIXEL <= SPILL_AUTO_BYTES):
        return None
    return ScanSpill(root)
