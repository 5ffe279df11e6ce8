"""Strands as rings of a polygonal tube: the geometry the GL synthetic renderer draws as
camera-facing ribbons (``datasets_synthetic.strand_gl``), and the numpy twins of its ring formulas.

A scene's strands (fur, needles) are tubes swept by ``geometry.tube_sweep``: rings of ``sides``
vertices around each centre-line point, the k-th at ``centre + r (cos a_k N + sin a_k B)`` with
``a_k = 2 pi k / sides``, ``B = T x N``.  :func:`split_strands` recovers from the mesh the rings
(centre, tangent, colour, radius, sides, frame N), the segments joining consecutive rings, and the
rest of the mesh (skin, pot, stems, leaves: the surfaces, drawn as triangles).

Seen from a direction ``w_dir`` (towards the viewer), a tube segment shows the facets between its
two silhouette vertices on the viewer's side (:func:`silhouette_vertices`, :func:`front_chain`):
about half of its ``sides`` facets.  The GL renderer draws each segment as the strip of those
facets only, with the tube's own vertices and normals: a ribbon folded along the tube's edges that
covers the pixels the tube covers, at the tube's depth, with a third (3 sides) to half the
triangles and none of the back faces.  The chain of a segment is the union of its two rings'
chains, so both silhouettes are inside it; where a segment twists or bends sharply the strip can
miss a sliver the tube covers (measured in tests/datasets_synthetic/test_strand_gl.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets_synthetic.hair_shading import StrandPoints, strand_points
from render.mesh.raster.gl import RasterMesh

#: Relative spread of the vertex distances of one ring allowed before it is not a tube ring.
RING_RADIUS_RTOL = 1e-3
#: Below this length a direction counts as degenerate (unitless).
DEGENERATE = 1e-9


class StrandError(ValueError):
    """A mesh whose strands are not tube rings (``geometry.tube_sweep``)."""


@dataclass(frozen=True)
class StrandGeometry:
    """A scene split into strands and surfaces.

    Attributes:
        points: the strand points (``hair_shading.strand_points``; one per ring).
        radius: (P,) float64 ring radius (metres).
        sides: (P,) int32 vertices of each ring.
        frame: (P, 3) float64 unit direction from the centre to the ring's first vertex (N).
        segments: (M, 2) int32 point indices of consecutive rings of one strand.
        surfaces: the faces between non-strand vertices, as their own mesh (None when there are none).
    """

    points: StrandPoints
    radius: np.ndarray
    sides: np.ndarray
    frame: np.ndarray
    segments: np.ndarray
    surfaces: RasterMesh | None

    @property
    def count(self) -> int:
        """Number of strand points."""
        return len(self.points.centres)


def _rings(mesh: RasterMesh, pts: StrandPoints):
    """(radius, sides, frame) of every strand point; StrandError if a group is not a tube ring."""
    g = pts.group
    idx = np.nonzero(g >= 0)[0]
    sides = np.bincount(g[idx], minlength=len(pts.centres)).astype(np.int32)
    first = idx[np.r_[True, np.diff(g[idx]) != 0]]
    off = mesh.vertices[idx].astype(np.float64) - pts.centres[g[idx]]
    dist = np.linalg.norm(off, axis=1)
    radius = dist[np.r_[True, np.diff(g[idx]) != 0]]
    if np.any(sides < 3) or np.any(np.abs(dist - radius[g[idx]]) > RING_RADIUS_RTOL * radius[g[idx]] + 1e-9):
        raise StrandError("strand vertices are not tube rings of >= 3 equidistant vertices (geometry.tube_sweep): "
                          "the GL synthetic renderer cannot draw them (use --synth-renderer numpy)")
    frame = (mesh.vertices[first].astype(np.float64) - pts.centres) / np.maximum(radius, DEGENERATE)[:, None]
    return radius, sides, frame


def split_strands(mesh: RasterMesh) -> StrandGeometry:
    """The strands (rings and segments) and the surfaces of ``mesh`` (module docstring)."""
    pts = strand_points(mesh)
    g = pts.group
    fg = g[mesh.faces]                                        # (F, 3) point of each corner, -1 = surface
    strand_face = fg >= 0
    if np.any(strand_face.any(1) & ~strand_face.all(1)):
        raise StrandError("a face joins strand and surface vertices: strands must be separate tubes")
    sf = fg[strand_face.all(1)]
    pairs = np.concatenate([sf[:, [0, 1]], sf[:, [1, 2]], sf[:, [0, 2]]])
    pairs = np.sort(pairs[pairs[:, 0] != pairs[:, 1]], axis=1).astype(np.int64)
    key = np.unique(pairs[:, 0] * max(len(pts.centres), 1) + pairs[:, 1])
    segments = np.stack([key // max(len(pts.centres), 1), key % max(len(pts.centres), 1)], 1).astype(np.int32)
    if len(pts.centres):
        radius, sides, frame = _rings(mesh, pts)
    else:
        radius, sides, frame = np.zeros(0), np.zeros(0, np.int32), np.zeros((0, 3))
    return StrandGeometry(pts, radius, sides, frame, segments, surface_mesh(mesh, g < 0))


def surface_mesh(mesh: RasterMesh, keep: np.ndarray) -> RasterMesh | None:
    """The faces of ``mesh`` whose vertices are all ``keep`` (V,) bool, re-indexed (None if none)."""
    faces = mesh.faces[keep[mesh.faces].all(1)]
    if len(faces) == 0:
        return None
    used = np.unique(faces)
    remap = np.full(len(mesh.vertices), -1, np.int64)
    remap[used] = np.arange(len(used))
    pick = lambda a: None if a is None else a[used]
    return RasterMesh(mesh.vertices[used], remap[faces], mesh.colors[used], pick(mesh.normals), pick(mesh.tangents),
                      pick(mesh.occlusion), pick(mesh.specular))


# ------------------------------------------------------------------------------ numpy twins
def ring_direction(tangent, frame, k, sides):
    """(..., 3) unit direction from a ring's centre to its k-th vertex, cos a N + sin a (T x N) with
    a = 2 pi k / sides (geometry.tube_sweep); twin of ``ring_direction`` in strand_ribbon.glsl."""
    a = 2 * np.pi * np.asarray(k, np.float64) / np.asarray(sides, np.float64)
    N = np.asarray(frame, np.float64)
    B = np.cross(np.asarray(tangent, np.float64), N)
    return np.cos(a)[..., None] * N + np.sin(a)[..., None] * B


def silhouette_vertices(tangent, frame, sides: int, w_dir) -> tuple[np.ndarray, np.ndarray]:
    """(kr, kl): the ring vertices with the largest and smallest offset along u = w_dir x T (N when
    T is along ``w_dir``, the unit direction towards the viewer), ties to the lower index; twin of
    ``silhouette_vertices`` in strand_ribbon.glsl.  tangent, frame, w_dir: (..., 3)."""
    T = np.asarray(tangent, np.float64)
    N = np.asarray(frame, np.float64)
    u = np.cross(np.asarray(w_dir, np.float64), T)
    n = np.linalg.norm(u, axis=-1, keepdims=True)
    u = np.where(n > DEGENERATE, u / np.maximum(n, DEGENERATE), N)
    x = np.stack([np.sum(ring_direction(T, N, k, sides) * u, -1) for k in range(int(sides))], -1)
    return np.argmax(x, -1), np.argmin(x, -1)


def front_chain(s0, s1, sides: int) -> tuple[np.ndarray, np.ndarray]:
    """(start, count) of a segment's front chain: ring vertices start, start + 1, ... (mod sides)
    from the right silhouette vertex over the side facing the viewer to the left one, the union of
    the chains of its two rings (``s0``, ``s1`` = (kr, kl) of each); twin of ``front_chain`` in
    strand_ribbon.glsl.  The strip over these vertices is the tube's facets facing the viewer; when
    the two rings disagree so much that the union is one vertex (a segment seen end-on), the chain
    is the whole ring (count = sides + 1: every facet)."""
    half = sides // 2
    wrap = lambda d: np.where(d % sides > half, d % sides - sides, d % sides)
    dr = wrap(np.asarray(s1[0]) - np.asarray(s0[0]))
    dl = wrap(np.asarray(s1[1]) - np.asarray(s0[1]))
    start = np.asarray(s0[0]) + np.minimum(dr, 0)
    stop = np.asarray(s0[1]) + np.maximum(dl, 0)
    count = (stop - start) % sides + 1
    return start % sides, np.where(count < 2, sides + 1, count)  # a single vertex: every facet
