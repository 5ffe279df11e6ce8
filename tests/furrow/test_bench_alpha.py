"""``furrow bench alpha`` end to end on a tiny fur ball: the true matte reaches the model, the
composite over white gains, the picture is written."""

from __future__ import annotations

import json

from furrow.bench import alpha as bench


def test_bench_alpha_smoke(tmp_path):
    """In the default run (3.6 s with the GL synthesiser): marked slow, it had been broken unseen since the
    synthesiser stopped using the rasteriser the bench subclassed."""
    pic = tmp_path / "pic.png"
    assert bench.main(["--scenes", "furball", "--size", "80x60", "--views", "8", "--strands", "300",
                       "--l-max", "32", "--repeat", "1", "--picture", str(pic), "-o", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "alpha.json").read_text())["scenes"]["furball"]
    a, b = res["true matte"], res["no matte"]
    assert a["alpha_mse"] < b["alpha_mse"] and a["psnr_white"] > b["psnr_white"]
    assert pic.is_file()
