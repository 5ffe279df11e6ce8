"""Smoke test of ``furrow bench shading`` (fast sections only): it runs, writes JSON and plots."""

from __future__ import annotations

import importlib.util
import json

from tests.conftest import REPO_DIR


def test_bench_shading_glare_section(tmp_path, capsys):
    spec = importlib.util.spec_from_file_location("bench_shading", REPO_DIR / "bench" / "shading.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    rc = mod.main(["--quick", "--sections", "glare", "-o", str(tmp_path), "--json"])
    assert rc == 0
    res = json.loads(capsys.readouterr().out)
    rows = res["glare"]
    assert [r["bright_pixels"] for r in rows] == [10, 100, 1000]
    for r in rows:
        assert abs(r["streak_light_over_excess"] - 1) < 0.02
    assert (tmp_path / "glare_cost.png").is_file()
