"""Scans spilled to disk (capture.scan_store): read back exactly, a bounded read cache, the same
model bit for bit as from scans in memory, and the reader / stages handing each scan to ``keep``."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from capture.io import auto_bounds, read_scanset, write_transforms
from capture.scan import MAX_SAMPLED_POINTS, Scan, sampled_points, to_uint8_srgb
from capture.scan_store import (
    READ_CACHE_VIEWS,
    SCAN_BYTES_PER_PIXEL,
    SPILL_AUTO_BYTES,
    ScanSpill,
    SpilledScan,
    spill_for,
)
from tests.scenes import furball_scene, make_scanset, ring_cameras, scan_ring, sphere_scene


@pytest.fixture(scope="module")
def fur():
    return make_scanset(furball_scene(n=150), ring_cameras(6, 96, 72), noise=0.001, holes=0.05)


def _with_alpha(scan: Scan, float_rgb: bool) -> Scan:
    alpha = (scan.depth > 0).astype(np.float32) * 0.75
    rgb = scan.linear_rgb if float_rgb else scan.rgb
    return Scan(rgb, scan.depth, scan.camera, scan.name, alpha)


@pytest.mark.parametrize("float_rgb", [False, True])
def test_spilled_scan_reads_back_exactly(fur, float_rgb):
    with ScanSpill() as spill:
        for scan in (fur.scans[0], _with_alpha(fur.scans[1], float_rgb)):
            sp = spill.keep(scan)
            assert isinstance(sp, SpilledScan) and spill.keep(sp) is sp  # kept once
            for attr in ("rgb", "depth", "linear_rgb", "srgb8", "valid"):
                a, b = getattr(sp, attr), getattr(scan, attr)
                assert a.dtype == b.dtype
                np.testing.assert_array_equal(a, b)
            assert (sp.alpha is None) == (scan.alpha is None)
            if scan.alpha is not None:
                np.testing.assert_array_equal(sp.alpha, scan.alpha)
            np.testing.assert_array_equal(sp.points(), scan.points())
            assert sp.camera is scan.camera and sp.name == scan.name
        folder = spill.path
        assert folder.is_dir()
    assert not folder.exists()  # removed on leaving ``with``
    with pytest.raises(RuntimeError, match="closed"):
        sp.load()


def test_read_cache_is_bounded(fur):
    with ScanSpill() as spill:
        kept = [spill.keep(s) for s in fur.scans]
        for sp in kept:
            _ = sp.depth
        assert len(spill._cache) == min(READ_CACHE_VIEWS, len(kept))
        assert sp.load() is sp.load()  # the last read view comes from the cache


def test_spill_for_chooses_by_size():
    small = SPILL_AUTO_BYTES // SCAN_BYTES_PER_PIXEL
    assert spill_for(small) is None
    with spill_for(small + 1) as s:
        assert isinstance(s, ScanSpill)
    assert spill_for(10 ** 12, "never") is None
    with spill_for(1, "always") as s:
        assert isinstance(s, ScanSpill)
    with pytest.raises(ValueError, match="--spill"):
        spill_for(1, "sometimes")


def test_model_from_spilled_scans_is_the_same(fur, tmp_path):
    """The whole pipeline (reading, extent, matte, photometric, fusion, RGBz) with every view on disk
    (--spill always: each view kept in the spill folder as soon as a stage makes it, the RGBz crops
    streamed to a file there) gives the model built with the views in memory, array for array, and
    saves it; the spill folder really held the views."""
    from capture.sources import open_source
    from volume.model import load_model
    from volume.pipeline.config import FuseConfig, PipelineConfig, SaveConfig
    from volume.pipeline.runner import run_pipeline
    from volume.pyramid import LoptConfig

    tj = write_transforms(fur, tmp_path / "capture")
    cfg = PipelineConfig(fuse=FuseConfig(lopt=LoptConfig(max_res=32)))
    with run_pipeline(open_source(tj), replace(cfg, spill="never")) as ref_run:
        ref, ref_summary = ref_run.model, ref_run.summary()
        assert ref_run.spill is None and ref.rgbz.crop_file is None
    with run_pipeline(open_source(tj), replace(cfg, spill="always", save=SaveConfig(out=tmp_path / "m"))) as run:
        got, summary = run.model, run.summary()
        assert all(isinstance(s, SpilledScan) for s in run.work.scans)
        assert got.rgbz.crop_file is not None and got.rgbz.crop_file.parent == run.spill.path
        for a, b in zip(ref.pyramid.levels, got.pyramid.levels, strict=True):
            np.testing.assert_array_equal(a.surface, b.surface)
            if a.values is not None:
                np.testing.assert_array_equal(a.values, b.values)
        for n in range(len(ref.rgbz)):
            for x, y in zip(ref.rgbz.view(n), got.rgbz.view(n), strict=True):
                np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(ref.mesh_vertices, got.mesh_vertices)
        np.testing.assert_array_equal(ref.spheres.centers, got.spheres.centers)
        folder = run.spill.path
    assert not folder.exists()  # the run's spill folder is removed with it
    assert summary["l_opt"] == ref_summary["l_opt"] and summary["spill"] == "disk"
    back = load_model(tmp_path / "m")  # the spill folder is gone; the saved crops are the model's own
    for n in range(len(ref.rgbz)):
        for x, y in zip(ref.rgbz.view(n), back.rgbz.view(n), strict=True):
            np.testing.assert_array_equal(x, y)


def test_reader_hands_each_scan_to_keep(tmp_path):
    ss = make_scanset(sphere_scene(), scan_ring(4, 64, 48))
    tj = write_transforms(ss, tmp_path / "s", depth_size=(16, 12))
    ref = read_scanset(tj)
    assert ref.metadata["depth_size"] == [16, 12]
    with ScanSpill() as spill:
        got = read_scanset(tj, keep=spill.keep)
        assert all(isinstance(s, SpilledScan) for s in got.scans)
        np.testing.assert_array_equal(got.bounds, ref.bounds)
        for a, b in zip(got.scans, ref.scans, strict=True):
            np.testing.assert_array_equal(a.depth, b.depth)
            np.testing.assert_array_equal(a.rgb, b.rgb)


def test_sampled_points_stride(fur):
    full = sampled_points(fur.scans)
    assert len(full) == sum(int(np.count_nonzero(s.depth > 0)) for s in fur.scans) and len(full) < MAX_SAMPLED_POINTS
    part = sampled_points(fur.scans, len(full) // 4)
    assert len(full) // 8 <= len(part) <= len(full) // 4 + len(fur.scans)  # stride k = ceil(total / max)
    # a regular sample: the robust box moves by little (metres)
    lo, hi = np.percentile(full, [0.5, 99.5], axis=0), np.percentile(part, [0.5, 99.5], axis=0)
    assert np.max(np.abs(lo - hi)) < 0.01
    # only the sampled pixels back-projected: the rows of every scan's points()[::k] (the reference)
    k = -(-len(full) // (len(full) // 4))
    np.testing.assert_array_equal(part, np.concatenate([s.points()[::k] for s in fur.scans]))


def test_auto_bounds_hold_the_object_and_little_more(fur):
    """The automatic bounds against the fur ball's true geometry (tests.scenes.furball_scene: a
    5 cm core with strands to at most 9 cm from the centre): the core inside on every side, nothing
    beyond the strands' reach plus AUTO_BOUNDS_MARGIN of the diagonal."""
    from capture.io import AUTO_BOUNDS_MARGIN

    b = auto_bounds(fur.scans)
    core, reach = 0.05, 0.05 + 0.04
    assert np.all(b[0] < -core) and np.all(b[1] > core)
    slack = AUTO_BOUNDS_MARGIN * np.linalg.norm(b[1] - b[0])
    assert np.all(b[0] > -reach - slack) and np.all(b[1] < reach + slack)


def test_sampled_points_do_not_keep_every_scans_points():
    """A strided sample of each scan's points must not keep the scan's full point array alive
    (it did: 9.6 GB on 200 phone frames); the peak stays near one scan's points."""
    import tracemalloc

    from capture.camera import Camera

    cam = ring_cameras(1, 200, 150)[0]
    scans = [Scan(np.zeros((150, 200, 3), np.uint8), np.full((150, 200), 0.45, np.float32),
                  Camera(cam.K, cam.cam_from_world, 200, 150), f"s{i}") for i in range(16)]
    one = 200 * 150 * 3 * 8  # bytes of one scan's float64 points
    tracemalloc.start()
    pts = sampled_points(scans, 1000)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert len(pts) <= 1000 + len(scans)
    assert peak < 8 * one, (peak, one)  # measured: 4.7x (back-projection temporaries); 19.6x with the views kept


@pytest.mark.parametrize("cv2_lookup", [True, False])
def test_linear_colour_lookup_equals_the_srgb_formula(monkeypatch, cv2_lookup):
    """capture.scan.srgb8_to_linear (Scan.linear_rgb, SpilledScan.linear_rgb) is srgb_to_linear of
    the 8-bit codes over 255, bit for bit, on a frame-sized image and on small odd ones, by OpenCV's
    lookup and by numpy's (SRGB8_CV2)."""
    import capture.scan as scan_mod
    from capture.scan import srgb8_to_linear, srgb_to_linear

    monkeypatch.setattr(scan_mod, "SRGB8_CV2", cv2_lookup)
    rng = np.random.default_rng(0)
    for shape in [(1440, 1920, 3), (7, 5, 3), (1, 1, 3), (256,), (9, 11), (5, 4, 4), (3, 2, 6)]:
        x = np.arange(256, dtype=np.uint8) if shape == (256,) else rng.integers(0, 256, shape).astype(np.uint8)
        got = srgb8_to_linear(x)
        assert got.dtype == np.float32 and np.array_equal(got, srgb_to_linear(x.astype(np.float32) / 255.0))


def test_bounds_steps_equal_their_numpy_forms():
    """Issue 32 round 10: every k-th point by flat indices, the finite rows by columns and both
    percentiles in one call give what np.nonzero, np.all(axis=1) and two calls give, bit for bit."""
    from capture.io import AUTO_BOUNDS_PERCENTILES, finite_rows
    from capture.scan import every_kth_point

    rng = np.random.default_rng(4)
    depth = rng.uniform(0.3, 2.0, (37, 53)).astype(np.float32)
    depth[rng.uniform(size=depth.shape) < 0.3] = 0.0
    scan = Scan(np.zeros((37, 53, 3), np.uint8), depth, ring_cameras(1, 53, 37)[0], "t")
    for k in (1, 2, 7, 1000):
        v, u = np.nonzero(np.isfinite(depth) & (depth > 0))
        v, u = v[::k], u[::k]
        ref = scan.camera.unproject(np.stack([u, v], axis=-1).astype(np.float64), depth[v, u])
        assert np.array_equal(every_kth_point(scan, k), ref)
    pts = rng.normal(size=(5000, 3))
    assert finite_rows(pts) is pts
    bad = pts.copy()
    bad[[3, 40, 41]] = [np.nan, 1.0, 2.0], [1.0, np.inf, 0.0], [0.0, 0.0, -np.inf]
    assert np.array_equal(finite_rows(bad), bad[np.all(np.isfinite(bad), axis=1)]) and len(finite_rows(bad)) == 4997
    for p in (pts, np.round(pts, 1), rng.normal(size=(7, 3))):  # ties, a short one
        lo, hi = np.percentile(p.copy(), AUTO_BOUNDS_PERCENTILES, axis=0, overwrite_input=True)
        assert np.array_equal(lo, np.percentile(p, AUTO_BOUNDS_PERCENTILES[0], axis=0))
        assert np.array_equal(hi, np.percentile(p, AUTO_BOUNDS_PERCENTILES[1], axis=0))


def test_gains_on_read_equal_the_written_gains(tmp_path, monkeypatch):
    """capture.photometric.GAINS_ON_READ: spilled float32 views get their gains as a factor on each read
    (nothing written: the same files, also through a worker's apply_steps and a pickle) and read the
    colour the reference writes (gain_view's product); an 8-bit view and a gain of 1 as before."""
    import pickle

    import capture.photometric as ph
    from volume.pipeline.pool import apply_steps

    ss = make_scanset(sphere_scene(), scan_ring(3, 40, 30))
    gains = np.array([[1.1, 0.9, 1.3], [1.0, 1.0, 1.0], [0.7, 1.2, 1.05]])
    out = {}
    with ScanSpill(tmp_path) as spill:
        scans = [_with_alpha(s, float_rgb=True) for s in ss.scans]
        scans[2] = Scan(scans[2].srgb8, scans[2].depth, scans[2].camera, scans[2].name, scans[2].alpha)  # 8-bit
        kept = [spill.keep(s) for s in scans]
        for on in (False, True):
            monkeypatch.setattr(ph, "GAINS_ON_READ", on)
            n_files = len(list(spill.path.iterdir()))
            out[on] = ph.apply_gains(kept, gains, spill.keep)
            written = len(list(spill.path.iterdir())) - n_files
            assert written == (1 if on else 2)  # view 1 has gain 1; on: only the 8-bit view is written
        for ref, got in zip(out[False], out[True], strict=True):
            assert ref.rgb.dtype == got.rgb.dtype
            np.testing.assert_array_equal(ref.rgb, got.rgb)
            np.testing.assert_array_equal(ref.load().rgb, got.load().rgb)
            np.testing.assert_array_equal(pickle.loads(pickle.dumps(got)).rgb, ref.rgb)
        assert out[True][0].file == kept[0].file and len(out[True][0].gains) == 1
        twice = ph.apply_gains(out[True], gains, spill.keep)[0]  # gains in turn, not their product
        np.testing.assert_array_equal(twice.rgb, (out[False][0].rgb * gains[0].astype(np.float32)))
        reserved = spill.reserve()
        view, *_ = apply_steps([(ph.gain_view, gains[0])], kept[0], 0, reserved)  # a worker's task
        assert isinstance(view, SpilledScan) and view.file == kept[0].file and not reserved.exists()
        np.testing.assert_array_equal(view.rgb, out[False][0].rgb)


def test_spill_references_read_back_the_same_arrays(tmp_path, monkeypatch):
    """capture.scan_store.SPILL_REFERENCES: a new scan's array that is bit for bit one read lately from
    an earlier file of the folder is stored as that file's name (chains followed) and reads back the
    same; a changed array is written; off, every array is written and the reads are the same."""
    import capture.scan_store as st

    s0 = _with_alpha(make_scanset(sphere_scene(), scan_ring(1, 40, 30)).scans[0], float_rgb=True)
    reads = {}
    for on in (False, True):
        monkeypatch.setattr(st, "SPILL_REFERENCES", on)
        with ScanSpill(tmp_path) as spill:
            a = spill.keep(s0)
            a.rgb, a.depth, a.alpha  # noqa: B018  (a stage reads the view)
            cut = np.median(a.depth[a.depth > 0])
            b = spill.keep(Scan(a.rgb, np.where(a.depth > cut, 0.0, a.depth), a.camera, a.name, a.alpha))
            b.rgb, b.depth  # noqa: B018
            c = spill.keep(Scan(b.rgb * np.float32(2), b.depth, b.camera, b.name, None))  # colour changed
            with np.load(b.file) as z:
                assert ("rgb_ref" in z.files and "alpha_ref" in z.files and "depth" in z.files) == on
            with np.load(c.file) as z:
                assert ("rgb" in z.files and "depth_ref" in z.files) == on and "alpha" not in z.files
            spill._cache.clear()  # read from the files again
            reads[on] = [(x.rgb, x.depth, x.alpha) for x in (a, b, c)]
    for ref, got in zip(reads[False], reads[True], strict=True):
        for x, y in zip(ref, got, strict=True):
            assert (x is None) == (y is None)
            if x is not None:
                assert x.dtype == y.dtype
                np.testing.assert_array_equal(x, y)
    assert reads[True][2][2] is None and reads[True][1][2] is not None
    x = np.zeros(100_000, np.float32)
    y = x.copy()
    y.view(np.uint8)[1] = 1  # one byte, off the sample's stride
    assert st._same_bits(x, x.copy()) and not st._same_bits(x, y) and not st._same_bits(x, x.astype(np.float64))


def test_spilled_arrays_read_in_place_are_np_loads(tmp_path, monkeypatch):
    """capture.scan_store.SPILL_READ_IN_PLACE: every member of a spilled file (8-bit and float colour, cropped
    depth and matte with their boxes, a stored file name) read in place equals np.load's, dtype and bits;
    a compressed .npz (not a spill file) is refused with its name."""
    import capture.scan_store as st

    scan = _with_alpha(make_scanset(sphere_scene(), scan_ring(1, 40, 30)).scans[0], float_rgb=True)
    with ScanSpill(tmp_path) as spill:
        files = [spill.keep(scan).file, spill.keep(Scan(scan.rgb, scan.depth, scan.camera, scan.name, None)).file]
        u8 = spill.keep(Scan(to_uint8_srgb(scan.rgb), scan.depth, scan.camera, scan.name, scan.alpha)).file
        for f in (*files, u8):
            with np.load(f) as ref, st._InPlaceNpz(f) as got:
                assert got.files == ref.files and len(ref.files) >= 3
                for key in ref.files:
                    a, b = ref[key], got[key]
                    assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), key
        reads = {}
        for on in (False, True):
            monkeypatch.setattr(st, "SPILL_READ_IN_PLACE", on)
            reads[on] = [st._read_array(f, k) for f in files for k in ("rgb", "depth", "alpha")]
        for a, b in zip(reads[False], reads[True], strict=True):
            assert (a is None and b is None) or (a.dtype == b.dtype and a.tobytes() == b.tobytes())
    bad = tmp_path / "compressed.npz"
    np.savez_compressed(bad, rgb=np.ones((4, 4, 3), np.float32))
    with pytest.raises(ValueError, match="compressed.npz"):
        st._InPlaceNpz(bad)


def test_float_colour_stored_against_its_photo_reads_back_the_same(tmp_path, monkeypatch):
    """capture.scan_store.SPILL_RGB_BASE: a float colour that is the linear colour of an 8-bit colour read
    lately except inside a box (a matte's foreground) is stored as that file's name, the box and its pixels;
    it reads back bit for bit (a -0.0 outside the object counts as a change); a colour changed everywhere is
    written whole; off, the whole colour is written and reads back the same."""
    import capture.scan_store as st
    from capture.scan import srgb8_to_linear

    s0 = make_scanset(sphere_scene(), scan_ring(1, 48, 36)).scans[0]
    photo = to_uint8_srgb(s0.rgb)  # a photo's 8-bit codes
    photo[30, 40] = 0
    s0 = Scan(photo, s0.depth, s0.camera, s0.name)
    fg = srgb8_to_linear(s0.rgb)
    fg[10:20, 12:30] = np.float32(0.25)  # the object's colours
    fg[30, 40, 1] = -0.0  # equal to 0.0 as a number, not as bits
    whole = fg * np.float32(1.5)
    reads = {}
    for on in (False, True):
        monkeypatch.setattr(st, "SPILL_RGB_BASE", on)
        with ScanSpill(tmp_path) as spill:
            a = spill.keep(s0)
            a.rgb  # noqa: B018  (a stage reads the view)
            b = spill.keep(Scan(fg, s0.depth, s0.camera, s0.name, None))
            c = spill.keep(Scan(whole, s0.depth, s0.camera, s0.name, None))
            with np.load(b.file) as z:
                assert ("rgb_base_ref" in z.files) == on
                if on:
                    assert z["rgb"].shape == (21, 29, 3) and tuple(z["rgb_box"]) == (10, 12, 36, 48)
            with np.load(c.file) as z:
                assert "rgb_base_ref" not in z.files and z["rgb"].shape == (36, 48, 3)
            spill._cache.clear()  # read from the files again
            reads[on] = [b.rgb, c.rgb]
    for x, want in zip(reads[True], (fg, whole), strict=True):
        assert x.dtype == np.float32 and x.tobytes() == want.tobytes()
    assert all(x.tobytes() == y.tobytes() for x, y in zip(reads[False], reads[True], strict=True))
    from capture.sampling import mask_box

    lin, bits = srgb8_to_linear(photo), fg.view(np.uint32)
    for b in (bits, whole.view(np.uint32), lin.view(np.uint32)):  # the fast box is the per-pixel reduction's
        assert st._differ_box(lin, b) == mask_box((lin.view(np.uint32) != b).any(axis=2))
