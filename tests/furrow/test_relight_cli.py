"""`furrow model --capture-env*` and `furrow render --relight` end to end (issue 15)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from capture.imageio import read_color, write_exr
from capture.io import write_transforms
from furrow.cli import main
from render.shading.capture_env import MIRROR_BALL_CAM_TO_WORLD, capture_envmap
from render.shading.envmap import bundled_envmap
from render.shading.projections import fisheye_from_equirect, mirror_ball_from_equirect
from tests.scenes import make_scanset, scan_ring, sphere_scene
from volume.model import load_model


@pytest.fixture(scope="module")
def relightable(tmp_path_factory):
    """(scan folder, a model of it with the capture lighting 'forest', one without)."""
    ss = make_scanset(sphere_scene(), scan_ring(8, 64, 48), noise=0.0005)
    base = tmp_path_factory.mktemp("relight")
    write_transforms(ss, base / "scans")
    assert main(["model", str(base / "scans"), "-o", str(base / "lit"), "--max-res", "32",
                 "--capture-env", "forest", "--capture-env-rotation", "30"]) == 0
    assert main(["model", str(base / "scans"), "-o", str(base / "plain"), "--max-res", "32"]) == 0
    return base / "scans", base / "lit", base / "plain"


def test_model_stores_the_capture_lighting(relightable):
    _, lit, plain = relightable
    m = load_model(lit)
    assert m.capture_env is not None and m.capture_env.source == "forest" and m.capture_env.rotation_deg == 30.0
    np.testing.assert_allclose(m.capture_env.up, [0, 0, 1], atol=1e-6)  # the ring's up
    np.testing.assert_array_equal(m.capture_env.radiance, bundled_envmap("forest").data)
    assert load_model(plain).capture_env is None


def test_bad_capture_map_fails_before_the_build(relightable, tmp_path, capsys):
    scans, _, _ = relightable
    assert main(["model", str(scans), "-o", str(tmp_path / "m"), "--capture-env", "nowhere"]) == 1
    assert "unknown environment map 'nowhere'" in " ".join(capsys.readouterr().err.split())
    assert not (tmp_path / "m").exists()


def test_render_relight(relightable, tmp_path, capsys):
    scans, lit, plain = relightable
    base = ["render", str(lit), "--cameras", str(scans), "--frames", "1", "--method", "microfacet",
            "--supersample", "1"]
    assert main(base + ["-o", str(tmp_path / "a")]) == 0
    capsys.readouterr()
    assert main(base + ["--relight", "sunset", "-o", str(tmp_path / "b")]) == 0
    # 8 views of 64x48 leave too few cells to cross-validate a fit: the CLI says so and what it relights with
    err = " ".join(capsys.readouterr().err.split())
    assert "cells can be predicted from views of other sectors" in err and "relighting with the fixed" in err
    assert main(base + ["--relight", "sunset", "--relight-visibility", "--relight-kernel", "lambert",
                        "-o", str(tmp_path / "v")]) == 0
    assert main(base + ["--relight", "--env", "sunset", "--ground", "-o", str(tmp_path / "c")]) == 0
    a, b, c, v = (read_color(tmp_path / d / "cam_001.png") for d in "abcv")
    obj = a.max(-1) > 0
    assert np.array_equal(b.max(-1) > 0, obj)  # on black, the same silhouette
    assert np.abs(a.astype(int) - b.astype(int))[obj].mean() > 3  # lit differently
    assert np.abs(v.astype(int) - b.astype(int))[obj].mean() > 0.5  # another kernel, with visibility
    assert (c.max(-1) > 0).mean() > 0.95  # composited over the map
    st = json.loads((tmp_path / "b" / "render_stats.json").read_text())
    assert st["frames"][0]["relight_ms"] > 0
    # the default method (gather) relights the same way: same silhouette, lit differently
    dflt = ["render", str(lit), "--cameras", str(scans), "--frames", "1"]
    assert main(dflt + ["-o", str(tmp_path / "ga")]) == 0
    assert main(dflt + ["--relight", "sunset", "-o", str(tmp_path / "gb")]) == 0
    ga, gb = (read_color(tmp_path / d / "cam_001.png") for d in ("ga", "gb"))
    gobj = ga.max(-1) > 0
    assert np.array_equal(gb.max(-1) > 0, gobj) and np.abs(ga.astype(int) - gb.astype(int))[gobj].mean() > 3
    capsys.readouterr()
    assert main(base + ["--relight", "studio", "--env", "sunset", "-o", str(tmp_path / "d")]) == 1
    assert "one map lights everything" in " ".join(capsys.readouterr().err.split())
    assert main(["render", str(plain), "--cameras", str(scans), "--relight", "sunset", "-o", str(tmp_path / "e")]) == 1
    err = " ".join(capsys.readouterr().err.split())  # the console wraps long lines
    assert "cannot be relit" in err and "--capture-env" in err and err.count("error:") == 1
    assert main(base + ["--relight", "sunset", "--relight-kernel", "mix:1,2", "-o", str(tmp_path / "f")]) == 1
    assert "mix kernel" in " ".join(capsys.readouterr().err.split())


def test_capture_lighting_from_photos(tmp_path):
    """A fisheye or a mirror-ball HDR photo of a map gives back the map where the photo sees it."""
    env = bundled_envmap("courtyard").resized(64)
    write_exr(tmp_path / "fish.exr", fisheye_from_equirect(env, 256))
    write_exr(tmp_path / "ball.exr", mirror_ball_from_equirect(env, 256, MIRROR_BALL_CAM_TO_WORLD))
    d = env.pixel_directions()
    for kw, seen in (({"fisheye": tmp_path / "fish.exr"}, d[..., 2] > 0.2),
                     ({"mirrorball": tmp_path / "ball.exr"}, d[..., 0] < 0.3)):  # the ball's rim looks along +x
        got = capture_envmap(**kw, height=64)
        err = np.abs(got.data - env.data)[seen].mean() / env.data[seen].mean()
        assert err < 0.1, (kw, err)
    with pytest.raises(ValueError, match="exactly one"):
        capture_envmap("forest", fisheye=tmp_path / "fish.exr")


def test_bench_variants_parse():
    from furrow.bench.relight import parse_variant, variant_turn

    c = parse_variant("lambert:vis:fwd=0:g=0.3:s=0.05:res=16")
    assert (c.kernel, c.visibility, c.forward, c.forward_g, c.smooth, c.volume_res) == ("lambert", True, 0.0, 0.3,
                                                                                        0.05, 16)
    assert parse_variant("wrap").visibility is False
    s = parse_variant("wrap:strands:sres=24:sw=0.3:turn=90")
    assert (s.strands, s.strand_res, s.strand_weight) == (True, 24, 0.3)
    assert variant_turn("wrap:strands:turn=90") == 90.0 and variant_turn("wrap") == 0.0
    assert parse_variant("wrap:nostrands").strands is False
    with pytest.raises(ValueError, match="flags"):
        parse_variant("wrap:shiny")
    with pytest.raises(ValueError, match="kernel"):
        parse_variant("phong")
