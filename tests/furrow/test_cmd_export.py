"""`furrow export`: the three files from a saved model, and one-line errors."""

from __future__ import annotations

import plyfile

from furrow.cli import main
from tests.scenes import SPHERES, build_model, ring_cameras
from volume.model import save_model


def test_export_all_three(tmp_path, capsys):
    m = build_model(ring_cameras(4, 40, 30))
    mdir = save_model(m, tmp_path / "model")
    out = tmp_path / "exp"
    rc = main(["export", str(mdir), "--mesh", str(out / "m.glb"), "--points", str(out / "p.ply"),
               "--spheres", str(out / "s.ply")])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["m.glb", "p.ply", "s.ply"]
    assert f"{len(m.mesh_vertices)} vertices" in err and f"{len(SPHERES)} spheres" in err
    assert plyfile.PlyData.read(str(out / "s.ply"))["vertex"].count == len(SPHERES)


def test_export_errors_are_one_line(tmp_path, capsys):
    assert main(["export", str(tmp_path / "nope"), "--mesh", str(tmp_path / "m.glb")]) == 1
    assert "nope" in capsys.readouterr().err
    m = save_model(build_model(ring_cameras(2, 16, 12)), tmp_path / "model")
    assert main(["export", str(m)]) == 1
    assert "nothing to export" in capsys.readouterr().err
    assert main(["export", str(m), "--mesh", str(tmp_path / "m.stl")]) == 1
    err = capsys.readouterr().err
    assert "m.stl" in err and ".glb or .ply" in err


def test_export_splats_and_web(tmp_path, capsys):
    """--splats writes the reference's PLY (plyfile reads it), --refine reports the kept views'
    alpha error falling, --web writes the page and its data, asking nothing of the network."""
    from tests.scenes import compact

    m = compact(build_model(ring_cameras(6, 64, 48)))
    mdir = save_model(m, tmp_path / "model")
    out = tmp_path / "exp"
    rc = main(["export", str(mdir), "--splats", str(out / "s.ply"), "--refine", "2", "--web", str(out / "web")])
    err = capsys.readouterr().err
    assert rc == 0, err
    v = plyfile.PlyData.read(str(out / "s.ply"))["vertex"]
    assert v.count > 100 and [p.name for p in v.properties][:9] == ["x", "y", "z", "nx", "ny", "nz", "f_dc_0",
                                                                     "f_dc_1", "f_dc_2"]
    assert "refined opacities" in err and "alpha error" in err
    page = (out / "web" / "index.html").read_text()
    assert sorted(p.name for p in (out / "web").iterdir()) == ["index.html", "splats.bin"]
    assert "http" not in page.split("<script>")[1] and 'fetch("splats.bin")' in page and "__CAMERA__" not in page
    n = int.from_bytes((out / "web" / "splats.bin").read_bytes()[:4], "little")
    assert n == v.count
    assert main(["export", str(mdir), "--refine", "1"]) == 1
    assert "nothing to export" in capsys.readouterr().err
    assert main(["export", str(mdir), "--mesh", str(out / "m.glb"), "--refine", "1"]) == 1
    assert "--refine apply to --splats" in capsys.readouterr().err
