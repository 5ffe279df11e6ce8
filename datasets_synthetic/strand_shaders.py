"""Shaders and GPU records of the GL synthetic renderer (``datasets_synthetic.strand_gl``): the
shader loader of this package's ``shaders/`` folder, the constants injected into the shaders from
their numpy twins (``render.shading.hair``), and the packing of strand points and hair lights into
the storage buffers the shaders read (layouts in ``strand_points.glsl`` and
``strand_lobes_comp.glsl``)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from datasets_synthetic.hair_shading import WIDTH_NODES_SYNTH
from datasets_synthetic.strands import StrandGeometry
from render.mesh.raster.gl import RasterMesh
from render.shading.hair import HairParams, sigma_a_from_colour, width_nodes

#: This package's shaders (package data, pyproject [tool.setuptools.package-data]).
SHADER_DIR = Path(__file__).resolve().parent / "shaders"
#: Invocations per work group of the compute passes.
LOCAL_SIZE = 64
#: Blue of a colour-attachment sample that holds a strand's (segment, t) until the deferred pass
#: shades it (shaded colours are never negative).
STRAND_SENTINEL = -1.0
#: Most segments the strand pass can name (an exact integer in the float32 colour attachment).
MAX_SEGMENTS = 2**24
#: Most sides of a strand's tube the geometry shader draws (its strip has at most 2 (this + 1) vertices).
MAX_SIDES = 8
#: Hierarchical-depth cull of strand strips behind the surfaces (strand_hiz_comp.glsl): tile size
#: (pixels), the most tiles one strip's screen box may touch and still be tested, and the depth
#: margin (window units, above the 24-bit depth buffer's step) a strip must lie beyond them.
HIZ_TILE = 16
MAX_TILES_TESTED = 16
HIZ_EPS = 1e-6
#: Floats per strand-point record (strand_points.glsl) and per light record (strand_lobes_comp.glsl).
POINT_FLOATS = 16
LIGHT_FLOATS = 20
#: Defines of the shaders that name the sentinel and the hierarchical-depth cull.
DEFERRED_DEFINES = {"STRAND_SENTINEL": f"{STRAND_SENTINEL:.1f}"}
HIZ_DEFINES = {"TILE": HIZ_TILE, "MAX_TILES_TESTED": MAX_TILES_TESTED, "HIZ_EPS": f"{HIZ_EPS:.9e}"}
_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$')


def load_synth_shader(name: str, defines: dict | None = None) -> str:
    """Source of the shader ``name``: from this package's shaders/ folder, else the render package's
    (``render.gl.load_shader``), ``#include`` resolved the same way (each file once) and ``defines``
    put after the ``#version`` line."""
    text = _expand(name, set())
    if defines:
        block = "".join(f"#define {k} {v}\n" for k, v in defines.items())
        head, _, rest = text.partition("\n")
        text = head + "\n" + block + rest if head.lstrip().startswith("#version") else block + text
    return text


def _expand(name: str, seen: set) -> str:
    if name in seen:
        return ""
    seen.add(name)
    path = SHADER_DIR / name
    if not path.is_file():
        from render.gl import load_shader

        return load_shader(name)
    out = []
    for line in path.read_text().splitlines():
        m = _INCLUDE.match(line)
        out.append(_expand(m.group(1), seen) if m else line)
    return "\n".join(out) + "\n"


def _floats(a) -> str:
    return "float[](" + ", ".join(f"{float(x):.9e}" for x in a) + ")"


def lobe_defines(n_lights: int, params: HairParams = HairParams(), nodes: int = WIDTH_NODES_SYNTH) -> dict:
    """Constants of strand_lobes_comp.glsl, from its numpy twin's (render.shading.hair)."""
    hs, ws = width_nodes(nodes)
    # sigma_a_from_colour(c) = (log(c) / den)^2: den read off the twin itself at c = 1/2
    den = -np.log(0.5) / float(np.sqrt(sigma_a_from_colour(0.5, params.beta_n)))
    return {"LOCAL_SIZE": LOCAL_SIZE, "N_LIGHTS": max(int(n_lights), 1), "N_NODES": int(nodes),
            "NODE_H_LIST": _floats(hs), "NODE_W_LIST": _floats(ws), "ETA": f"{params.eta:.9e}",
            "ALPHA_RAD": f"{np.radians(params.alpha_deg):.9e}", "SIGMA_DEN": f"{den:.9e}"}


def light_records(dirs, power, spread, params: HairParams = HairParams()) -> np.ndarray:
    """(L, LIGHT_FLOATS) float32 records of strand_lobes_comp.glsl's Light: direction, power, 1 / v_p
    and log normaliser of M_p (p = 0..3), 1 / s and norm / s of the logistic, per light (the
    per-light constants of render.shading.hair._radiance_block, widened by ``spread``)."""
    spread = np.asarray(spread, np.float64)
    v = params.variances()[None, :] + spread[:, None]                          # (L, 4)
    s = np.sqrt(params.azimuthal_scale() ** 2 + 3 * spread / np.pi**2)
    norm = 1 / (1 / (1 + np.exp(-np.pi / s)) - 1 / (1 + np.exp(np.pi / s)))
    out = np.zeros((len(spread), LIGHT_FLOATS), np.float64)
    out[:, 0:3] = dirs
    out[:, 4:7] = power
    out[:, 8:12] = 1 / v
    out[:, 12:16] = -1 / v - np.log(v) - np.log1p(-np.exp(-2 / v))
    out[:, 16] = 1 / s
    out[:, 17] = norm / s
    return out.astype(np.float32)


def point_records(geo: StrandGeometry, mesh: RasterMesh) -> np.ndarray:
    """(P, POINT_FLOATS) float32 strand-point records (strand_points.glsl)."""
    pts = geo.points
    first = np.nonzero(np.r_[True, np.diff(pts.group) != 0] & (pts.group >= 0))[0]
    occl = mesh.occlusion[first] if mesh.occlusion is not None else np.ones(len(first))
    spec = mesh.specular[first] if mesh.specular is not None else np.zeros(len(first))
    out = np.zeros((geo.count, POINT_FLOATS), np.float64)
    out[:, 0:3], out[:, 3] = pts.centres, geo.radius
    out[:, 4:7], out[:, 7] = pts.tangents, geo.sides
    out[:, 8:11], out[:, 11] = pts.colours, occl
    out[:, 12:15], out[:, 15] = geo.frame, spec
    return out.astype(np.float32)
