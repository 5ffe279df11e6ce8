"""The one camera model of furrow, and the one place that converts between conventions.

Inside furrow every camera follows **OpenCV**: x right, y down, z forward (metres);
pixel (i, j) (column i, row j) has its centre at (u, v) = (i, j); ``K`` maps camera
coordinates to pixels.  This module alone converts to and from

* the nerfstudio / instant-ngp ``transform_matrix`` (camera-to-world, OpenGL axes:
  x right, y up, z back) and its half-pixel-shifted intrinsics (pixel centre at i + 0.5),
* the OpenGL view and projection matrices used by ``render/``,
* OpenGL framebuffer row order (bottom row first) and image row order (top row first),
* corner-origin pixel coordinates (pixel i's centre at i + 0.5: OpenGL windows, nerfstudio,
  COLMAP, VCG range maps) and resampled images (a pixel grid at another resolution).

Nowhere else in the code base flips an axis or shifts a pixel centre: other modules call the
named functions below (GLSL calls ``render/shaders/framebuffer_row.glsl``, its twin), and
``tests/capture/test_no_flips.py`` greps the tree to keep it so.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Diagonal that flips y and z: OpenCV camera axes <-> OpenGL camera axes.
CV_TO_GL = np.diag([1.0, -1.0, -1.0, 1.0])
#: Row of ``cam_from_world`` holding the camera's y axis (image down) in world coordinates.
_IMAGE_DOWN_ROW = 1
#: Camera.unproject of many pixels by capture.camera_kernel (True), else numpy (the reference).
UNPROJECT_COMPILED = True
#: Fewest pixels the compiled path takes (below, numpy's fixed cost is small).
UNPROJECT_COMPILED_MIN = 4096
#: Largest deviation of R^T R from I (and of det R from 1) accepted for a rigid pose.
RIGID_TOLERANCE = 1e-4
#: Offset between OpenCV pixel centres (integers) and nerfstudio/OpenGL ones (i + 0.5).
HALF_PIXEL = 0.5


class CameraError(ValueError):
    """An invalid camera: non-finite, non-rigid, or inconsistent intrinsics."""


def check_rigid(m: np.ndarray, what: str = "pose") -> np.ndarray:
    """Return ``m`` as a float64 (4, 4) array, or raise CameraError naming ``what``.

    A rigid transform has a finite rotation block with R^T R = I, det R = +1 and a last
    row (0, 0, 0, 1), all within ``RIGID_TOLERANCE``.
    """
    m = np.asarray(m, dtype=np.float64)
    if m.shape != (4, 4):
        raise CameraError(f"{what}: expected a 4x4 matrix, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise CameraError(f"{what}: pose contains NaN or inf")
    r = m[:3, :3]
    err = np.abs(r.T @ r - np.eye(3)).max()
    if err > RIGID_TOLERANCE or abs(np.linalg.det(r) - 1.0) > RIGID_TOLERANCE:
        raise CameraError(
            f"{what}: pose is not rigid (|R^T R - I| = {err:.2e}, det R = {np.linalg.det(r):.6f}; "
            "scale, shear or reflection are not allowed)"
        )
    if np.abs(m[3] - [0, 0, 0, 1]).max() > RIGID_TOLERANCE:
        raise CameraError(f"{what}: last row of the pose must be (0, 0, 0, 1), got {m[3]}")
    return m


def make_K(fx: float, fy: float, cx: float, cy: float, skew: float = 0.0) -> np.ndarray:
    """OpenCV intrinsic matrix (3, 3) in pixels."""
    return np.array([[fx, skew, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]], dtype=np.float64)


@dataclass(frozen=True)
class Camera:
    """A pinhole camera in the OpenCV convention.

    Attributes:
        K: (3, 3) float64 intrinsics in pixels; pixel (i, j) has its centre at u=i, v=j.
        cam_from_world: (4, 4) float64 rigid transform, world (metres) -> camera (metres).
        width: image width in pixels.
        height: image height in pixels.
    """

    K: np.ndarray
    cam_from_world: np.ndarray
    width: int
    height: int
    name: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        K = np.asarray(self.K, dtype=np.float64)
        label = f"camera {self.name!r}" if self.name else "camera"
        if K.shape != (3, 3) or not np.all(np.isfinite(K)):
            raise CameraError(f"{label}: K must be a finite 3x3 matrix")
        if K[0, 0] <= 0 or K[1, 1] <= 0 or abs(K[2, 2] - 1) > 1e-9 or np.any(K[2, :2] != 0) or K[1, 0] != 0:
            raise CameraError(f"{label}: K must be upper triangular with fx, fy > 0 and K[2,2] = 1, got {K.tolist()}")
        if int(self.width) <= 0 or int(self.height) <= 0:
            raise CameraError(f"{label}: image size must be positive, got {self.width}x{self.height}")
        pose = check_rigid(self.cam_from_world, label)
        K.setflags(write=False)
        pose = pose.copy()
        pose.setflags(write=False)
        object.__setattr__(self, "K", K)
        object.__setattr__(self, "cam_from_world", pose)
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))

    # ------------------------------------------------------------------ geometry
    @property
    def world_from_cam(self) -> np.ndarray:
        """(4, 4) camera-to-world transform (OpenCV axes)."""
        r = self.cam_from_world[:3, :3]
        t = self.cam_from_world[:3, 3]
        out = np.eye(4)
        out[:3, :3] = r.T
        out[:3, 3] = -r.T @ t
        return out

    @property
    def center(self) -> np.ndarray:
        """(3,) camera centre in world coordinates (metres)."""
        return self.world_from_cam[:3, 3]

    @property
    def forward(self) -> np.ndarray:
        """(3,) unit optical axis (+z of the camera) in world coordinates."""
        return self.cam_from_world[2, :3].copy()

    def world_to_cam(self, points: np.ndarray) -> np.ndarray:
        """(..., 3) world points -> (..., 3) camera-frame points."""
        p = np.asarray(points, dtype=np.float64)
        return p @ self.cam_from_world[:3, :3].T + self.cam_from_world[:3, 3]

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project world points.

        Args:
            points: (..., 3) world coordinates in metres.
        Returns:
            uv: (..., 2) pixel coordinates (OpenCV centres); NaN where z <= 0.
            z: (...,) z-depth along the optical axis in metres.
        """
        pc = self.world_to_cam(points)
        z = pc[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            xn = np.where(z > 0, pc[..., 0] / z, np.nan)
            yn = np.where(z > 0, pc[..., 1] / z, np.nan)
        K = self.K
        u = K[0, 0] * xn + K[0, 1] * yn + K[0, 2]
        v = K[1, 1] * yn + K[1, 2]
        return np.stack([u, v], axis=-1), z

    def pixel_rays(self, uv: np.ndarray) -> np.ndarray:
        """(..., 2) pixels -> (..., 3) camera-frame directions with z = 1."""
        uv = np.asarray(uv, dtype=np.float64)
        K = self.K
        y = (uv[..., 1] - K[1, 2]) / K[1, 1]
        x = (uv[..., 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
        return np.stack([x, y, np.ones_like(x)], axis=-1)

    def unproject(self, uv: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """Pixels with z-depth (metres) -> (..., 3) world points.  (N, 2) pixels, at least
        UNPROJECT_COMPILED_MIN of them, go through capture.camera_kernel (the same points here; the
        lines below are its reference)."""
        if UNPROJECT_COMPILED and np.ndim(uv) == 2 and np.shape(uv)[1] == 2 and np.ndim(depth) == 1 \
                and len(depth) >= UNPROJECT_COMPILED_MIN:
            from capture.camera_kernel import unproject

            return unproject(self.K, self.world_from_cam, uv, depth)
        pc = self.pixel_rays(uv) * np.asarray(depth, dtype=np.float64)[..., None]
        wfc = self.world_from_cam
        return pc @ wfc[:3, :3].T + wfc[:3, 3]

    def pixel_grid(self) -> np.ndarray:
        """(H, W, 2) pixel-centre coordinates (u, v) of every pixel, OpenCV convention."""
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        return np.stack([u, v], axis=-1)

    def depth_to_points(self, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Back-project a z-depth map (H, W) in metres; 0 / non-finite = no data.

        Returns (points (N, 3) world, mask (H, W) bool of the pixels used).
        """
        depth = np.asarray(depth)
        if depth.shape != (self.height, self.width):
            raise CameraError(f"depth shape {depth.shape} does not match camera {self.height}x{self.width}")
        mask = np.isfinite(depth) & (depth > 0)
        v, u = np.nonzero(mask)  # row-major, as pixel_grid()[mask], without the full grid
        uv = np.stack([u, v], axis=-1).astype(np.float64)
        return self.unproject(uv, depth[mask]), mask

    def footprint(self, depth: float) -> float:
        """Approximate side (metres) of one pixel at z-depth ``depth`` (mean of fx, fy)."""
        return float(depth) * 2.0 / (self.K[0, 0] + self.K[1, 1])

    def scaled(self, factor: float) -> Camera:
        """The same camera for an image resized by ``factor`` (pixel centres handled exactly)."""
        K = self.K.copy()
        K[0, 0] *= factor
        K[1, 1] *= factor
        K[0, 1] *= factor
        K[:2, 2] = resample_pixel_coords(K[:2, 2], factor)
        return Camera(K, self.cam_from_world, round(self.width * factor), round(self.height * factor), self.name)

    # ------------------------------------------------------------- conventions
    def to_nerfstudio(self) -> dict:
        """nerfstudio frame fields: ``transform_matrix`` (c2w, OpenGL axes) and intrinsics
        with pixel centres at i + 0.5 (``fl_x fl_y cx cy w h``)."""
        return {
            "transform_matrix": (self.world_from_cam @ CV_TO_GL).tolist(),
            "fl_x": float(self.K[0, 0]),
            "fl_y": float(self.K[1, 1]),
            "cx": float(corner_from_cv(self.K[0, 2])),
            "cy": float(corner_from_cv(self.K[1, 2])),
            "w": self.width,
            "h": self.height,
        }

    @staticmethod
    def from_nerfstudio(
        transform_matrix, fl_x: float, fl_y: float, cx: float, cy: float, w: int, h: int, name: str = ""
    ) -> Camera:
        """Inverse of :meth:`to_nerfstudio` (nerfstudio cx, cy have centres at i + 0.5)."""
        c2w_gl = check_rigid(transform_matrix, f"camera {name!r}" if name else "transform_matrix")
        c2w_cv = c2w_gl @ CV_TO_GL
        return Camera(
            make_K(fl_x, fl_y, cv_from_corner(cx), cv_from_corner(cy)), invert_rigid(c2w_cv), int(w), int(h), name
        )

    def gl_view(self) -> np.ndarray:
        """(4, 4) OpenGL view matrix (world -> eye, eye looks down -z, y up)."""
        return CV_TO_GL @ self.cam_from_world

    def gl_projection(self, near: float, far: float) -> np.ndarray:
        """(4, 4) OpenGL projection matrix that reproduces ``K`` exactly.

        NDC x = 2 (u + 0.5) / W - 1 and NDC y = 1 - 2 (v + 0.5) / H for the OpenCV pixel
        (u, v), so framebuffer row r (bottom first) is image row H - 1 - r; use
        :func:`gl_rows_to_image` on read-back.  Depth maps [near, far] to NDC [-1, 1].
        """
        if not (0 < near < far):
            raise CameraError(f"need 0 < near < far, got near={near}, far={far}")
        fx, s, cx = self.K[0]
        fy, cy = self.K[1, 1], self.K[1, 2]
        W, H = self.width, self.height
        P = np.zeros((4, 4))
        P[0, 0] = 2 * fx / W
        P[0, 1] = -2 * s / W
        P[0, 2] = 1 - 2 * corner_from_cv(cx) / W
        P[1, 1] = 2 * fy / H
        P[1, 2] = 2 * corner_from_cv(cy) / H - 1
        P[2, 2] = -(far + near) / (far - near)
        P[2, 3] = -2 * far * near / (far - near)
        P[3, 2] = -1.0
        return P


def cam_from_world_of_transform(transform_matrix) -> np.ndarray:
    """(4, 4) float64 OpenCV cam_from_world of a transforms.json / nerfstudio ``transform_matrix``
    (OpenGL camera-to-world), as :meth:`Camera.from_nerfstudio` reads it (no rigidity check)."""
    return invert_rigid(np.asarray(transform_matrix, np.float64) @ CV_TO_GL)


def invert_rigid(m: np.ndarray) -> np.ndarray:
    """Inverse of a (4, 4) rigid transform."""
    out = np.eye(4)
    out[:3, :3] = m[:3, :3].T
    out[:3, 3] = -m[:3, :3].T @ m[:3, 3]
    return out


def misread_poses(world_from_cam: np.ndarray) -> dict[str, np.ndarray]:
    """The (4, 4) camera-to-world transforms (OpenCV axes) meant by a pose read as ``world_from_cam``, had its file
    been written in another convention than its format's (capture.depth_agreement.convention_check), up to one
    rigid transform of the whole scene (which no check can see): ``axes`` (its camera y and z axes negated: a
    transforms.json camera-to-world matrix written in OpenCV axes), ``inverse`` (a transforms.json world-to-camera
    matrix in OpenCV axes, or a COLMAP pose that was camera-to-world), ``inverse, axes`` (a transforms.json
    world-to-camera matrix in OpenGL axes)."""
    P = np.asarray(world_from_cam, np.float64)
    inv = invert_rigid(P)
    return {"axes": P @ CV_TO_GL, "inverse": inv, "inverse, axes": inv @ CV_TO_GL}


def misread_intrinsics(camera: Camera) -> dict[str, np.ndarray]:
    """The (3, 3) intrinsics meant by ``camera``'s, had its file been written wrong in the common ways
    (capture.depth_agreement.intrinsics_check): ``image size`` (fl_x, fl_y, cx, cy of an image of another size:
    all of them scaled so that the principal point comes to the image's centre; left out when that scale is
    within 10 % of 1, or cx is not positive), ``centre`` (the principal point at the image's centre, the focal
    lengths kept)."""
    K = camera.K
    half = np.array([camera.width, camera.height], np.float64) / 2.0  # the centre in corner-origin coordinates
    out = {"centre": make_K(K[0, 0], K[1, 1], *cv_from_corner(half), K[0, 1])}
    c = corner_from_cv(K[:2, 2])
    if c[0] > 0:
        k = float(half[0] / c[0])
        if abs(np.log(k)) > np.log(1.1):
            out["image size"] = make_K(K[0, 0] * k, K[1, 1] * k, *resample_pixel_coords(K[:2, 2], k), K[0, 1] * k)
    return out


def gl_rows_to_image(fb: np.ndarray) -> np.ndarray:
    """OpenGL read-back (bottom row first) -> image rows (top row first). Its own inverse."""
    return np.ascontiguousarray(fb[::-1])


def mirror_pixels(uv, shape: tuple[int, int], rows: bool, cols: bool) -> np.ndarray:
    """(..., 2) OpenCV pixels (x, y) of an (H, W) = ``shape`` image stored mirrored: y -> H - 1 - y where ``rows``
    (upside down), x -> W - 1 - x where ``cols`` (left to right); float64, a copy.  Its own inverse."""
    out = np.array(uv, np.float64, copy=True)
    if cols:
        out[..., 0] = shape[1] - 1 - out[..., 0]
    if rows:
        out[..., 1] = gl_row(out[..., 1], shape[0])
    return out


def gl_row(row, height: int):
    """Image row (top first) <-> OpenGL framebuffer row (bottom first) of an image ``height``
    rows tall: ``height - 1 - row`` (integers or arrays). Its own inverse."""
    return height - 1 - row


# ------------------------------------------------------------------ pixel centres
def corner_from_cv(uv):
    """OpenCV pixel coordinates (pixel i's centre at i) -> corner-origin ones (centre at i + 0.5:
    OpenGL window coordinates, nerfstudio / COLMAP / VCG principal points). Scalars or arrays."""
    return np.add(uv, HALF_PIXEL)


def cv_from_corner(xy):
    """Inverse of :func:`corner_from_cv`: corner-origin pixel coordinates -> OpenCV ones."""
    return np.subtract(xy, HALF_PIXEL)


def resample_pixel_coords(uv, factor: float):
    """OpenCV pixel coordinates of the same image points on a grid ``factor`` times as fine
    (edges kept: ``u' + 0.5 = factor (u + 0.5)``); ``factor = 1 / s`` maps sub-sample indices of
    an s-times supersampled image back to pixel coordinates."""
    return factor * corner_from_cv(uv) - HALF_PIXEL


# ------------------------------------------------------------------ axes
def gl_from_cv_axes() -> np.ndarray:
    """(3, 3) diagonal flipping y and z: OpenCV camera axes (y down, z forward) <-> OpenGL ones
    (y up, z back); also any frame with its y along image rows and z into the picture (a
    ChArUco board's) <-> one with y up and z out of it. Its own inverse."""
    return CV_TO_GL[:3, :3].copy()


def image_right(camera: Camera) -> np.ndarray:
    """(3,) unit world direction of increasing image column u (the camera's +x)."""
    return camera.cam_from_world[0, :3].copy()


def image_up(camera: Camera) -> np.ndarray:
    """(3,) unit world direction that points up in the image (the camera's -y: OpenCV rows go down)."""
    return -camera.cam_from_world[_IMAGE_DOWN_ROW, :3]


def image_axes(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """(right, up): :func:`image_right` and :func:`image_up`."""
    return image_right(camera), image_up(camera)


def cv_rotation_from_gl_axes(right, up, forward) -> np.ndarray:
    """(3, 3) OpenCV world -> camera rotation of a camera given OpenGL-style by the world
    directions of its image right, image up and optical axis (unit, orthogonal). ``right`` is
    negated when (right, down, forward) would be left-handed (a mirrored camera file)."""
    right, up, forward = (np.asarray(a, np.float64) for a in (right, up, forward))
    down = -up
    if np.dot(np.cross(right, down), forward) <= 0:
        right = -right
    return np.stack([right, down, forward])


def gl_ndc_depth_to_z(ndc_depth01: np.ndarray, near: float, far: float) -> np.ndarray:
    """Window depth in [0, 1] (the depth buffer) -> z-depth in metres; 1.0 (cleared) -> 0."""
    d = np.asarray(ndc_depth01, dtype=np.float64)
    zn = 2.0 * d - 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        z = 2.0 * near * far / (far + near - zn * (far - near))
    return np.where(d >= 1.0, 0.0, z)


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """(4, 4) OpenCV cam_from_world for a camera at ``eye`` looking at ``target``.

    ``up`` is the world direction that should appear upwards in the image (image y points
    down, so camera -y is aligned with it as far as possible).
    """
    eye = np.asarray(eye, dtype=np.float64)
    z = np.asarray(target, dtype=np.float64) - eye
    z /= np.linalg.norm(z)
    up = np.asarray(up, dtype=np.float64)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:  # looking along up: pick any perpendicular
        x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    out = np.eye(4)
    out[:3, :3] = R
    out[:3, 3] = -R @ eye
    return out


# ------------------------------------------------------------------ web viewer (viser)
def rotation_from_wxyz(wxyz) -> np.ndarray:
    """(3, 3) rotation matrix of the quaternion (w, x, y, z) (normalised here)."""
    q = np.asarray(wxyz, dtype=np.float64)
    n = np.linalg.norm(q)
    if q.shape != (4,) or not np.isfinite(n) or n < 1e-12:
        raise CameraError(f"expected a non-zero quaternion (w, x, y, z), got {q.tolist()}")
    w, x, y, z = q / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def camera_from_viser(wxyz, position, fov_y: float, width: int, height: int, name: str = "") -> Camera:
    """The Camera of a viser (1.x) browser client.

    viser reports a client's camera as ``wxyz``, the rotation R of ``P_world = R p_camera + t``
    with ``t = position``, in OpenCV axes (x right, y down, z forward: viser's CameraHandle), its
    vertical field of view ``fov_y`` in radians and the canvas size ``width`` x ``height`` in
    pixels.  The browser shows the server's image stretched over the whole canvas, so the
    principal point is the canvas centre and pixels are square.  No axis changes sign here.
    """
    if not 0 < fov_y < np.pi:
        raise CameraError(f"viser camera: vertical field of view must be in (0, pi) radians, got {fov_y}")
    c2w = np.eye(4)
    c2w[:3, :3] = rotation_from_wxyz(wxyz)
    c2w[:3, 3] = np.asarray(position, dtype=np.float64)
    f = 0.5 * height / np.tan(0.5 * fov_y)
    K = make_K(f, f, cv_from_corner(0.5 * width), cv_from_corner(0.5 * height))
    return Camera(K, invert_rigid(check_rigid(c2w, "viser camera")), int(width), int(height), name)


def viser_view(camera: Camera, distance: float) -> dict:
    """Where a viser client's camera goes to look through ``camera``: ``position`` (its centre),
    ``look_at`` (``distance`` metres along its optical axis), ``up_direction`` (the world
    direction up in its image) and ``fov`` (its vertical field of view, radians)."""
    up = image_up(camera)
    fov = 2.0 * np.arctan(0.5 * camera.height / camera.K[1, 1])
    return {"position": camera.center, "look_at": camera.center + float(distance) * camera.forward,
            "up_direction": up, "fov": float(fov)}
