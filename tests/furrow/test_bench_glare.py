"""``furrow bench glare`` end to end on a small frame (GL, llvmpipe here: about 2 s): the streak layer's energy
against the analytic light of its pairs, the composite pictures written; a frame too small for the thin pairs'
test refused with a clear message (it failed with numpy's "low >= high" before)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from furrow.bench import glare as bench

#: Streak energy's relative error with 4x supersampling, every pair on screen (measured here: 3e-6 for wide
#: pairs, 4e-4 / 9e-4 for 2 px / 1 px ones; without supersampling 1 px pairs are 13 % off).
ENERGY_TOL_S4 = 0.005


@pytest.mark.gl
def test_bench_glare_small_frame(tmp_path, capsys):
    assert bench.main(["--size", "200x170", "--counts", "10", "-o", str(tmp_path), "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["size"] == [200, 170]
    s4 = [r for r in res["energy"] if r["supersample"] == 4]
    assert {r["n"] for r in s4} == {10.0, 100.0, 1000.0}
    assert all(r["energy_rel_err"] < ENERGY_TOL_S4 for r in s4), s4
    for k in ("no_glare", "glare"):
        png = Path(res["composite"][k]["png"])
        assert png.parent == tmp_path and png.is_file(), png


def test_bench_glare_refuses_a_frame_too_small(capsys):
    with pytest.raises(SystemExit) as e:
        bench.main(["--size", "160x120"])
    assert e.value.code == 2
    assert "each side must be above 160 px" in capsys.readouterr().err
