"""Model -> files other tools open: the mesh (GLB or PLY), fused coloured points (PLY), occluder spheres (PLY).

Every file is written by Open3D (``open3d.io`` / ``open3d.t.io``, already a furrow dependency); the
GLB's material is then set with pygltflib (see :func:`write_mesh`).  Nothing here packs bytes by
hand.  Coordinates are the capture's world frame in metres, unchanged (the frame of the scan
set's cameras and of ``model.json``), so the three files and the cameras line up.

Colour: furrow keeps linear float colour.  glTF defines ``COLOR_0`` as linear, so the GLB stores the
linear values as float32 (exact).  PLY viewers (MeshLab, CloudCompare, Blender) show ``red green
blue`` bytes as display values, so the PLY files store 8-bit sRGB (``capture.scan.to_uint8_srgb``).

The sphere set is a PLY *point* file: one vertex per sphere with ``x y z`` (centre) and a
``radius`` property, all float32 metres.  Why not a meshed PLY: it is lossless (a tessellated sphere
is only an approximation of the radius), 16 bytes per sphere instead of hundreds, and it is what
the consumers of an occluder proxy need (physics / shadow proxies, Blender's "instance on points"
with the radius attribute as scale, CloudCompare shows radius as a scalar field).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from capture.atomic import atomic_write
from capture.scan import linear_to_srgb
from volume.model import Model, ModelError

#: Mesh formats :func:`write_mesh` accepts (by file suffix).
MESH_SUFFIXES = (".glb", ".ply")
#: Fused points: default voxel of the colour-averaging downsample, as a fraction of the finest
#: pyramid level's voxel edge (half a voxel keeps the surface detail the model itself holds).
POINT_VOXEL_FRACTION = 0.5
#: glTF material of the exported mesh: a dielectric (the glTF default metallicFactor 1 would
#: show vertex colours as dark metal in PBR viewers) with fully rough reflection.
GLTF_METALLIC = 0.0
GLTF_ROUGHNESS = 1.0


class ExportError(ModelError):
    """A model part cannot be exported (empty, wrong format); the message names the file."""


@dataclass(frozen=True)
class ExportResult:
    """What one export wrote.

    Attributes:
        path: the file written.
        count: vertices (mesh), points or spheres written.
        faces: triangles written (mesh only, else 0).
    """

    path: Path
    count: int
    faces: int = 0


def _srgb(linear: np.ndarray) -> np.ndarray:
    """Linear colour -> sRGB-encoded float in [0, 1] (what Open3D writes to PLY as bytes * 255)."""
    return linear_to_srgb(np.asarray(linear, np.float32)).astype(np.float64)


def write_mesh(model: Model, path) -> ExportResult:
    """The baseline mesh with per-vertex colour as binary glTF (``.glb``) or PLY (``.ply``).

    GLB: positions, vertex normals, linear float32 ``COLOR_0`` and a rough dielectric material.
    PLY: binary little-endian, float positions and normals, sRGB ``uchar`` colours.  Vertices and
    faces are written as the model holds them (same order, same count).
    """
    import open3d as o3d

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise ExportError(f"{path}: mesh export writes {' or '.join(MESH_SUFFIXES)}, not {suffix or 'no suffix'!r}")
    v, f = model.mesh_vertices, model.mesh_faces
    if len(v) == 0 or len(f) == 0:
        raise ExportError(f"{path}: the model has no mesh to export")
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v.astype(np.float64)),
                                     o3d.utility.Vector3iVector(f.astype(np.int32)))
    mesh.compute_vertex_normals()
    if model.mesh_colors is not None:
        c = model.mesh_colors.astype(np.float64) if suffix == ".glb" else _srgb(model.mesh_colors)
        mesh.vertex_colors = o3d.utility.Vector3dVector(c)
    with atomic_write(path) as tmp:
        ok = o3d.io.write_triangle_mesh(str(tmp), mesh, write_ascii=False, compressed=False,
                                        write_vertex_normals=True, write_vertex_colors=model.mesh_colors is not None,
                                        write_triangle_uvs=False)
        if not ok:
            raise ExportError(f"{path}: Open3D could not write the mesh")
        if suffix == ".glb":
            _set_gltf_material(tmp)
    return ExportResult(path, len(v), len(f))


def _set_gltf_material(path: Path) -> None:
    """Give every primitive of a GLB one rough dielectric material (pygltflib rewrites the file)."""
    import pygltflib

    g = pygltflib.GLTF2().load(str(path))
    pbr = pygltflib.PbrMetallicRoughness(baseColorFactor=[1.0, 1.0, 1.0, 1.0], metallicFactor=GLTF_METALLIC,
                                         roughnessFactor=GLTF_ROUGHNESS)
    g.materials = [pygltflib.Material(name="furrow", doubleSided=True, pbrMetallicRoughness=pbr)]
    for m in g.meshes:
        for p in m.primitives:
            p.material = 0
    g.asset.generator = "furrow (Open3D + pygltflib)"
    g.save_binary(str(path))


def fused_points(model: Model, voxel: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Coloured points of every kept view, fused: ((N, 3) float64 world metres, (N, 3) float32 linear colour).

    Each model camera's RGBz geometry depth (0 = none) is back-projected with its colour; the union
    is downsampled on a grid of edge ``voxel`` metres (default POINT_VOXEL_FRACTION of the finest
    pyramid voxel), each occupied cell giving the mean position and mean linear colour of its
    points (Open3D ``voxel_down_sample``).  ``voxel=0`` keeps every point.
    """
    import open3d as o3d

    pts, cols = [], []
    for cam, rgb, depth in zip(model.rgbz.cameras, model.rgbz.rgb, model.rgbz.depth):
        p, mask = cam.depth_to_points(depth)
        pts.append(p)
        cols.append(rgb[mask])
    if not pts or sum(len(p) for p in pts) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.float32)
    p = np.concatenate(pts)
    c = np.concatenate(cols).astype(np.float64)
    if voxel is None:
        voxel = POINT_VOXEL_FRACTION * model.pyramid.levels[-1].voxel_size
    if voxel < 0 or not np.isfinite(voxel):
        raise ExportError(f"point voxel must be a finite size >= 0 in metres, got {voxel}")
    if voxel == 0:
        return p, c.astype(np.float32)
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p))
    pc.colors = o3d.utility.Vector3dVector(c)
    down = pc.voxel_down_sample(float(voxel))
    return np.asarray(down.points), np.asarray(down.colors).astype(np.float32)


def write_points(model: Model, path, voxel: float | None = None) -> ExportResult:
    """The fused coloured points (:func:`fused_points`) as a binary PLY: float x y z, sRGB uchar colour."""
    import open3d as o3d

    path = Path(path)
    if path.suffix.lower() != ".ply":
        raise ExportError(f"{path}: points are written as .ply")
    p, c = fused_points(model, voxel)
    if len(p) == 0:
        raise ExportError(f"{path}: the model's RGBz images hold no depth: no point to export")
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p))
    pc.colors = o3d.utility.Vector3dVector(_srgb(c))
    with atomic_write(path) as tmp:
        if not o3d.io.write_point_cloud(str(tmp), pc, write_ascii=False, compressed=False):
            raise ExportError(f"{path}: Open3D could not write the points")
    return ExportResult(path, len(p))


def write_spheres(model: Model, path) -> ExportResult:
    """The occluder sphere set as a binary PLY of centres with a ``radius`` property (module docstring)."""
    import open3d as o3d

    path = Path(path)
    if path.suffix.lower() != ".ply":
        raise ExportError(f"{path}: the sphere set is written as .ply (centres + radius)")
    s = model.spheres
    if len(s) == 0:
        raise ExportError(f"{path}: the model has no occluder spheres")
    pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(s.centers.astype(np.float32)))
    pc.point.radius = o3d.core.Tensor(s.radii.astype(np.float32).reshape(-1, 1))
    with atomic_write(path) as tmp:
        if not o3d.t.io.write_point_cloud(str(tmp), pc, write_ascii=False, compressed=False):
            raise ExportError(f"{path}: Open3D could not write the spheres")
    return ExportResult(path, len(s))


# ---------------------------------------------------------------------------- 3D Gaussian splats
#: The PLY header's first lines (what the 3DGS reference writes through plyfile on a little-endian machine).
SPLAT_PLY_FORMAT = "format binary_little_endian 1.0"


def splat_ply_fields(degree: int) -> list[str]:
    """The vertex properties of a 3D Gaussian Splatting PLY of SH degree ``degree``, in the order
    of the reference (graphdeco-inria/gaussian-splatting ``GaussianModel.construct_list_of_attributes``):
    x y z nx ny nz f_dc_0..2 f_rest_0..(3 (K - 1) - 1) opacity scale_0..2 rot_0..3."""
    from volume.splat_sh import n_coeffs

    k = n_coeffs(degree)
    return (["x", "y", "z", "nx", "ny", "nz"] + [f"f_dc_{i}" for i in range(3)]
            + [f"f_rest_{i}" for i in range(3 * (k - 1))] + ["opacity"] + [f"scale_{i}" for i in range(3)]
            + [f"rot_{i}" for i in range(4)])


def splat_records(splats) -> np.ndarray:
    """(N, F) float32 PLY rows of ``splats`` (volume.splats.Splats) in :func:`splat_ply_fields` order,
    stored as the reference stores its parameters: normals 0; f_dc the DC coefficient per channel;
    f_rest channel-major (all of red's higher coefficients, then green's, then blue's: the
    reference's ``features_rest.transpose(1, 2).flatten``); opacity as its logit; scales as their
    natural log; rotation as the quaternion (w, x, y, z)."""
    n, k = len(splats), splats.sh.shape[1]
    o = splats.opacities.astype(np.float64)
    rest = splats.sh[:, 1:, :].transpose(0, 2, 1).reshape(n, 3 * (k - 1))
    cols = [splats.positions, np.zeros((n, 3), np.float32), splats.sh[:, 0, :], rest,
            np.log(o / (1.0 - o))[:, None], np.log(splats.scales.astype(np.float64)), splats.rotations]
    return np.concatenate([np.asarray(c, np.float32).reshape(n, -1) for c in cols], 1)


def splat_ply_header(n: int, degree: int) -> bytes:
    """The PLY header of ``n`` Gaussians of SH degree ``degree`` (ASCII, ends with ``end_header\\n``)."""
    lines = ["ply", SPLAT_PLY_FORMAT, f"element vertex {int(n)}"]
    lines += [f"property float {name}" for name in splat_ply_fields(degree)]
    return ("\n".join(lines + ["end_header"]) + "\n").encode("ascii")


def write_splats(splats, path) -> ExportResult:
    """The Gaussians as a 3D Gaussian Splatting PLY (binary little-endian float32, the reference's
    header and field order: :func:`splat_ply_fields`, :func:`splat_records`), written atomically."""
    path = Path(path)
    if path.suffix.lower() != ".ply":
        raise ExportError(f"{path}: splats are written as .ply")
    if len(splats) == 0:
        raise ExportError(f"{path}: no Gaussian to export")
    with atomic_write(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(splat_ply_header(len(splats), splats.degree))
            fh.write(splat_records(splats).astype("<f4").tobytes())
    return ExportResult(path, len(splats))


def _ply_header(path: Path, fh) -> tuple[int, list[str]]:
    """(vertex count, property names) of a binary little-endian float PLY with one element."""
    if fh.readline().strip() != b"ply":
        raise ExportError(f"{path}: not a PLY file (no 'ply' magic)")
    n, names = None, []
    for _ in range(10000):
        raw = fh.readline()
        if not raw:
            break
        line = raw.decode("ascii", "replace").strip()
        words = line.split()
        if line == "end_header":
            if n is None:
                raise ExportError(f"{path}: no 'element vertex' in the header")
            return n, names
        if words[:1] in (["comment"], ["obj_info"]):
            continue
        if words[:1] == ["format"] and line != SPLAT_PLY_FORMAT:
            raise ExportError(f"{path}: {line!r}: only binary_little_endian 1.0 splat files are read")
        elif words[:2] == ["element", "vertex"]:
            n = int(words[2])
        elif words[:1] == ["element"]:
            raise ExportError(f"{path}: unexpected element {line!r} (a splat PLY holds vertices only)")
        elif words[:1] == ["property"]:
            if words[1] not in ("float", "float32") or len(words) != 3:
                raise ExportError(f"{path}: property {line!r}: splat properties are float32")
            names.append(words[2])
    raise ExportError(f"{path}: the header has no end_header")


def read_splats(path):
    """The Gaussians of a 3D Gaussian Splatting PLY (:func:`write_splats`, or the reference's own
    files): activations applied (sigmoid opacity, exp scales, normalised quaternions); errors
    name the file and the problem."""
    from volume.splat_sh import degree_of
    from volume.splats import Splats

    path = Path(path)
    if not path.is_file():
        raise ExportError(f"{path}: no such splat file")
    with open(path, "rb") as fh:
        n, names = _ply_header(path, fh)
        raw = fh.read()
    if len(raw) != 4 * n * len(names):
        raise ExportError(f"{path}: {len(raw)} bytes of data for {n} vertices x {len(names)} float properties "
                          "(truncated?)")
    data = np.frombuffer(raw, "<f4")
    rows = data.reshape(n, len(names)).astype(np.float64)
    n_rest = sum(name.startswith("f_rest_") for name in names)
    try:
        if n_rest % 3:
            raise ValueError
        degree = degree_of(n_rest // 3 + 1)
    except ValueError:
        raise ExportError(f"{path}: {n_rest} f_rest properties are no SH degree") from None
    missing = [f for f in splat_ply_fields(degree) if f not in names and f[0] != "n"]
    if missing:
        raise ExportError(f"{path}: missing properties {missing}")

    def col(name):
        return rows[:, names.index(name)]

    k = n_rest // 3 + 1
    sh = np.zeros((n, k, 3))
    sh[:, 0, :] = np.stack([col(f"f_dc_{c}") for c in range(3)], 1)
    if k > 1:
        rest = np.stack([col(f"f_rest_{i}") for i in range(n_rest)], 1)
        sh[:, 1:, :] = rest.reshape(n, 3, k - 1).transpose(0, 2, 1)
    q = np.stack([col(f"rot_{i}") for i in range(4)], 1)
    q /= np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-30)
    o = 1.0 / (1.0 + np.exp(-col("opacity")))
    try:
        return Splats(np.stack([col(c) for c in "xyz"], 1), np.exp(np.stack([col(f"scale_{i}") for i in range(3)], 1)),
                      q, np.clip(o, 1e-6, 1 - 1e-6), sh)
    except ValueError as e:
        raise ExportError(f"{path}: {e}") from None
