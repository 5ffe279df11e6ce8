"""`furrow eval`'s line on gather's coverage pull (furrow.cmd_eval.print_pulls): said from the frames' stats, for the
methods that report one, with its mean and range; a method without the stat gets no line."""

from __future__ import annotations

import io

from rich.console import Console

from furrow.cmd_eval import print_pulls
from render.evaluate import summarise


def _views(pulls):
    base = {k: 0.0 for k in ("psnr", "ssim", "psnr_masked", "ssim_masked", "sharpness", "hole_fraction",
                             "largest_hole", "ms", "cpu_ms")}
    return [{**base, **({} if p is None else {"alpha_pull": p})} for p in pulls]


def _said(res, methods) -> str:
    out = io.StringIO()
    print_pulls(Console(file=out, width=300), res, methods)
    return out.getvalue()


def test_the_pull_is_said_with_its_mean_and_range():
    res = {"gather": summarise(_views([0.2, 0.3, 0.25])), "points": summarise(_views([None, None, None]))}
    text = _said(res, ("gather", "points"))
    assert "gather's coverage pull" in text and "d = 0.250 (range 0.200-0.300) over 3 frames" in text
    assert "points" not in text
    assert abs(res["gather"]["alpha_pull"] - 0.25) < 1e-12


def test_a_model_drawn_as_drawn_says_so_and_a_method_without_the_stat_says_nothing():
    assert "pull (a - d a (1 - a), docs/novel_views.md): none (d = 0) over 2 frames" in _said(
        {"gather": summarise(_views([0.0, 0.0]))}, ("gather",))
    assert _said({"gather": summarise(_views([None, None]))}, ("gather",)) == ""
