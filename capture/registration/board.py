"""Camera poses from a ChArUco board (opencv-contrib ``cv2.aruco``) by PnP (issue 4 item 3).

The board lies flat under the object, printed side up (+z world).  Board frame (OpenCV
ChArUco): origin at the board's top-left outer corner, x along the ``squares_x`` direction,
y along ``squares_y``, z into the board.  It maps to the world as x_b -> +x, y_b -> -y,
z_b -> -z, centred on the world origin at height ``z_m``; the board therefore fixes the
gauge (world frame) itself, no scan needs to.

Per image: ChArUco corners (OpenCV pixel centres at integers, as ``Camera.K``), then
``solvePnP`` (iterative) + Levenberg-Marquardt refinement with the known intrinsics; an image
with fewer than ``MIN_CORNERS`` corners, or a reprojection RMS above ``MAX_REPROJ_PX``,
gets no board pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.scan import ScanSet

#: Minimum ChArUco corners for a pose.
MIN_CORNERS = 6
#: Maximum RMS reprojection error (pixels) of an accepted board pose.
MAX_REPROJ_PX = 2.0


@dataclass(frozen=True)
class BoardSpec:
    """A ChArUco board."""

    squares_x: int = 7
    """Squares along the board's x."""
    squares_y: int = 7
    """Squares along the board's y."""
    square_m: float = 0.05
    """Side of a chessboard square (metres)."""
    marker_m: float = 0.037
    """Side of an ArUco marker (metres)."""
    dictionary: str = "DICT_4X4_50"
    """Predefined ArUco dictionary name (``cv2.aruco.<name>``)."""
    z_m: float = -0.13
    """Height of the board plane in the world (metres; below the object)."""

    def __post_init__(self) -> None:
        if self.squares_x < 3 or self.squares_y < 3:
            raise ValueError("BoardSpec: need at least 3x3 squares")
        if not 0 < self.marker_m < self.square_m:
            raise ValueError("BoardSpec: need 0 < marker_m < square_m")

    @property
    def size_m(self) -> tuple[float, float]:
        return self.squares_x * self.square_m, self.squares_y * self.square_m

    def cv_board(self):
        import cv2

        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.squares_x, self.squares_y), self.square_m, self.marker_m, d)

    def world_from_board(self) -> np.ndarray:
        """(4, 4) board frame -> world."""
        w, h = self.size_m
        M = np.eye(4)
        M[:3, :3] = np.diag([1.0, -1.0, -1.0])
        M[:3, 3] = [-w / 2, h / 2, self.z_m]
        return M

    def image(self, px_per_square: int = 40):
        """(H, W) uint8 board image, no margin: pixel (i, j) covers board [i, i+1) x [j, j+1) / px_per_m."""
        w = self.squares_x * px_per_square
        h = self.squares_y * px_per_square
        return self.cv_board().generateImage((w, h), marginSize=0, borderBits=1)


@dataclass
class BoardResult:
    """Board poses of a scan set."""

    poses: list  # cam_from_world (4, 4) or None per scan
    corners: list[int]  # ChArUco corners found per scan
    reprojection_px: list[float]  # RMS reprojection per scan (nan without a pose)

    @property
    def median_reprojection_px(self) -> float:
        r = [x for x in self.reprojection_px if np.isfinite(x)]
        return float(np.median(r)) if r else float("nan")


def detect_pose(gray: np.ndarray, K: np.ndarray, spec: BoardSpec) -> tuple[np.ndarray | None, int, float]:
    """(cam_from_board (4, 4) or None, corners found, RMS reprojection px) for one 8-bit image."""
    import cv2

    board = spec.cv_board()
    det = cv2.aruco.CharucoDetector(board)
    ch_corners, ch_ids, _, _ = det.detectBoard(gray)
    n = 0 if ch_ids is None else len(ch_ids)
    if n < MIN_CORNERS:
        return None, n, float("nan")
    obj, img = board.matchImagePoints(ch_corners, ch_ids)
    obj = obj.reshape(-1, 3).astype(np.float64)
    img = img.reshape(-1, 2).astype(np.float64)
    if board.checkCharucoCornersCollinear(ch_ids):
        return None, n, float("nan")
    ok, rvec, tvec = cv2.solvePnP(obj, img, K, None, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        return None, n, float("nan")
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, None, rvec, tvec)
    proj, _ = cv2.projectPoints(obj, rvec, tvec, K, None)
    rms = float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1))))
    if rms > MAX_REPROJ_PX:
        return None, n, rms
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(rvec)[0]
    T[:3, 3] = tvec.ravel()
    return T, n, rms


def board_poses(scanset: ScanSet, spec: BoardSpec | None = None) -> BoardResult:
    """Board-based cam_from_world of every scan (None where the board is not usable)."""
    import cv2

    spec = spec or BoardSpec()
    bfw = np.linalg.inv(spec.world_from_board())
    poses, corners, rms = [], [], []
    for s in scanset.scans:
        gray = cv2.cvtColor(np.ascontiguousarray(s.srgb8), cv2.COLOR_RGB2GRAY)
        T, n, r = detect_pose(gray, s.camera.K, spec)
        poses.append(None if T is None else T @ bfw)
        corners.append(n)
        rms.append(r)
    return BoardResult(poses, corners, rms)


def board_texture_fn(spec: BoardSpec, px_per_square: int = 40):
    """``f(points (N, 3) world) -> (N, 3)`` linear colour of the board plane (nearest board
    pixel; white outside the board) for ray-cast or rasterised synthetic scenes."""
    img = spec.image(px_per_square).astype(np.float32) / 255.0
    bfw = np.linalg.inv(spec.world_from_board())
    ppm = px_per_square / spec.square_m

    def fn(p: np.ndarray) -> np.ndarray:
        q = np.asarray(p, dtype=np.float64) @ bfw[:3, :3].T + bfw[:3, 3]
        i = np.floor(q[:, 0] * ppm).astype(np.int64)
        j = np.floor(q[:, 1] * ppm).astype(np.int64)
        inside = (i >= 0) & (i < img.shape[1]) & (j >= 0) & (j < img.shape[0])
        v = np.ones(len(q), dtype=np.float32)
        v[inside] = img[j[inside], i[inside]]
        lin = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)
        return np.repeat(lin[:, None], 3, axis=1)

    return fn
