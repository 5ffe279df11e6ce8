"""The one sampler and conventions core (capture.sampling): one table of cases, each mode checked
against values from independent references: hand-computed cases (ties, borders, wrap), scipy's
ndimage.map_coordinates and OpenCV's remap with the matching mode, and a GL texture sampled by the
GPU (the behaviour the module documents)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy import ndimage

from capture.sampling import (
    cell_centres,
    cell_index,
    from_texcoord,
    index_coords,
    mask_box,
    nearest_pixel,
    points_box,
    sample_grid,
    sample_image,
    to_texcoord,
    voxel_centres,
)

#: A 4 x 8 image whose value is linear in the pixel coordinates: img[y, x] = 10 y + x + 1, so a
#: bilinear sample inside the centres' hull is 10 y + x + 1 exactly.
H, W = 4, 8
IMG = (10.0 * np.arange(H)[:, None] + np.arange(W)[None, :] + 1.0).astype(np.float32)

#: (filter, boundary, x, y, expected): worked by hand from IMG (and, for "edge", from DEPTH).
HAND = [
    ("linear", "clamp", 1.25, 0.5, 7.25),             # inside: 10 * 0.5 + 1.25 + 1
    ("linear", "clamp", -0.7, 1.0, 11.0),             # left of the first centre: the edge value
    ("linear", "clamp", 7.6, 3.4, 38.0),              # beyond the last centres: the corner
    ("linear", "zero", -0.5, 0.0, 0.5),               # half the edge texel, half the zero border
    ("linear", "zero", 7.25, 1.0, 0.75 * 18.0),       # 3/4 of x = 7, 1/4 of the border
    ("linear", "zero", 2.0, -1.0, 0.0),               # a whole texel outside
    ("linear", "wrap", 7.5, 0.0, 0.5 * 8.0 + 0.5 * 1.0),     # between the last and the first column
    ("linear", "wrap", -0.25, 2.0, 0.25 * 28.0 + 0.75 * 21.0),
    ("nearest", "clamp", 1.5, 0.0, 3.0),              # a tie goes up: floor(1.5 + 0.5) = 2
    ("nearest", "clamp", 2.5, 0.0, 4.0),              # ... where np.round would give 2
    ("nearest", "clamp", 1.49, 0.51, 12.0),
    ("nearest", "clamp", -3.0, 9.0, 31.0),            # clamped to (0, 3)
    ("nearest", "zero", -0.5, 0.0, 1.0),              # s = 0: still texel 0
    ("nearest", "zero", -0.51, 0.0, 0.0),             # outside
    ("nearest", "zero", 7.49, 3.49, 38.0),
    ("nearest", "zero", 7.5, 0.0, 0.0),
    ("nearest", "wrap", 7.5, 0.0, 1.0),               # column 8 = column 0
    ("nearest", "wrap", -0.6, 1.0, 18.0),             # column -1 = column 7
]

#: A depth map with an edge (1 m | 2 m) and a hole (0) for the edge-aware filter.
DEPTH = np.array([[1.0, 1.0, 2.0, 2.0],
                  [1.0, 1.01, 2.0, 0.0],
                  [1.0, 1.0, 2.0, 2.0]], np.float32)
EDGE_HAND = [
    (0.5, 0.5, 0.25 * (1.0 + 1.0 + 1.0 + 1.01)),      # one surface (within 3 %): linear
    (1.25, 0.5, 1.01),                                # across the edge: the nearest sample, (1, 1)
    (1.75, 0.25, 2.0),                                # ... here (2, 0)
    (2.5, 0.75, 0.0),                                 # next to the hole: nearest (3, 1) is the hole
    (-0.6, 0.0, 0.0),                                 # outside: no value
]

#: scipy.ndimage.map_coordinates mode and OpenCV border of each boundary.
SCIPY_MODE = {"clamp": "nearest", "zero": "grid-constant", "wrap": "grid-wrap"}
CV2_BORDER = {"clamp": cv2.BORDER_REPLICATE, "zero": cv2.BORDER_CONSTANT, "wrap": cv2.BORDER_WRAP}


@pytest.mark.parametrize("filt,boundary,x,y,want", HAND)
def test_hand_computed_cases(filt, boundary, x, y, want):
    got = sample_image(IMG, np.array([x]), np.array([y]), filt, boundary)
    assert got.shape == (1,)
    assert got[0] == pytest.approx(want, abs=1e-9)


@pytest.mark.parametrize("x,y,want", EDGE_HAND)
def test_edge_aware_cases(x, y, want):
    got = sample_image(DEPTH, np.array([x]), np.array([y]), "edge", "zero")
    assert got[0] == pytest.approx(want, abs=1e-6)


def _points(n=400, seed=0, ties=True):
    """Points on a 1/32 grid (OpenCV's remap weights are exact there) around and beyond the image;
    without ``ties``: none at a half-integer (where the references' rounding differs)."""
    rng = np.random.default_rng(seed)
    x = rng.integers(-3 * 32, (W + 2) * 32, n) / 32.0
    y = rng.integers(-3 * 32, (H + 2) * 32, n) / 32.0
    if not ties:
        keep = (np.abs(x % 1 - 0.5) > 1e-9) & (np.abs(y % 1 - 0.5) > 1e-9)
        x, y = x[keep], y[keep]
    return x, y


@pytest.mark.parametrize("boundary", ["clamp", "zero", "wrap"])
@pytest.mark.parametrize("filt", ["linear", "nearest"])
def test_against_scipy_map_coordinates(filt, boundary):
    x, y = _points(ties=filt == "linear")
    want = ndimage.map_coordinates(IMG.astype(np.float64), np.stack([y, x]), order=1 if filt == "linear" else 0,
                                   mode=SCIPY_MODE[boundary], cval=0.0)
    np.testing.assert_allclose(sample_image(IMG, x, y, filt, boundary), want, atol=1e-9)


@pytest.mark.parametrize("boundary", ["clamp", "zero", "wrap"])
@pytest.mark.parametrize("filt", ["linear", "nearest"])
def test_against_opencv_remap(filt, boundary):
    x, y = _points(ties=filt == "linear")
    interp = cv2.INTER_LINEAR if filt == "linear" else cv2.INTER_NEAREST
    want = cv2.remap(IMG, x.astype(np.float32)[None], y.astype(np.float32)[None], interp,
                     borderMode=CV2_BORDER[boundary], borderValue=0)[0]
    np.testing.assert_allclose(sample_image(IMG, x, y, filt, boundary), want, atol=1e-4)


def test_channels_per_axis_boundary_and_shapes():
    """Colour images keep their channels; a boundary per axis (the equirect: clamp the rows, wrap
    the columns); coordinates of any shape."""
    rgb = np.stack([IMG, 2 * IMG, -IMG], -1)
    x, y = _points(60, seed=3)
    got = sample_image(rgb, x.reshape(6, 10), y.reshape(6, 10), "linear", ("clamp", "wrap"))
    assert got.shape == (6, 10, 3)
    rows = ndimage.map_coordinates(IMG.astype(np.float64), np.stack([np.clip(y, 0, H - 1), x]), order=1,
                                   mode="grid-wrap")
    np.testing.assert_allclose(got[..., 1].ravel(), 2 * rows, atol=1e-9)
    np.testing.assert_allclose(got[..., 2].ravel(), -rows, atol=1e-9)
    with pytest.raises(ValueError, match="boundary"):
        sample_image(IMG, x, y, "linear", "mirror")
    with pytest.raises(ValueError, match="filter"):
        sample_image(IMG, x, y, "cubic")


@pytest.mark.parametrize("boundary", ["clamp", "zero", "wrap"])
def test_trilinear_against_scipy(boundary):
    vol = (100.0 * np.arange(3)[:, None, None] + 10.0 * np.arange(4)[None, :, None]
           + np.arange(5)[None, None, :] + 1.0)
    rng = np.random.default_rng(1)
    p = rng.uniform(-1.5, 5.5, (300, 3))
    want = ndimage.map_coordinates(vol, p.T, order=1, mode=SCIPY_MODE[boundary], cval=0.0)
    np.testing.assert_allclose(sample_grid(vol, p, "linear", boundary), want, atol=1e-9)
    inside = np.array([[0.5, 2.25, 3.75]])  # the linear field, exactly
    assert sample_grid(vol, inside)[0] == pytest.approx(100 * 0.5 + 10 * 2.25 + 3.75 + 1)


def test_nearest_pixel_cell_centres_and_texcoords():
    assert nearest_pixel([-0.5, 0.49, 0.5, 1.5, 2.5, -1.5]).tolist() == [0, 0, 1, 2, 3, -1]  # ties up
    assert np.round(2.5) == 2.0  # (what the rule avoids: half to even)
    np.testing.assert_allclose(cell_centres(4), [0.5, 1.5, 2.5, 3.5])
    np.testing.assert_allclose(cell_centres(4, -1.0, 1.0), [-0.75, -0.25, 0.25, 0.75])
    np.testing.assert_allclose(cell_centres(2, 0.0, np.pi), [np.pi / 4, 3 * np.pi / 4])
    np.testing.assert_allclose(to_texcoord([0.0, 7.0, -0.5], 8), [1 / 16, 15 / 16, 0.0])
    np.testing.assert_allclose(from_texcoord(to_texcoord([0.3, 5.0], 8), 8), [0.3, 5.0])
    ijk = np.array([[0, 0, 0], [3, 1, 2]])
    c = voxel_centres(ijk, [1.0, 2.0, 3.0], 0.5)
    np.testing.assert_allclose(c, [[1.25, 2.25, 3.25], [2.75, 2.75, 4.25]])
    np.testing.assert_allclose(index_coords(c, [1.0, 2.0, 3.0], 0.5), ijk)
    assert cell_index(c, [1.0, 2.0, 3.0], 0.5).tolist() == ijk.tolist()
    assert cell_index([[0.99, 2.0, 3.49], [1.5, 2.0, 3.5]], [1.0, 2.0, 3.0], 0.5).tolist() == [[-1, 0, 0], [1, 0, 1]]


def test_boxes():
    pts = np.array([[0.0, 1.0, -2.0], [3.0, -1.0, 5.0], [np.nan, 0.0, 0.0]])
    np.testing.assert_array_equal(points_box(pts), [[0.0, -1.0, -2.0], [3.0, 1.0, 5.0]])
    with pytest.raises(ValueError):
        points_box(np.full((2, 3), np.nan))
    m = np.zeros((5, 6), bool)
    assert mask_box(m) is None
    m[1, 2] = m[3, 4] = True
    assert mask_box(m) == (1, 4, 2, 5)


GL_VERT = """#version 430
void main() { vec2 p = vec2(float((gl_VertexID & 1) * 4 - 1), float((gl_VertexID & 2) * 2 - 1));
              gl_Position = vec4(p, 0.0, 1.0); }"""
GL_FRAG = """#version 430
layout(std430, binding = 0) buffer Coords { vec2 st[]; };
uniform sampler2D tex;
out vec4 colour;
void main() { colour = vec4(texture(tex, st[int(gl_FragCoord.x)]).r, 0.0, 0.0, 1.0); }"""


@pytest.mark.gl
@pytest.mark.parametrize("boundary", ["clamp", "zero", "wrap"])
@pytest.mark.parametrize("filt", ["linear", "nearest"])
def test_against_a_gl_texture(gl_ctx, filt, boundary):
    """What the module documents: GL_LINEAR / GL_NEAREST with CLAMP_TO_EDGE, CLAMP_TO_BORDER (0) and
    REPEAT at s = (x + 0.5) / W, t = (y + 0.5) / H give the sampler's values."""
    ctx = gl_ctx
    x, y = _points(ties=filt == "linear")
    st = np.stack([to_texcoord(x, W), to_texcoord(y, H)], -1).astype(np.float32)
    n = len(st)
    tex = ctx.texture((W, H), 1, IMG.tobytes(), dtype="f4")
    mode = ctx.LINEAR if filt == "linear" else ctx.NEAREST
    kw = {"border_color": (0.0, 0.0, 0.0, 0.0)} if boundary == "zero" else {
        "repeat_x": boundary == "wrap", "repeat_y": boundary == "wrap"}
    sampler = ctx.sampler(texture=tex, filter=(mode, mode), **kw)
    buf = ctx.buffer(st.tobytes())
    prog = ctx.program(vertex_shader=GL_VERT, fragment_shader=GL_FRAG)
    target = ctx.texture((n, 1), 4, dtype="f4")
    fbo = ctx.framebuffer([target])
    vao = ctx.vertex_array(prog, [])
    try:
        fbo.use()
        ctx.viewport = (0, 0, n, 1)
        sampler.use(0)
        prog["tex"].value = 0
        buf.bind_to_storage_buffer(0)
        vao.render(ctx.TRIANGLES, vertices=3)
        got = np.frombuffer(target.read(), np.float32).reshape(n, 4)[:, 0]
    finally:
        for obj in (vao, fbo, target, prog, buf, sampler, tex):
            obj.release()
    np.testing.assert_allclose(sample_image(IMG, x, y, filt, boundary), got, atol=1e-3)
