"""A real range scan for registration tests: a VCG/MeshLab range-map PLY with its camera.

pymeshlab's wheel ships ``pymeshlab/tests/sample_meshes/rangemaps/face000.ply`` (MeshLab sample
data, distributed with PyMeshLab under the GPL-3.0; a structured-light scan of a face,
85,849 vertices in millimetres, 640x480 camera in the header).  It is read here (binary
little-endian PLY with ``element camera``), re-projected into an OpenCV camera as a depth
map, and cut into overlapping windows, each a :class:`Scan` with its own (cropped) camera.

VCG camera fields: ``view_p`` centre, ``x_axis``/``y_axis``/``z_axis`` rows of the rotation,
``focal`` (mm), ``scalex``/``scaley`` (mm per pixel), ``centerx``/``centery`` (pixels),
``viewport`` (pixels).  The optical axis direction is taken from the side of the camera the
points lie on, and the result is checked: the points must project inside the viewport.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from capture.camera import Camera, cv_from_corner, cv_rotation_from_gl_axes, make_K
from capture.sampling import nearest_pixel
from capture.scan import Scan, ScanSet, bounds_from_points

CAMERA_FIELDS = ("view_px view_py view_pz x_axisx x_axisy x_axisz y_axisx y_axisy y_axisz z_axisx z_axisy "
                 "z_axisz focal scalex scaley centerx centery").split()
#: Millimetres -> metres.
MM = 1e-3


def pymeshlab_face_path() -> Path | None:
    """Path of the face range map inside the installed pymeshlab wheel, or None."""
    try:
        import pymeshlab
    except ImportError:
        return None
    p = Path(pymeshlab.__file__).parent / "tests" / "sample_meshes" / "rangemaps" / "face000.ply"
    return p if p.is_file() else None


def read_vcg_rangemap(path: Path) -> tuple[np.ndarray, dict]:
    """(points (N, 3) float64 in the file's units, camera fields dict) of a VCG range-map PLY."""
    path = Path(path)
    b = path.read_bytes()
    end = b.find(b"end_header\n")
    if end < 0:
        raise ValueError(f"{path}: not a PLY file (no end_header)")
    header = b[:end].decode("ascii", "replace").splitlines()
    if "format binary_little_endian 1.0" not in header:
        raise ValueError(f"{path}: only binary little-endian PLY range maps are supported")
    pos = end + len(b"end_header\n")
    elems: list[tuple[str, int, list[tuple[str, str]]]] = []
    for line in header:
        w = line.split()
        if w[:1] == ["element"]:
            elems.append((w[1], int(w[2]), []))
        elif w[:1] == ["property"] and elems:
            if w[1] == "list":
                elems[-1][2].append(("list", w[-1]))
            else:
                elems[-1][2].append((w[2], w[1]))
    types = {"float": "<f4", "double": "<f8", "int": "<i4", "uint": "<u4", "uchar": "u1", "char": "i1",
             "short": "<i2", "ushort": "<u2"}
    cam = None
    pts = None
    for name, count, props in elems:
        if any(t == "list" for t, _ in props):
            break  # faces come after the vertices; not needed
        dt = np.dtype([(n, types[t]) for n, t in props])
        arr = np.frombuffer(b, dt, count, pos)
        pos += dt.itemsize * count
        if name == "camera":
            cam = {n: float(arr[n][0]) for n in dt.names}
        elif name == "vertex":
            pts = np.stack([arr["x"], arr["y"], arr["z"]], axis=1).astype(np.float64)
    if pts is None or cam is None:
        raise ValueError(f"{path}: needs 'element camera' and 'element vertex'")
    return pts, cam


def rangemap_camera(pts: np.ndarray, cam: dict, unit: float = MM) -> Camera:
    """OpenCV camera (metres) of a VCG range map whose points (file units) it saw."""
    R = np.array([[cam["x_axisx"], cam["x_axisy"], cam["x_axisz"]],
                  [cam["y_axisx"], cam["y_axisy"], cam["y_axisz"]],
                  [cam["z_axisx"], cam["z_axisy"], cam["z_axisz"]]])
    c = np.array([cam["view_px"], cam["view_py"], cam["view_pz"]])
    fwd = R[2] if np.median((pts - c) @ R[2]) > 0 else -R[2]
    Rcv = cv_rotation_from_gl_axes(R[0], R[1], fwd)  # VCG: x right, y up in the image
    if np.linalg.det(Rcv) < 0:
        Rcv[0] *= -1
    pose = np.eye(4)
    pose[:3, :3] = Rcv
    pose[:3, 3] = -Rcv @ (c * unit)
    f = cam["focal"] / cam["scalex"]
    fy = cam["focal"] / cam["scaley"]
    W, H = int(cam.get("viewportx", 640)), int(cam.get("viewporty", 480))
    K = make_K(f, fy, cv_from_corner(cam["centerx"]), cv_from_corner(cam["centery"]))
    return Camera(K, pose, W, H, "rangemap")


def rangemap_depth(pts_m: np.ndarray, camera: Camera) -> tuple[np.ndarray, float]:
    """Z-buffer the points (metres) into the camera: (depth (H, W) float32, fraction inside)."""
    uv, z = camera.project(pts_m)
    ok = np.isfinite(uv).all(axis=1) & (z > 0)
    iu = nearest_pixel(uv[ok, 0])
    iv = nearest_pixel(uv[ok, 1])
    zz = z[ok]
    inside = (iu >= 0) & (iu < camera.width) & (iv >= 0) & (iv < camera.height)
    depth = np.full(camera.height * camera.width, np.inf)
    np.minimum.at(depth, iv[inside] * camera.width + iu[inside], zz[inside])
    depth[~np.isfinite(depth)] = 0.0
    return depth.reshape(camera.height, camera.width).astype(np.float32), float(inside.mean())


def window_scans(depth: np.ndarray, camera: Camera, grid: tuple[int, int] = (2, 3), overlap: float = 0.5,
                 stride: int = 2, min_valid: int = 500) -> list[Scan]:
    """Cut a depth map into ``grid`` (rows, cols) overlapping windows (around its valid region),
    each a scan with the cropped (and ``stride``-subsampled) camera.  Colour is flat grey."""
    rows, cols = np.nonzero(depth > 0)
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    gh, gw = grid
    # window size so that neighbours overlap by ``overlap`` of a window
    hh = int((r1 - r0) / (1 + (gh - 1) * (1 - overlap)))
    ww = int((c1 - c0) / (1 + (gw - 1) * (1 - overlap)))
    scans = []
    for a in range(gh):
        for b in range(gw):
            y0 = r0 + int(round(a * hh * (1 - overlap)))
            x0 = c0 + int(round(b * ww * (1 - overlap)))
            d = depth[y0:y0 + hh:stride, x0:x0 + ww:stride]
            if (d > 0).sum() < min_valid:
                continue
            # window pixel (i, j) is full-image pixel (x0 + stride i, y0 + stride j) (OpenCV centres)
            K = camera.K.copy()
            K[0, 2] -= x0
            K[1, 2] -= y0
            K[:2, :] /= stride
            sub = Camera(K, camera.cam_from_world, d.shape[1], d.shape[0], f"win{a}{b}")
            rgb = np.full(d.shape + (3,), 128, np.uint8)
            scans.append(Scan(rgb, d, sub, sub.name))
    return scans


def face_scanset(grid: tuple[int, int] = (2, 3), overlap: float = 0.5, stride: int = 2) -> ScanSet:
    """The pymeshlab face range map as a scan set of overlapping windows (metres, true poses)."""
    p = pymeshlab_face_path()
    if p is None:
        raise FileNotFoundError("pymeshlab's face000.ply range map is not installed")
    pts, cam = read_vcg_rangemap(p)
    camera = rangemap_camera(pts, cam)
    depth, inside = rangemap_depth(pts * MM, camera)
    if inside < 0.99:
        raise ValueError(f"{p}: only {inside:.1%} of the points project into the header's camera")
    scans = window_scans(depth, camera, grid, overlap, stride)
    return ScanSet(tuple(scans), bounds_from_points(pts * MM, margin=0.02),
                   {"source": str(p), "licence": "GPL-3.0 (PyMeshLab sample data)"})
