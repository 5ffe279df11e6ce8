"""furrow bench memory: the rates it measures, the files it leaves (none), and its verdict."""

from __future__ import annotations

import furrow.bench.memory as bm


def test_file_rate_writes_the_bytes_and_leaves_no_file(tmp_path):
    rate = bm.file_rate(3 << 20, tmp_path)
    assert rate > 0 and list(tmp_path.iterdir()) == []


def test_measure_reports_medians_and_the_verdict(monkeypatch):
    """The verdict is the cold rate against HANDED_BACK_RATIO x the warm one, over the medians."""
    for rates, handed in (([16.0, 16.0, 0.2, 16.0, 16.0, 0.3], True), ([16.0, 16.0, 12.0, 16.0, 16.0, 10.0], False)):
        it = iter(rates)  # per repeat: the first touch, warm, cold
        monkeypatch.setattr(bm, "touch_rate", lambda n, it=it: next(it))
        monkeypatch.setattr(bm, "file_rate", lambda n, folder: 1.5)
        res = bm.measure(1, 0.0, 2)
        assert res["warm_gb_s"] == 16.0 and res["file_gb_s"] == 1.5
        assert res["cold_gb_s"] == (0.25 if handed else 11.0) and res["handed_back"] is handed


def test_main_runs_small(capsys):
    assert bm.main(["--size-mb", "4", "--pause", "0", "--repeats", "1", "--json"]) == 0
    out = capsys.readouterr().out
    assert '"warm_gb_s"' in out and '"handed_back"' in out
