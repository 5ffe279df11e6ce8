"""The path-traced hard cases' generator (datasets_synthetic/pathtraced) against exact geometry.

The lens inversion is plain numpy (always run); everything that renders needs Mitsuba 3 and skips
with the reason when it cannot start (`pip install -e '.[pathtrace]'` + Debian's libllvm19; `make
setup` installs neither, so the default `make test` skips them).  Where Mitsuba is installed they run
in the default suite: the renders are tiny (<= 96x72), all of them about 7 s with Mitsuba's JIT
kernel cache empty (the largest, the 4-view capture, 3.8 s; load 4).  Whether Mitsuba starts is
asked only when such a test runs, so no other test process imports it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from capture.camera import Camera, look_at, make_K
from capture.lens import Lens, distort_pixels, undistort_pixels
from datasets_synthetic.camera_traits import OPENCV_LENS
from datasets_synthetic.pathtraced.film import undistort_normalized
from datasets_synthetic.pathtraced.objects import Curves, PathObject, Sphere, diffuse
from datasets_synthetic.pathtraced.runtime import mitsuba_available
from render.shading.envmap import EnvMap, uv_to_dir


@pytest.fixture(scope="module")
def mitsuba_or_skip():
    """Skips the test, with the reason, when Mitsuba 3 cannot start here."""
    ok, why = mitsuba_available()
    if not ok:
        pytest.skip(f"Mitsuba 3 cannot start: {why}")


needs_mitsuba = pytest.mark.usefixtures("mitsuba_or_skip")


def _camera(eye, target, w=64, h=48, f=60.0, cx=None, cy=None) -> Camera:
    K = make_K(f, f, (w - 1) / 2 if cx is None else cx, (h - 1) / 2 if cy is None else cy)
    return Camera(K, look_at(eye, target), w, h, name="t")


def test_lens_inversion_matches_opencv():
    """undistort_normalized (the arithmetic the renderer runs on Dr.Jit arrays) against cv2 through
    capture.lens, over the whole 640x480 frame and its corners: within 1e-6 px."""
    K = make_K(500.0, 500.0, 319.5, 239.5)
    u, v = np.meshgrid(np.linspace(-0.5, 639.5, 33), np.linspace(-0.5, 479.5, 25))
    uv = np.stack([u.ravel(), v.ravel()], 1)
    want = undistort_pixels(uv, K, OPENCV_LENS)
    x, y = undistort_normalized((uv[:, 0] - K[0, 2]) / K[0, 0], (uv[:, 1] - K[1, 2]) / K[1, 1], OPENCV_LENS.coeffs)
    got = np.stack([x * K[0, 0] + K[0, 2], y * K[1, 1] + K[1, 2]], 1)
    assert np.abs(got - want).max() < 1e-6
    assert np.abs(got - uv).max() > 5.0  # the lens does move the corners: the comparison is not vacuous


def _scene(parts, materials=None, env=None):
    from datasets_synthetic.pathtraced.scene import PathScene, Room

    obj = PathObject("test", tuple(parts), materials or {"m": diffuse((0.5, 0.5, 0.5))})
    env = env if env is not None else EnvMap(np.full((8, 16, 3), 0.5, np.float32), "grey")
    return PathScene(obj, Room(env))


def _ray_sphere_z(cam: Camera, centre, radius) -> np.ndarray:
    """Analytic z-depth of a sphere at every pixel centre (0 = miss)."""
    d = cam.pixel_rays(cam.pixel_grid()) @ cam.world_from_cam[:3, :3].T
    n = np.linalg.norm(d, axis=-1)
    u = d / n[..., None]
    oc = cam.center - np.asarray(centre)
    b = (u * oc).sum(-1)
    disc = b * b - (oc @ oc - radius**2)
    t = -b - np.sqrt(np.maximum(disc, 0))
    return np.where(disc > 0, t / n, 0.0)


@needs_mitsuba
def test_depth_is_z_depth_at_pixel_centres():
    """film.z_depth (1 sub-ray) = the analytic z-depth of a sphere seen off-axis at every pixel centre:
    z along the optical axis, not the distance along the ray (which differs by up to 3 mm here), and
    pixel centres where capture.camera puts them (half a pixel off moves the silhouette by 25+ pixels
    and the depth near it by millimetres)."""
    from datasets_synthetic.pathtraced.film import z_depth

    centre, r = (0.05, -0.03, 0.02), 0.06
    cam = _camera((0.6, 0.1, 0.25), (0.0, 0.0, 0.0), f=200.0, cx=30.0, cy=25.5)
    want = _ray_sphere_z(cam, centre, r)
    with _scene([Sphere(centre, r, "m")]) as ps:
        got = z_depth(ps, cam, samples=1)
    both = (got > 0) & (want > 0)
    assert both.sum() > 400
    assert np.count_nonzero((got > 0) != (want > 0)) <= 2  # only pixels grazing the silhouette
    assert np.abs(got[both] - want[both]).max() < 2e-5
    ray_len = want * np.linalg.norm(cam.pixel_rays(cam.pixel_grid()), axis=-1)
    assert np.abs(ray_len - want)[both].max() > 1e-3  # the distance along the ray would fail


@needs_mitsuba
def test_true_matte_is_subpixel_coverage():
    """A horizontal wire 0.4 px wide across the view: every column's matte sums to its projected
    width (the filter integrates to 1), the black image is the wire alone (zero where the matte is),
    and the room image is the map where the wire is not."""
    from datasets_synthetic.pathtraced.film import render_view

    cam = _camera((0.0, -0.5, 0.0), (0.0, 0.0, 0.0), w=48, h=32, f=80.0, cx=23.5, cy=16.0)
    radius = 0.2 * 0.5 / 80.0  # 0.4 px wide at 0.5 m
    wire = Curves(np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), np.array([radius, radius]), np.array([2]),
                  "linear", "m")
    for rfilter in ("box", "gaussian"):
        with _scene([wire]) as ps:
            v = render_view(ps, cam, 256, 3, rfilter=rfilter, max_depth=2)
        cols = v.alpha[:, 4:-4].sum(axis=0)
        width = 2 * radius * 80.0 / np.sqrt(0.5**2 - radius**2)
        assert abs(cols.mean() - width) < 0.02 * width, (rfilter, cols.mean(), width)
        assert cols.std() < 0.1 * width
        assert v.alpha[:12].max() == 0 and v.alpha[-12:].max() == 0
        assert np.all(v.black[v.alpha == 0] == 0)
        grey = v.room[v.alpha == 0]
        assert np.allclose(grey, 0.5, atol=1e-3)  # the constant map seen where the wire is not


def _smooth_map(h=64) -> EnvMap:
    """A map whose radiance is linear in the direction (different weight on x, y, z): any turn shows."""
    u = (np.arange(2 * h) + 0.5) / (2 * h)
    v = (np.arange(h) + 0.5) / h
    d = uv_to_dir(np.stack(np.meshgrid(u, v), -1))
    rad = 1.0 + 0.6 * d[..., 0:1] * [1, 0.2, 0.2] + 0.6 * d[..., 1:2] * [0.2, 1, 0.2] + 0.6 * d[..., 2:3] * [0, 0, 1]
    return EnvMap(rad.astype(np.float32), "smooth")


@needs_mitsuba
@pytest.mark.parametrize("turn", [0.0, 90.0, 200.0])
def test_room_map_faces_furrows_directions(turn):
    """The room Mitsuba shows behind the object = furrow's own lookup of the same map turned the same
    way (datasets_synthetic.lighting.background, EnvMap.rotated): the map is in furrow's layout, and a
    quarter turn (Mitsuba's own layout) would be off by tens of percent."""
    from datasets_synthetic.lighting import background
    from datasets_synthetic.pathtraced.film import render_view

    env = _smooth_map()
    cam = _camera((0.0, 0.0, 0.0), (0.3, 1.0, 0.4), w=48, h=36, f=30.0)
    with _scene([Sphere((0.0, 0.0, -50.0), 0.01, "m")], env=env) as ps:
        ps.turn(turn)
        v = render_view(ps, cam, 16, 1, max_depth=1)
    want = background(env, cam, 1.0, turn)
    assert np.abs(v.room - want).max() < 0.02
    quarter = background(env, cam, 1.0, turn + 90.0)
    assert np.abs(quarter - want).max() > 0.2


@needs_mitsuba
@pytest.mark.parametrize("row, col", [(20, 200), (64, 37), (110, 131)])
def test_one_spot_lands_where_the_camera_projects_it(row, col):
    """A map black but for one bright texel: its image is centred on the texel's direction as
    capture.camera projects it (furrow's layout: no quarter turn, no mirror, and no stretch of the rows:
    Mitsuba's own texel grid would put the spot of row 20 of 128 a third of a texel, 1.3 px, too high),
    within 0.05 texel, also through the lens."""
    from datasets_synthetic.pathtraced.film import render_view

    h, f = 128, 150.0
    data = np.zeros((h, 2 * h, 3), np.float32)
    data[row, col] = 1000.0
    d = uv_to_dir(np.array([(col + 0.5) / (2 * h), (row + 0.5) / h]))
    texel_px = f * np.pi / h
    for lens in (None, OPENCV_LENS):
        cam = _camera((0.0, 0.0, 0.0), d + np.array([0.04, -0.03, 0.02]), w=96, h=72, f=f)
        with _scene([Sphere((0.0, 0.0, -50.0), 0.01, "m")], env=EnvMap(data, "spot")) as ps:
            v = render_view(ps, cam, 32, 2, lens=lens, max_depth=1)
        lum = v.room.sum(-1)
        yy, xx = np.mgrid[0:72, 0:96]
        got = np.array([(lum * xx).sum(), (lum * yy).sum()]) / lum.sum()
        want = cam.project(d[None])[0][0]
        if lens is not None:
            want = distort_pixels(want[None], cam.K, lens)[0]
        assert np.linalg.norm(got - want) < 0.05 * texel_px, (lens, got, want)


@needs_mitsuba
def test_small_capture_reads_back(tmp_path):
    """A 40x30 conifer turntable of 4 views written as a furrow capture: read back with its true mattes,
    the room on views 0::2 only, the black twin of the same pixels, millimetre depth; gt/ files."""
    import json

    from capture.io import read_scanset
    from datasets_synthetic.pathtraced.cases import Options, conifer_room

    opts = Options(out=tmp_path / "out", cache=tmp_path / "cache", size=(40, 30), spp=2, views=4)
    entries = conifer_room(opts, log=lambda m: None)
    assert [e["name"] for e in entries] == ["conifer_room_turntable", "conifer_black_turntable"]
    room = read_scanset(tmp_path / "out" / "conifer_room_turntable")
    black = read_scanset(tmp_path / "out" / "conifer_black_turntable")
    assert len(room) == len(black) == 4 and all(s.alpha is not None for s in room.scans)
    bg = [float((s.rgb.max(-1) > 2)[s.alpha == 0].mean()) for s in room.scans]  # 8-bit; a matte under
    assert bg[0] > 0.9 and bg[2] > 0.9 and bg[1] == 0 and bg[3] == 0  # 0.5/255 can leave 1-2/255 of colour
    assert np.array_equal(room.scans[1].rgb, black.scans[1].rgb)
    info = json.loads((tmp_path / "out" / "conifer_room_turntable" / "gt" / "scene.json").read_text())
    assert info["room_rotation_deg"][1] == pytest.approx(90.0) and info["env"]["convention"] == "furrow"
    assert (tmp_path / "out" / "conifer_room_turntable" / "gt" / "mesh.ply").stat().st_size > 10_000
    assert entries[0]["partial_fraction"] > 0.5


def test_lens_of_the_cases_is_opencv():
    """The cases' lens is the one furrow synth --lens opencv writes (k1 k2 p1 p2), which the renderer's
    inversion handles; a fisheye is refused."""
    from datasets_synthetic.pathtraced.film import _check_lens

    assert OPENCV_LENS.source == "OPENCV" and not OPENCV_LENS.fisheye
    _check_lens(OPENCV_LENS)
    with pytest.raises(ValueError, match="OPENCV"):
        _check_lens(Lens("OPENCV_FISHEYE", (0.03, -0.01, 0.002, -0.0005), "OPENCV_FISHEYE"))


def test_alias_capture_shares_images_and_carries_its_own_poses(tmp_path):
    """write_alias: a second transforms.json beside a capture reads the capture's own images, depth and
    mattes (relative paths) with the poses it was given."""
    from capture.io import read_scanset, write_transforms
    from capture.scan import Scan, ScanSet
    from datasets_synthetic.noise import perturb_pose
    from datasets_synthetic.pathtraced.assemble import write_alias

    rng = np.random.default_rng(0)
    cams = [_camera((0.5 * np.cos(a), 0.5 * np.sin(a), 0.1), (0, 0, 0), w=16, h=12) for a in (0.0, 1.0, 2.0)]
    cams = [Camera(c.K, c.cam_from_world, c.width, c.height, name=f"v{i}") for i, c in enumerate(cams)]
    scans = [Scan(rng.integers(0, 255, (12, 16, 3), dtype=np.uint8), np.full((12, 16), 0.5, np.float32), c,
                  f"{c.name}.png", rng.uniform(0, 1, (12, 16)).astype(np.float32)) for c in cams]
    write_transforms(ScanSet(tuple(scans), np.array([[-1.0, -1, -1], [1, 1, 1]]), {}), tmp_path / "src")
    moved = [perturb_pose(c, np.random.default_rng(i), 5.0, 0.01) for i, c in enumerate(cams)]
    write_alias(tmp_path / "src", tmp_path / "alias", moved, {"gt/note.txt": b"x"})
    a, s = read_scanset(tmp_path / "alias"), read_scanset(tmp_path / "src")
    for x, y, m in zip(a.scans, s.scans, moved):
        assert np.array_equal(x.rgb, y.rgb) and np.array_equal(x.depth, y.depth) and np.array_equal(x.alpha, y.alpha)
        np.testing.assert_allclose(x.camera.cam_from_world, m.cam_from_world, atol=1e-9)
        assert np.abs(x.camera.cam_from_world - y.camera.cam_from_world).max() > 1e-3
    assert (tmp_path / "alias" / "gt" / "note.txt").read_bytes() == b"x"


def test_lens_case_is_its_pinhole_twin_but_for_the_lens(tmp_path):
    """conifer_black_lens renders what conifer_black_turntable renders (object, seed, light, cameras, spp)
    through the OPENCV lens: the two differ by the lens alone, so their scores compare the lens path."""
    from dataclasses import replace

    from datasets_synthetic.pathtraced.cases import Options, case_spec

    opts = Options(out=tmp_path, cache=tmp_path)
    lens, twin = case_spec("conifer_black_lens", opts), case_spec("conifer_room_turntable", opts)
    assert lens.lens == OPENCV_LENS and twin.lens is None
    assert replace(lens, lens=None) == twin and lens.key() != twin.key()


def test_fur_table_case_is_the_brown_fur_but_for_table_and_lens(tmp_path):
    """fur_room_table_ae_lens (bunny_room_table_ae_lens) renders fur_similar_bg's ball (bunny_room_turntable's
    bunny: object, seed, room and its turn, spp, size) on the table through the OPENCV lens; --size and the room
    options reach it as they reach the room case."""
    from dataclasses import replace

    from datasets_synthetic.pathtraced.cases import Options, case_spec

    for opts in (Options(out=tmp_path, cache=tmp_path), Options(out=tmp_path, cache=tmp_path, size=(640, 480),
                                                                  room_rotation=0.0, seed=3)):
        for name, room in (("fur_room_table_ae_lens", "fur_similar_bg"), ("bunny_room_table_ae_lens",
                                                                           "bunny_room_turntable")):
            tab, twin = case_spec(name, opts), case_spec(room, opts)
            assert (tab.support, tab.lens, twin.support, twin.lens) == ("table", OPENCV_LENS, "none", None)
            assert replace(tab, support="none", lens=None) == twin and tab.key() != twin.key()


def test_room_map_and_turn_reach_every_room_case(tmp_path):
    """--room-map / --room-rotation change the map and its turn behind the conifer *and* fur_similar_bg (a fur
    capture once asked for a turn of 90 degrees and got the default 270); without them each keeps its own."""
    from datasets_synthetic.pathtraced.cases import BROWN_ROOM, CONIFER_ROOM, Options, case_spec

    plain = Options(out=tmp_path, cache=tmp_path)
    assert (case_spec("fur_similar_bg", plain).env, case_spec("fur_similar_bg", plain).env_rotation_deg) == BROWN_ROOM
    tt = case_spec("conifer_room_turntable", plain)
    assert (tt.env, tt.env_rotation_deg) == CONIFER_ROOM
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "interior.exr").write_bytes(b"")
    turned = Options(out=tmp_path, cache=tmp_path, env_dir=tmp_path / "maps", room_rotation=90.0, room_map="interior")
    for name in ("fur_similar_bg", "fur_similar_bg_orbit", "conifer_room_turntable", "conifer_room_orbit",
                 "conifer_room_table_ae_lens", "bunny_room_turntable", "bunny_room_orbit"):
        spec = case_spec(name, turned)
        assert spec.env == str(tmp_path / "maps" / "interior.exr") and spec.env_rotation_deg == 90.0, name
    orbit, tt = case_spec("fur_similar_bg_orbit", plain), case_spec("fur_similar_bg", plain)
    assert (orbit.motion, tt.motion) == ("orbit", "turntable") and dataclasses.replace(orbit, motion="turntable") == tt
    with pytest.raises(ValueError, match="not bundled"):
        case_spec("fur_similar_bg", Options(out=tmp_path, cache=tmp_path, room_map="nowhere"))
    # a case with no room behind it never looks the map up
    assert case_spec("furball_uniform_turntable", Options(out=tmp_path, cache=tmp_path, room_map="nowhere")).env \
        == case_spec("furball_uniform_turntable", plain).env


def test_the_index_names_the_map_behind_the_room():
    """A room case rendered with --room-map says so in its INDEX description (a bunny before the interior map was
    described as before the courtyard's bricks); without it the description is as written."""
    from datasets_synthetic.pathtraced.cases import Options, room_described

    what = "furry bunny before the courtyard's brown bricks, camera circling"
    assert room_described(what, Options(out=None, cache=None)) == what
    got = room_described(what, Options(out=None, cache=None, room_map="interior"))
    assert got == "furry bunny before the interior map (--room-map), camera circling"
    assert room_described("uniform brown fur ball before the courtyard's brown brick floor (similar colour)",
                          Options(out=None, cache=None, room_map="city")) == \
        "uniform brown fur ball before the city map (--room-map) (similar colour)"
    assert room_described("conifer in the courtyard, fixed camera", Options(out=None, cache=None, room_map="forest")) \
        == "conifer in the forest map (--room-map), fixed camera"


def _script():
    import importlib.util

    from tests.conftest import REPO_DIR

    spec = importlib.util.spec_from_file_location("hardcases_script", REPO_DIR / "scripts" / "hardcases.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("codes, calls, rc", [([-11, 0], 2, 0), ([-11, -11, -11], 3, 139), ([1], 1, 1), ([0], 1, 0)])
def test_a_case_the_renderer_kills_is_run_again(codes, calls, rc):
    """run_isolated: a worker killed by a signal (Mitsuba's segfault) is run again, MAX_ATTEMPTS runs at most
    (then 128 + signal); a worker that exits by itself (success or a reported error) is not."""
    from types import SimpleNamespace

    from datasets_synthetic.pathtraced.render import MAX_ATTEMPTS

    hc, seen, logged = _script(), [], []

    def runner(cmd, env):
        seen.append(env.get(hc.WORKER_ENV))
        return SimpleNamespace(returncode=codes[len(seen) - 1])

    assert MAX_ATTEMPTS == 3
    assert hc.run_isolated("c", ["x"], logged.append, runner) == rc
    assert seen == ["1"] * calls and len(logged) == sum(c < 0 for c in codes)


def test_issue30_table_pairs_every_room_case_with_its_twin(tmp_path):
    """scripts/issue30_table.py's twin(): each room capture's black twin, the fur orbit's included."""
    import importlib.util

    from tests.conftest import REPO_DIR

    spec = importlib.util.spec_from_file_location("issue30_table", REPO_DIR / "scripts" / "issue30_table.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    pairs = {"conifer_room_turntable": "conifer_black_turntable", "conifer_room_orbit_ae": "conifer_black_orbit",
             "conifer_room_table_ae_lens": "conifer_black_turntable", "fur_similar_bg": "fur_black_similar",
             "fur_similar_bg_jump_ae": "fur_black_similar", "fur_similar_bg_orbit": "fur_black_similar_orbit",
             "conifer_room_turntable_jump_ae": "conifer_black_turntable",
             "fur_room_table_ae_lens": "fur_black_similar", "bunny_room_turntable": "bunny_black_turntable",
             "bunny_room_table_ae_lens": "bunny_black_turntable"}
    for name in set(pairs) | set(pairs.values()):
        (tmp_path / name).mkdir()
    for room, black in pairs.items():
        assert mod.twin(tmp_path / room) == tmp_path / black, room
