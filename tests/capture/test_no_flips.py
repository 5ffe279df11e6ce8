"""Only ``capture/camera.py`` flips axes or shifts pixel centres (and, in GLSL, only
``render/shaders/framebuffer_row.glsl``): the code of every package is grepped for the idioms.

What counts (comments and docstrings are skipped; tests are not scanned):

* axis flips: the y/z flip matrix ``diag(1, -1, -1)``, ``CV_TO_GL``, the image-up vector written
  by hand as ``-R[1]`` or as row 1 of a ``cam_from_world``;
* framebuffer rows: ``gl_FragCoord.y``, ``height - 1 - row``-style row arithmetic, the NDC y flip
  ``1 - 2 (v + 0.5) / H``, ``1.0 - uv.y``, ``[::-1]`` / ``np.flipud`` / ``np.flip(axis=0)`` on an
  image;
* pixel-centre shifts between conventions: ``HALF_PIXEL``, a principal point +-0.5, pixel
  coordinates +-0.5 (``xs + 0.5``, ``xy[0] - 0.5``, ``rint(c - 0.5)``), pixel centre to normalised
  image coordinates (``(u + 0.5) / W``) and to a finer grid (``(u + 0.5) * s - 0.5``).

``capture/sampling.py`` (the one sampling core) may name ``HALF_PIXEL``, which it takes from
``capture/camera.py``. The pixel-centre idioms of environment maps are the same arithmetic on texels: they may stand in
``render/shading/envmap.py`` only (its one direction <-> pixel map). Not counted: centres of voxels
and of other tables' texels (``(i + 0.5) * w``, ``(np.arange(n) + 0.5) / n``), NDC to texture
coordinates (``ndc * 0.5 + 0.5``), and rounding to the nearest pixel (``floor(u + 0.5)``, ``rint(u)``).
"""

from __future__ import annotations

import io
import re
import tokenize
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
#: The files allowed to hold the idioms: all of them (None), or the named ones.
HOMES = {"capture/camera.py": None, "capture/sampling.py": {"HALF_PIXEL"}, "render/shaders/framebuffer_row.glsl": None,
         "render/shading/envmap.py": {"pixel centre to normalised coordinates", "rounding a shifted coordinate"}}
#: Top-level folders that are not code of the project.
SKIP_DIRS = {"tests", "out", "build", "dist", "docs", "node_modules"}

_IMAGE = r"(?:fb|img|image|frame|raw|rgba?|colou?r|depth|dep|d01|alpha|nor|normals?|buf|block|pixels|mask|out|data)"
_HEIGHT = r"(?:\b[hH]\b|\bheight\b|\bu_height\b|\w+\.height\b|\bu_size\.y\b|\bsize\.y\b)"
_SIZE = r"(?:\b[WH]\b|\bwidth\b|\bheight\b|\w+\.(?:width|height)\b|\b\w*size\.[xy]\b)"
_HALF = r"[+-]\s*0?\.50*\b(?!\s*\*)"
PATTERNS = {
    "y/z flip matrix": r"diag\(\s*\[?\s*1(?:\.0*)?\s*,\s*-\s*1(?:\.0*)?\s*,\s*-\s*1",
    "CV_TO_GL": r"\bCV_TO_GL\b",
    "image up as -R[1]": r"-\s*R\s*\[\s*1\s*\]",
    "camera y axis read from the pose": r"cam_from_world\s*\[\s*1\b",
    "gl_FragCoord.y": r"gl_FragCoord\s*\.\s*y\b",
    "row flip height - k - row": _HEIGHT + r"\s*[-+]\s*\d+\s*-\s*[\w(]",
    "NDC y flip": r"\b1(?:\.0*)?\s*-\s*2(?:\.0*)?\s*\*[^;=]*" + _HALF + r"[^;=]*/\s*" + _HEIGHT,
    "texture v flip": r"\b1(?:\.0*)?\s*-\s*[\w.]*(?:uv|tex|coord)\w*\s*\.\s*[yt]\b",
    "image rows reversed": r"(?:\)|\b" + _IMAGE + r")\s*\[\s*::\s*-1\s*[\],]",
    "np.flipud / np.flip(axis=0)": r"\bnp\.flipud\(|\bnp\.flip\([^)]*axis\s*=\s*0",
    "HALF_PIXEL": r"\bHALF_PIXEL\b",
    "principal point +-0.5": r"(?:\[\s*[01]\s*,\s*2\s*\]|principal_point_[xy]|"
                             r"center[xy]|centre[xy]|\bc[xy]\b)[\"'\]]*\s*" + _HALF,
    "pixel coordinates +-0.5": r"\b(?:xs|ys|us|vs|iu|iv)\s*" + _HALF + r"|\bxy\s*\[\s*\d\s*\]\s*" + _HALF,
    "rounding a shifted coordinate": r"\b(?:rint|round)\([^()]*" + _HALF + r"\s*\)",
    "pixel centre to normalised coordinates": _HALF + r"\s*\)\s*/\s*" + _SIZE,
    "pixel centre to a finer grid": r"(?<!0\.5 )\+\s*0?\.5\s*\)\s*[*/]\s*\w+\s*-\s*0?\.5\b",
}
COMPILED = {name: re.compile(p) for name, p in PATTERNS.items()}


def _blank(text: str) -> str:
    return re.sub(r"[^\n]", " ", text)


def code_of_python(src: str) -> list[str]:
    """Source lines with comments and docstrings (strings that stand alone as a statement) blanked."""
    lines = [list(line) for line in src.splitlines()]
    starts_statement = True
    for tok in tokenize.generate_tokens(io.StringIO(src).readline):
        if tok.type == tokenize.COMMENT or (tok.type == tokenize.STRING and starts_statement):
            (r0, c0), (r1, c1) = tok.start, tok.end
            for r in range(r0, r1 + 1):
                row = lines[r - 1]
                for k in range(c0 if r == r0 else 0, c1 if r == r1 else len(row)):
                    row[k] = " "
        if tok.type not in (tokenize.COMMENT, tokenize.NL):
            starts_statement = tok.type in (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT)
    return ["".join(r) for r in lines]


def code_of_glsl(src: str) -> list[str]:
    """Source lines with // and /* */ comments blanked."""
    src = re.sub(r"/\*.*?\*/", lambda m: _blank(m.group()), src, flags=re.S)
    return [line.split("//")[0] for line in src.splitlines()]


def flips_in(path: Path, rel: str) -> list[str]:
    """'file:line: idiom: code' for every idiom in ``path`` that its place ``rel`` may not hold."""
    allowed = HOMES.get(rel, set())
    if allowed is None:
        return []
    src = path.read_text(encoding="utf-8")
    lines = code_of_python(src) if path.suffix == ".py" else code_of_glsl(src)
    return [f"{rel}:{i}: {name}: {line.strip()}" for i, line in enumerate(lines, 1)
            for name, rx in COMPILED.items() if name not in allowed and rx.search(line)]


def code_files(root: Path):
    for path in sorted(root.rglob("*")):
        rel = path.relative_to(root)
        top = rel.parts[0]
        if path.suffix not in (".py", ".glsl") or top in SKIP_DIRS or top.startswith("."):
            continue
        yield path, rel.as_posix()


def test_no_flips_outside_the_camera_module():
    found = [hit for path, rel in code_files(REPO) for hit in flips_in(path, rel)]
    assert not found, ("axis flips / pixel-centre shifts outside capture/camera.py (call its named "
                       "functions, or framebuffer_row.glsl in GLSL):\n" + "\n".join(found))


def test_scan_sees_the_packages():
    rels = {rel for _, rel in code_files(REPO)}
    assert set(HOMES) <= rels
    for pkg in ("capture/", "volume/", "render/", "datasets_synthetic/", "furrow/"):
        assert sum(r.startswith(pkg) for r in rels) >= 3, pkg


# The idioms this test was written against (the flips removed from the tree), and near misses it
# must leave alone; each must be judged the same inside a file the scan reads.
CAUGHT = [
    "    return R[0].copy(), -R[1].copy()",
    "    ups = np.array([-c.cam_from_world[1, :3] for c in cameras])",
    "    Rcv = np.stack([R[0] if np.dot(np.cross(R[0], -R[1]), fwd) > 0 else -R[0], -R[1], fwd])",
    "        M[:3, :3] = np.diag([1.0, -1.0, -1.0])",
    "        return np.diag([1.0, -1.0, -1.0])",
    "    K = make_K(f, fy, cam[\"centerx\"] - 0.5, cam[\"centery\"] - 0.5)",
    "    reader.camera_params = ','.join(str(v) for v in (K0[0, 0], K0[1, 1], K0[0, 2] + 0.5, K0[1, 2] + 0.5))",
    "                u, v = p2.xy[0] - 0.5, p2.xy[1] - 0.5",
    "    make_K(fx, fy, cam.principal_point_x - HALF_PIXEL, cam.principal_point_y - HALF_PIXEL)",
    "        y0, y1 = max(h - 2 - int(np.ceil(hi[1])), 0), min(h + 1 - int(np.floor(lo[1])), h)",
    "    return np.stack([xs + 0.5, ys + 0.5], 1), val - clipped, lum[ys, xs] / display_max",
    "    ij = np.rint(c - 0.5).astype(np.int64)",
    "        lo = np.maximum(np.floor((c - ext + 0.5) * s - 0.5).astype(int), 0)",
    "        w = _tent(streaks, m, (ii + 0.5) / s - 0.5, (jj + 0.5) / s - 0.5)",
    "    th_c = np.pi * (np.arange(H) + 0.5) / H",
    "    i0 = np.clip(np.round(uv[:, 1] * H - 0.5).astype(np.int64), 0, H - 1)",
    "    img = np.frombuffer(buf, np.float32).reshape(h, w, 4)[::-1]",
    "    return np.ascontiguousarray(fb[::-1])",
    "    rgb = np.flipud(rgb)",
]
CAUGHT_GLSL = [
    "    gl_Position = vec4(2.0 * (p.x + 0.5) / u_size.x - 1.0, 1.0 - 2.0 * (p.y + 0.5) / u_size.y, 0.0, 1.0);",
    "    ivec2 px = ivec2(int(gl_FragCoord.x), u_height - 1 - int(gl_FragCoord.y));",
    "    vec2 st = vec2(v_uv.x, 1.0 - v_uv.y);",
]
PASSED = [
    "    return lv.origin + (self.surfaces[level].astype(np.float64) + 0.5) * lv.voxel_size",
    "        u = (np.arange(w) + 0.5) / w",
    "    x = uv[..., 0] * W - 0.5",
    "        ix = np.floor(uv[:, 0] + 0.5)",
    "    img = np.ascontiguousarray(img[..., ::-1])  # BGR -> RGB",
    "    return a * streaks.length[m] + a[..., ::-1] * streaks.width[m] / 2",
    "            for o in objs[::-1]:",
    "    side1 = c[:, None] + 0.5 * Ws[..., None] * v",
    "    lim = np.array([width - 0.5, height - 0.5])",
    "    x = (ndc[:, 0] * 0.5 + 0.5) * S - 0.5",
    '    """NDC y = 1 - 2 (v + 0.5) / H; -R[1] is image up."""',
    "    far = max(far, 2 * near)  # gl_FragCoord.y, diag(1, -1, -1)",
]
PASSED_GLSL = [
    "    ivec2 base = ivec2(gl_FragCoord.xy) * SUPERSAMPLE;",
    "    vec3 x = vec3(u_grid_origin + (floor(gl_FragCoord.xy) + 0.5) * u_grid_cell, u_plane_z);",
    "    ivec2 ij = ivec2(floor(uvz.xy + 0.5));",
    "    return texture(msem, t * 0.5 + 0.5).rgb;  // 1.0 - uv.y",
]


def _scan_snippet(tmp_path: Path, line: str, suffix: str) -> list[str]:
    body = f"def f():\n{line}\n" if suffix == ".py" else f"void f() {{\n{line}\n}}\n"
    path = tmp_path / f"snippet{suffix}"
    path.write_text(body)
    return flips_in(path, path.name)


@pytest.mark.parametrize("line", CAUGHT)
def test_patterns_catch_python_flips(tmp_path, line):
    assert _scan_snippet(tmp_path, line, ".py"), line


@pytest.mark.parametrize("line", CAUGHT_GLSL)
def test_patterns_catch_glsl_flips(tmp_path, line):
    assert _scan_snippet(tmp_path, line, ".glsl"), line


@pytest.mark.parametrize("line", PASSED)
def test_patterns_pass_python_non_flips(tmp_path, line):
    assert not _scan_snippet(tmp_path, line, ".py"), line


@pytest.mark.parametrize("line", PASSED_GLSL)
def test_patterns_pass_glsl_non_flips(tmp_path, line):
    assert not _scan_snippet(tmp_path, line, ".glsl"), line


def test_scan_fails_on_a_flip_outside_the_camera_module(tmp_path):
    """A copy of a real module with one flip put back is caught; the module as it is is not."""
    rel = "capture/orbit.py"
    src = (REPO / rel).read_text()
    assert not flips_in(REPO / rel, rel)
    bad = tmp_path / "orbit.py"
    bad.write_text(src.replace("image_up(c)", "-c.cam_from_world[1, :3]"))
    assert src != bad.read_text()
    assert any("camera y axis" in h for h in flips_in(bad, rel))
