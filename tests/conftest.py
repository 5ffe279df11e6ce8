"""Shared test fixtures and the one image-comparison helper."""

from __future__ import annotations

import numpy as np
import pytest

TESTS_DIR = __import__("pathlib").Path(__file__).resolve().parent
REPO_DIR = TESTS_DIR.parent


def image_diff_stats(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> dict:
    """Mean / max absolute difference and PSNR (peak 1.0 for float, 255 for uint8) of two images."""
    a = np.asarray(a)
    b = np.asarray(b)
    assert a.shape == b.shape, f"image shapes differ: {a.shape} vs {b.shape}"
    peak = 255.0 if a.dtype == np.uint8 else 1.0
    d = np.abs(a.astype(np.float64) - b.astype(np.float64))
    if mask is not None:
        d = d[np.asarray(mask, bool)]
    if d.size == 0:
        return {"mean": 0.0, "max": 0.0, "psnr": float("inf"), "frac_over": 0.0}
    mse = float(np.mean(d**2))
    return {"mean": float(d.mean()), "max": float(d.max()),
            "psnr": float("inf") if mse == 0 else float(10 * np.log10(peak**2 / mse))}


def assert_images_close(actual, expected, *, mean_tol: float, max_tol: float | None = None,
                        mask=None, outlier_frac: float = 0.0, what: str = "image") -> dict:
    """Assert two images agree: mean |diff| <= mean_tol; and at most ``outlier_frac`` of the
    (masked) pixel values differ by more than ``max_tol``. Returns the statistics."""
    st = image_diff_stats(actual, expected, mask)
    assert st["mean"] <= mean_tol, f"{what}: mean |diff| {st['mean']:.4g} > {mean_tol} ({st})"
    if max_tol is not None:
        a = np.asarray(actual, np.float64)
        e = np.asarray(expected, np.float64)
        d = np.abs(a - e)
        if mask is not None:
            d = d[np.asarray(mask, bool)]
        frac = float(np.mean(d > max_tol)) if d.size else 0.0
        st["frac_over"] = frac
        assert frac <= outlier_frac, f"{what}: {frac:.4%} of values differ by > {max_tol} (allowed {outlier_frac:.4%})"
    return st


@pytest.fixture(scope="session")
def gl_ctx():
    """One headless GL context for the test session."""
    from render.gl import create_context

    ctx = create_context()
    yield ctx
    ctx.release()
