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


def test_fine_depth_is_said_with_the_share_it_was_decided_on():
    on = [{**v, "fine_depth": 1.0, "partial_share": 0.95} for v in _views([None, None])]
    off = [{**v, "fine_depth": 0.0, "partial_share": 0.25} for v in _views([None, None])]
    asked = [{**v, "fine_depth": 0.0, "partial_share": float("nan")} for v in _views([None])]
    text = _said({"gather": summarise(on), "points": summarise(_views([None]))}, ("gather", "points"))
    said = "gather's fine depth (1-pixel splats first, docs/novel_views.md): on (its mattes 0.95 partial, at least 0.6)"
    assert said in text and "points" not in text
    assert "off (its mattes 0.25 partial, under 0.6)" in _said({"gather": summarise(off)}, ("gather",))
    assert "off (no matte, or as asked)" in _said({"gather": summarise(asked)}, ("gather",))
