"""`furrow eval` builds its model with the pipeline of `furrow model` and the same flags: with a
model-changing flag, the model eval evaluates (--save-model) is the model `furrow model --frames 0::2`
writes with that flag, file for file, and differs from eval's model without it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from capture.io import write_transforms
from capture.lens import PERSPECTIVE, Lens
from capture.scan import Scan, ScanSet
from furrow.cli import main
from tests.scenes import make_scanset, scan_ring, sphere_scene
from volume.model import load_model

#: A mild radial lens in the capture (its frames are undistorted when read: --undistort matters).
LENS = Lens(PERSPECTIVE, (-0.08, 0.01, 0.0, 0.0), "OPENCV")
#: Small and quick: the model's finest level and the held-out views drawn.
FAST = ["--max-res", "16", "--mesh-level", "16", "--max-views", "1", "--supersample", "1"]


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    ss = make_scanset(sphere_scene(), scan_ring(12, 64, 48), noise=0.0005)
    # two kept views over-exposed by half a stop: --no-photometric matters (at a third of a stop, since the
    # known-background matte's CF_EPSILON 1e-5, the fit left 2.4 of no alignment's 7.4 on these 64x48 views and
    # the held-back check kept the views as they are)
    scans = tuple(Scan(s.linear_rgb * np.float32(1.41 if i in (2, 4) else 1.0), s.depth, s.camera, s.name)
                  for i, s in enumerate(ss.scans))
    out = tmp_path_factory.mktemp("eval") / "sphere"
    write_transforms(ScanSet(scans, ss.bounds, ss.metadata), out, lens=LENS)
    return out


def _timeless(rec):
    """A record without its timings (they differ between any two runs)."""
    if isinstance(rec, dict):
        return {k: _timeless(v) for k, v in rec.items() if "seconds" not in k}
    return rec


def _arrays(folder) -> dict:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.suffix == ".npz"}


def _eval(capture, tmp, name, flags, capsys) -> tuple[dict, object, dict]:
    """(eval.json, the evaluated model, its arrays) of `furrow eval` with ``flags``."""
    js, saved = tmp / f"{name}.json", tmp / f"{name}_model"
    rc = main(["eval", str(capture), "--holdout", "2", *FAST, *flags, "--json", str(js), "-o", str(tmp / name),
               "--save-model", str(saved)])
    err = capsys.readouterr().err
    assert rc == 0, err
    return json.loads(js.read_text()), load_model(saved), _arrays(saved)


@pytest.fixture(scope="module")
def default_eval(capture, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("default")
    js, saved = tmp / "e.json", tmp / "m"
    assert main(["eval", str(capture), "--holdout", "2", *FAST, "--json", str(js), "-o", str(tmp / "e"),
                 "--save-model", str(saved)]) == 0
    return json.loads(js.read_text()), load_model(saved), _arrays(saved)


#: flag -> what it changes in the model (checked against eval's default model)
CHANGES = {
    "matte-off": (["--matte", "off"], lambda m, d: m.rgbz.alpha is None and d.rgbz.alpha is not None),
    "no-photometric": (["--no-photometric"], lambda m, d: m.params["photometric"] is None
                       and d.params["photometric"] is not None),
    "views": (["--views", "2"], lambda m, d: len(m.rgbz) == 2 and len(d.rgbz) == 6),
    "undistort": (["--undistort", "crop"], lambda m, d: m.rgbz.size != d.rgbz.size),
}


@pytest.mark.parametrize("name", list(CHANGES))
def test_eval_flag_changes_the_model_as_furrow_model_does(capture, default_eval, tmp_path, capsys, name):
    flags, changed = CHANGES[name]
    res, model, arrays = _eval(capture, tmp_path, name, flags, capsys)
    assert res["kept"] == [0, 2, 4, 6, 8, 10] and res["held"] == [1]
    for method in ("gather", "microfacet", "points", "mesh_vdtm", "mesh_colour"):
        assert np.isfinite(res[method]["psnr"])
    out = tmp_path / "model"
    rc = main(["model", str(capture), "-o", str(out), "--frames", "0::2", *FAST[:4], *flags])
    assert rc == 0, capsys.readouterr().err
    assert _arrays(out) == arrays  # the very same model, file for file
    ref = load_model(out)
    for key in ("surroundings", "photometric", "views", "resolution", "lopt", "mesh_level"):
        assert _timeless(ref.params[key]) == _timeless(model.params[key]), key
    _, default_model, default_arrays = default_eval
    assert changed(model, default_model), name
    assert arrays != default_arrays


def test_eval_reports_the_model_it_built(default_eval):
    res, model, _ = default_eval
    assert res["model"]["views"]["kept"] == 6 and res["model"]["surroundings"]["matte"]["mode"] == "auto"
    assert res["undistorted"]["mode"] == "keep" and res["levels"] == model.pyramid.resolutions


def test_eval_takes_every_model_flag(capsys):
    """Every flag of furrow model that changes the model is a flag of furrow eval."""
    for cmd in ("model", "eval"):
        with pytest.raises(SystemExit):
            main([cmd, "--help"])
        text = capsys.readouterr().out
        for flag in ("--matte", "--backdrop", "--no-photometric", "--photometric-reference", "--views", "--undistort",
                     "--keep-support", "--no-extent", "--max-res", "--sdf", "--quorum", "--output-size", "--frames",
                     "--mesh-level", "--spill", "--reference-pipeline"):
            assert flag in text, (cmd, flag)
