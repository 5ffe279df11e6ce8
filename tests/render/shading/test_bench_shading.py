"""Smoke test of ``furrow bench shading`` (a fast section): it runs, writes JSON and a plot."""

from __future__ import annotations

import json

from furrow.bench import shading as bench_shading


def test_bench_shading_ssdf_section(tmp_path, capsys):
    rc = bench_shading.main(["--quick", "--sections", "ssdf", "-o", str(tmp_path), "--json"])
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    rows = res["ssdf"]
    assert [r["spheres"] for r in rows] == [8, 64, 512]
    for r in rows:
        assert 0 <= r["err_mean_l10"] < 0.2
    assert (tmp_path / "ssdf_error_vs_spheres.png").is_file()
