"""capture.matting_bound's compiled passes against the numpy references of capture.matting_known
(alpha_lower_bound, clipped) bit for bit."""

import numpy as np
import pytest

import capture.matting_bound as mb
import capture.matting_candidates_kernel as mck
import capture.matting_full_colour as mfc
from capture import matting_known as mk

pytestmark = pytest.mark.filterwarnings("ignore:invalid value encountered")


def _pairs(seed: int, shape, dtype_c, dtype_b):
    rng = np.random.default_rng(seed)
    C = rng.uniform(-0.1, 1.1, shape).astype(dtype_c)
    B = rng.uniform(-0.05, 1.05, shape).astype(dtype_b)
    # near ties with the noise allowance, equal colours, the edges of the room, the clip level
    n = C.reshape(-1, 3).shape[0]
    Cf, Bf = C.reshape(-1, 3), B.reshape(-1, 3)
    Cf[: n // 8] = Bf[: n // 8]
    Bf[n // 8: n // 4] = rng.choice([0.0, 1.0, 1e-7, 1 - 1e-7, 0.975, np.nextafter(0.975, 0)], (n // 4 - n // 8, 3))
    Cf[n // 4: n // 3] = rng.choice([0.975, np.float32(0.975), np.nextafter(np.float32(0.975), 0), 1.0, 0.0],
                                    (n // 3 - n // 4, 3))
    Cf[n // 3: n // 3 + 5] = [[np.nan, 0.2, 0.99], [0.99, np.nan, 0.1], [np.inf, 0, 0], [-np.inf, 0.5, 0.5],
                              [0.1, 0.2, np.nan]]
    Bf[n // 3 + 5: n // 3 + 8] = [[np.nan, 0.3, 0.3], [0.99, 0.1, np.nan], [np.inf, 0.2, 0.2]]
    return C, B


def _reference(fn, *args):
    mb.FUSED_BOUND = False
    try:
        return fn(*args)
    finally:
        mb.FUSED_BOUND = True


@pytest.mark.parametrize("dtypes", [(np.float32, np.float32), (np.float64, np.float64), (np.float32, np.float64),
                                    (np.float64, np.float32)])
@pytest.mark.parametrize("shape", [(37, 53, 3), (4001, 3)])
@pytest.mark.parametrize("noise", [0.0, 0.01, np.float32(0.004)])
def test_lower_bound_equals_numpy(dtypes, shape, noise):
    C, B = _pairs(1, shape, *dtypes)
    ref = _reference(mk.alpha_lower_bound, C, B, noise)
    out = mk.alpha_lower_bound(C, B, noise)
    assert mb.lower_bound(C, B, noise, mk.NOISE_REL) is not None  # the compiled pass ran
    assert out.dtype == ref.dtype and out.shape == ref.shape
    assert np.array_equal(out.view(np.uint64), ref.view(np.uint64))  # bit for bit, NaN and signed zeros too
    assert (ref == 1.0).any() and (ref == 0.0).any() and ((ref > 0) & (ref < 1)).any()


@pytest.mark.parametrize("dtypes", [(np.float32, np.float32), (np.float64, np.float64), (np.float32, np.float64),
                                    (np.float64, np.float32)])
@pytest.mark.parametrize("shape", [(37, 53, 3), (4001, 3)])
def test_clipped_equals_numpy(dtypes, shape):
    C, B = _pairs(2, shape, *dtypes)
    ref = _reference(mk.clipped, C, B)
    out = mk.clipped(C, B)
    assert mb.clipped_mask(C, B, mk.CLIP_LEVEL) is not None
    assert out.dtype == ref.dtype and out.shape == ref.shape
    assert np.array_equal(out, ref)
    assert ref.any() and not ref.all()


def test_float32_level_is_the_arrays_own():
    """numpy compares a float32 array with the level rounded to float32: at a level float32 rounds
    down (0.7), the float32 value of the level is clipped in float32 and not in float64."""
    level = 0.7
    lv32 = np.float32(level)
    assert float(lv32) < level
    C = np.array([[lv32, 0, 0], [np.nextafter(lv32, np.float32(0)), 0, 0]], np.float32)
    for c in (C, C.astype(np.float64)):
        for b in (np.zeros_like(C), np.zeros_like(C, np.float64)):
            ref = (c.max(-1) >= level) | (b.max(-1) >= level)
            assert np.array_equal(mb.clipped_mask(c, b, level), ref)
            assert np.array_equal(mb.clipped_mask(b, c, level), ref)
    assert mb.clipped_mask(C, np.zeros_like(C), level).tolist() == [True, False]


def test_shapes_it_does_not_take_go_to_numpy():
    C = np.zeros((4, 3), np.float32)
    assert mb.lower_bound(C, np.zeros((1, 3), np.float32), 0.0, 0.03) is None
    assert mb.clipped_mask(C.astype(np.float16), C.astype(np.float16), 0.9) is None
    assert mb.clipped_mask(C[:, :2], C[:, :2], 0.9) is None


def _candidates_case(seed: int, shape, dtype):
    rng = np.random.default_rng(seed)
    C = rng.uniform(0, 1, shape).astype(dtype)
    B = rng.uniform(0, 1, shape).astype(dtype)
    near = rng.uniform(0, 1, shape).astype(dtype)
    extra = [rng.uniform(0, 1, shape).astype(np.float32)]
    Cf, Bf, Nf = C.reshape(-1, 3), B.reshape(-1, 3), near.reshape(-1, 3)
    n = len(Cf)
    Nf[: n // 10] = Bf[: n // 10]                           # a candidate on the background (e2 0)
    Cf[n // 10: n // 5] = Bf[n // 10: n // 5]               # the photo on the background: de +-0
    Nf[n // 10: n // 5: 2] = Bf[n // 10: n // 5: 2] - 0.25  # negative E: de -0.0 against lower 0
    Cf[n // 5: n // 5 + 3] = np.nan
    Nf[n // 5 + 3: n // 5 + 6] = np.nan
    extra[0].reshape(-1, 3)[n // 4: n // 3] = Nf[n // 4: n // 3]  # exact ties of cost
    lower = rng.choice([0.0, -0.0, 0.3, 1.0, np.nan], shape[:-1]).astype(dtype)
    t = slice(n // 5 + 6, n // 5 + 30)  # no nearest colour, every other candidate at the same cost
    Cf[t], Nf[t], lower.reshape(-1)[t] = Bf[t], np.nan, 0.0
    src = rng.uniform(0, 1, (500, 3))
    return C, B, near, src, lower, extra


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("shape", [(41, 29, 3), (3001, 1, 3)])
def test_fit_candidates_equals_numpy(monkeypatch, dtype, shape):
    C, B, near, src, lower, extra = _candidates_case(3, shape, dtype)
    for ex in ([], extra):
        monkeypatch.setattr(mck, "FUSED_CANDIDATES", False)
        ref = mk.fit_candidates(C, B, near, src, lower, ex)
        monkeypatch.setattr(mck, "FUSED_CANDIDATES", True)
        assert mck.fit_fused(C, B, near, mk.palette(src), ex, lower, 0.02, 0.05, 0.03) is not None
        out = mk.fit_candidates(C, B, near, src, lower, ex)
        for o, r in zip(out, ref, strict=True):
            assert o.dtype == r.dtype and o.shape == r.shape
            assert np.array_equal(o.view(np.uint64), r.view(np.uint64))  # NaN and signed zeros too
        a = ref[0]
        assert (a == 1.0).any() and ((a > 0) & (a < 1)).any() and (ref[1] == 0).any() and (ref[1] > 0).any()


def test_candidates_it_does_not_take_go_to_numpy():
    C = np.zeros((4, 3))
    assert mck.fit_fused(C, C, np.zeros((1, 3)), np.zeros((2, 3)), [], 0.0, 0.02, 0.05, 0.03) is None
    assert mck.fit_fused(C, C, C, np.zeros((2, 3)), [np.zeros((4, 1, 3))], 0.0, 0.02, 0.05, 0.03) is None
    assert mck.fit_fused(C, C, C, np.zeros((2, 3)), [], 0.0, 0.02, 0.05, 0.03) is None  # a scalar lower bound
    assert mck.fit_fused(C, C, C, np.zeros((2, 3)), [], np.zeros(4), 0.02, 0.05, 0.03) is not None


@pytest.mark.parametrize("shape", [(43, 37, 3), (1, 5000, 3)])
def test_full_colour_equals_numpy(monkeypatch, shape):
    from capture.matting_scale import _full_colour

    rng = np.random.default_rng(5)
    C = rng.uniform(0, 1, shape).astype(np.float32)
    B = rng.uniform(0, 1, shape).astype(np.float32)
    f_up = rng.uniform(0, 1, shape).astype(np.float32)
    a = rng.choice([0.0, -0.0, 1e-7, 0.3, 0.999, 1.0, np.nan], shape[:2]) * rng.uniform(0.5, 1, shape[:2])
    known = rng.uniform(size=shape[:2]) < 0.8
    Cf, Bf = C.reshape(-1, 3), B.reshape(-1, 3)
    n = len(Cf)
    Cf[: n // 6] = rng.choice([0.0, -0.0, 1.0, np.float32(0.975), np.nextafter(np.float32(0.975), 0)], (n // 6, 3))
    Bf[n // 6: n // 3] = rng.choice([0.0, -0.0, 1.0, np.float32(0.975), np.nan], (n // 3 - n // 6, 3))
    Cf[n // 3: n // 3 + 4] = np.nan
    f_up.reshape(-1, 3)[n // 2: n // 2 + 200] = rng.choice([np.nan, -0.0, 0.5], (200, 3))
    monkeypatch.setattr(mfc, "FUSED_FULL_COLOUR", False)
    ref = _full_colour(C, a, B, known, f_up)
    monkeypatch.setattr(mfc, "FUSED_FULL_COLOUR", True)
    assert mfc.full_colour(C, a, B, known, f_up, mk.CLIP_LEVEL, mk.OPAQUE_ALPHA) is not None
    out = _full_colour(C, a, B, known, f_up)
    assert out.dtype == ref.dtype == np.float64 and out.shape == ref.shape
    assert np.array_equal(out.view(np.uint64), ref.view(np.uint64))  # NaN and signed zeros too
    assert np.isnan(ref).any() and (ref == 1.0).any() and (np.signbit(ref) & (ref == 0)).any()
    # other dtypes go to numpy
    assert mfc.full_colour(C, a.astype(np.float32), B, known, f_up, mk.CLIP_LEVEL, mk.OPAQUE_ALPHA) is None


@pytest.mark.parametrize("resolution", ["full", "working"])
@pytest.mark.parametrize("seed", [0, 1])
def test_the_whole_matte_is_the_same_with_the_switches_off(monkeypatch, seed, resolution):
    """matte_scan on a needle scene before an estimated background (the colour gate unmixes some
    pixels, fills others and drops seen ones) with FUSED_BOUND (and FUSED_CANDIDATES) and
    matting_colour.GATE_SUMS each on and off: the same alpha, colour and record bit for bit."""
    from capture import matting_colour as mc
    from capture import matting_scale
    from capture.matting import MatteConfig, matte_scan
    from tests.capture.test_matting_colour import _plate, _scene
    from tests.capture.test_matting_known import _scan

    if resolution == "working":
        monkeypatch.setattr(matting_scale, "working_scale", lambda *a, **k: 0.5)
    C, A, F, D, est, bg, sigma = _scene(seed, 0.7, 3.0)
    out = {}
    for fused, sums in [(True, True), (False, True), (True, False), (False, False)]:
        monkeypatch.setattr(mb, "FUSED_BOUND", fused)
        monkeypatch.setattr(mck, "FUSED_CANDIDATES", fused)
        monkeypatch.setattr(mfc, "FUSED_FULL_COLOUR", fused)
        monkeypatch.setattr(mc, "GATE_SUMS", sums)
        m = matte_scan(_scan(C, D), cfg=MatteConfig(mode="plate", resolution=resolution),
                       plate=_plate(bg, est, sigma))
        out[fused, sums] = m
    ref = out[False, False]
    rec = ref.notes["colour"]
    assert rec["unmixed"] > 0 and rec["filled"] > 0 and rec["seen_filled"] > 0, rec
    for key, m in out.items():
        assert np.array_equal(m.alpha.view(np.uint32), ref.alpha.view(np.uint32)), key
        assert np.array_equal(np.asarray(m.foreground).view(np.uint32), np.asarray(ref.foreground).view(np.uint32)), key
        assert m.notes["colour"] == rec, key
