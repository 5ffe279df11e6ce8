"""furrow bench photometric: its error measure (the global gain removed, EV and white balance)."""

from __future__ import annotations

import numpy as np

from furrow.bench.photometric import errors


def test_errors_ignore_the_global_gain_and_split_ev_from_white_balance():
    rng = np.random.default_rng(0)
    truth = np.exp2(rng.normal(0, 0.35, (9, 1))) * np.exp(rng.normal(0, 0.06, (9, 3)))
    perfect = errors(1.7 / truth, truth)                  # any global gain is as good
    assert perfect["ev_max"] < 1e-12 and perfect["wb_pct_max"] < 1e-9
    off = 1.0 / truth
    off[4] *= 2 ** 0.1                                      # one view 0.1 EV too bright, white balance right
    e = errors(off, truth)
    assert abs(e["ev_max"] - 0.1) < 1e-9 and e["wb_pct_max"] < 1e-9 and e["ev_median"] < 1e-12
    off = 1.0 / truth
    off[2] *= np.exp2([0.05, 0.0, -0.05])                  # a white-balance error only
    e = errors(off, truth)
    assert e["ev_max"] < 1e-12 and abs(e["wb_pct_max"] - 100 * (2 ** 0.05 - 1)) < 1e-6
