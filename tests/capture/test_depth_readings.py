"""capture.depth_readings: depth maps stored flipped, or as distances along the rays, on seeded scenes with exact
depth; each accelerated step against its point-by-point reference."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from capture.depth_agreement import AgreementConfig, neighbours, view_sample
from capture.depth_readings import (
    READING_Z,
    READINGS,
    flip_sums,
    read_depth,
    read_points,
    reading_check,
    reading_hits,
)
from tests.scenes import make_scanset, pair_hit_cases, scan_ring, spheres_scene

CFG = AgreementConfig()
FLIPS = {"upside down": lambda z: z[::-1], "left to right": lambda z: z[:, ::-1],
         "turned 180 degrees": lambda z: z[::-1, ::-1]}


@pytest.fixture(scope="module")
def ring():
    return make_scanset(spheres_scene(), scan_ring(12, 96, 72), noise=0.0005)


def _rays_norm(camera, shape):
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w]
    return np.linalg.norm(camera.pixel_rays(np.stack([xs, ys], axis=-1).astype(np.float64)), axis=-1)


def _stored(scans, name):
    """The scans with their depth stored as ``name`` says (the mistake the check looks for)."""
    if name == "range":
        return [replace(s, depth=(s.depth * _rays_norm(s.camera, s.depth.shape)).astype(np.float32)) for s in scans]
    return [replace(s, depth=np.ascontiguousarray(FLIPS[name](s.depth))) for s in scans]


def _check(scans):
    cams = [s.camera for s in scans]
    samples = [view_sample(s.depth, s.camera, CFG.points, i) for i, s in enumerate(scans)]
    nb = neighbours(cams, CFG.neighbours)
    pairs = [(i, int(j)) for i in range(len(cams)) for j in nb[i] if j >= 0]
    return reading_check(samples, [s.depth.shape for s in scans], cams, pairs, 1.0, CFG.rel)


def test_right_depth_is_read_as_stored(ring):
    rec = _check(ring.scans)
    assert rec["status"] == "as stored", rec
    assert all(t["z"] < 0 for t in rec["tried"].values()), rec


@pytest.mark.parametrize("name", list(READINGS))
def test_depth_stored_flipped_or_as_range_is_named(ring, name):
    rec = _check(_stored(ring.scans, name))
    assert rec["status"] == "reading" and rec["reading"] == name, rec
    assert rec["tried"][name]["z"] >= READING_Z and rec["tried"][name]["share"] > rec["share_as_stored"], rec
    right = _check(ring.scans)["share_as_stored"]
    assert rec["tried"][name]["share"] == pytest.approx(right, abs=0.05), rec  # read so, it is the right capture


def test_reading_hits_as_stored_equal_pair_hits(ring):
    scans, s = ring.scans, np.array([0.97, 1.0, 1.02])
    for i, j, a, b, want in pair_hit_cases(scans, CFG.points, ((0, 1), (3, 2), (7, 8)), s, CFG.rel):
        got = reading_hits(a[0], scans[i].camera, scans[j].camera, b, scans[j].depth.shape, s, CFG.rel, None)
        assert np.array_equal(got, want)


@pytest.mark.parametrize("name", list(READINGS))
def test_read_points_are_the_points_of_the_map_read_so(ring, name):
    """A sample of the stored map, read as ``name``: each point is the pixel's own point of the map that was meant
    (the reference: pixel by pixel, through the meant map)."""
    s = _stored(ring.scans, name)[4]
    meant = ring.scans[4].depth
    smp = view_sample(s.depth, s.camera, CFG.points, 4)
    got = read_points(smp[0], s.camera, s.depth.shape, name)
    h, w = s.depth.shape
    for p, q in zip(smp[0][:40], got[:40]):
        u, v = np.rint((s.camera.K @ (p / p[2]))[:2]).astype(int)  # the stored pixel
        rows, cols, along = READINGS[name]
        mu, mv = (w - 1 - u if cols else u), (h - 1 - v if rows else v)
        want = s.camera.pixel_rays(np.array([mu, mv], float)) * meant[mv, mu]
        np.testing.assert_allclose(q, want, rtol=2e-6, atol=1e-9)


def test_range_lookup_equals_the_point_by_point_reference(ring):
    """The neighbour's range read at the landed pixel over |ray| against a loop that projects each point and
    reads the z-depth map that was meant (sub-sampled the same way)."""
    scans = _stored(ring.scans, "range")
    i, j = 2, 3
    a = view_sample(scans[i].depth, scans[i].camera, CFG.points, i)
    b = view_sample(scans[j].depth, scans[j].camera, CFG.points, j)
    pts = read_points(a[0], scans[i].camera, scans[i].depth.shape, "range")
    got = reading_hits(pts, scans[i].camera, scans[j].camera, b, scans[j].depth.shape, np.ones(1), CFG.rel, "range")[0]
    ci, cj = scans[i].camera, scans[j].camera
    step = b[2]
    want = np.zeros(len(pts), bool)
    for k, p in enumerate(pts):
        world = ci.world_from_cam[:3, :3] @ p + ci.world_from_cam[:3, 3]
        uv, z = cj.project(world[None])
        if not z[0] > 1e-9:
            continue
        r, c = int(np.rint(uv[0, 1] / step)), int(np.rint(uv[0, 0] / step))
        if not (0 <= r < b[1].shape[0] and 0 <= c < b[1].shape[1]) or b[1][r, c] <= 0:
            continue
        zj = b[1][r, c] / np.linalg.norm(cj.pixel_rays(uv[0]))
        want[k] = abs(z[0] - zj) <= CFG.rel * zj
    assert np.array_equal(got, want)
    assert got.mean() > 0.3  # and most points agree, read as range


@pytest.mark.parametrize("name", list(READINGS))
def test_read_depth_undoes_the_mistake(ring, name):
    s = _stored(ring.scans, name)[5]
    got = read_depth(s.depth, s.camera, name)
    assert got.dtype == np.float32
    np.testing.assert_allclose(got, ring.scans[5].depth, rtol=1e-6, atol=0)


def test_flip_sums_follow_the_colour():
    """A bright square on black, its depth measured where it is: flipped, the depth's edges leave the colour's
    (the colour scores the flipped depth's edges lower); the depth stored flipped scores them higher."""
    rgb = np.zeros((60, 90, 3), np.uint8)
    rgb[10:30, 15:40] = 200
    depth = np.zeros((60, 90), np.float32)
    depth[10:30, 15:40] = 0.5
    for name in FLIPS:
        right = flip_sums(rgb, depth, name)
        assert right[1] < 0.5 * right[0], (name, right)
        flipped = flip_sums(rgb, np.ascontiguousarray(FLIPS[name](depth)), name)
        assert flipped[1] > 2.0 * flipped[0], (name, flipped)
