"""The turntable prior: every camera on one circle about one axis (issue 16).

A turntable turns the object in front of a fixed camera; in the object's frame the cameras
are one camera rotated about the turntable's axis by one angle per view.  So, with the
reference view ``r``'s pose ``P_r`` (cam_from_world),

    cam_k_from_world = P_r @ Rot(axis, theta_r - theta_k)

and the relative pose of two views is ``cam_i_from_cam_j = P_r Rot(axis, theta_j - theta_i) P_r^-1``:
it depends only on the axis (a line: 4 numbers) and the angle differences, never on ``P_r``
(which is the gauge).  The unknowns are therefore 4 + (N - 1) numbers instead of 6 (N - 1).

:func:`fit_turntable` reads the model off the nominal poses (the axis as the direction that is
the same in every camera frame, the axis point from a circle fit to the camera centres, the
angles from each view's orientation about it) and says whether the poses describe a turntable
at all (``rig auto``); views whose nominal pose is far off the circle are named.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from capture.camera import invert_rigid
from capture.registration.perturb import rotation

#: A nominal view whose orientation differs from the turntable model by more than this (degrees)
#: is off the turntable: its nominal pose is wrong (flagged by name, never placed).
MAX_VIEW_DEVIATION_DEG = 20.0
#: ... or whose camera centre is further than this fraction of the circle's radius from it (the
#: nominal pose only starts the view's angle: 10 degree / 10 % perturbations put centres up to
#: 0.29 of the radius off the circle of the 36-view plant, and those views are placed).
MAX_VIEW_OFFSET_FRAC = 0.5
#: ``rig auto`` takes the poses for a turntable when at least this fraction of the views is on it ...
MIN_ON_FRACTION = 0.75
#: ... there are at least this many views ...
MIN_VIEWS = 6
#: ... and they span at least this many degrees about the axis.
MIN_SPAN_DEG = 60.0
#: Alternations of the mean ring orientation and the view angles.
ANGLE_ITERATIONS = 3
#: Neighbouring views (in angle) further apart than this are not paired.
MAX_GAP_DEG = 75.0
#: Finite-difference step of the pair-twist Jacobians (radians and metres / object size).
FD_STEP = 1e-6
#: The axis prior (issue 22): the ring of nominal poses fixes the axis against the cameras to about
#: their median deviation over the square root of their number (``turntable.fit_turntable``); the
#: evidence moves it only as far as its information outweighs that.  On a fur ball the axis is
#: what the evidence determines worst.  Synthetic fur ball, 24 views, 320x240, 2 degrees input:
#: median-filtered depth gave the surface term fitness 0.56 instead of 0.07 but tilted the axis by
#: 4 degrees (every view 4 degrees off, with or without the prior: its information outweighed it;
#: hence ``AXIS_AGREE_SIGMAS``), and with the axis held put the angles 0.7-6.3 degrees off: the
#: coat's apparent surface moves with the view.  On the raw depth the prior changed little there
#: (8 views placed at 0.16 / 0.46 degrees median / max without, 7 at 0.17 / 0.49 with).
#: The prior's tilt sigma is never below this (degrees) ...
AXIS_PRIOR_FLOOR_DEG = 0.05
#: ... and its shift sigma is this fraction of the object size per degree of tilt sigma (a
#: perturbation of D degrees comes with D % of the size in the benches and on phones alike).
AXIS_SHIFT_FRAC_PER_DEG = 0.01


def rotation_about_line(axis: np.ndarray, point: np.ndarray, angle: float) -> np.ndarray:
    """(4, 4) rigid rotation by ``angle`` (radians) about the line through ``point`` along ``axis``."""
    M = np.eye(4)
    M[:3, :3] = rotation(axis, angle)
    M[:3, 3] = point - M[:3, :3] @ point
    return M


def _perp_basis(a: np.ndarray) -> np.ndarray:
    """(2, 3) orthonormal basis of the plane perpendicular to unit ``a``."""
    e = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    b1 = np.cross(a, e)
    b1 /= np.linalg.norm(b1)
    return np.stack([b1, np.cross(a, b1)])


@dataclass(frozen=True)
class Turntable:
    """A turntable model of a scan set (world = the nominal poses' frame, metres, radians).

    Attributes:
        axis: (3,) unit axis direction (world).
        point: (3,) a point on the axis (world), perpendicular foot of the reference camera centre.
        reference: index of the reference view (its angle is fixed).
        reference_pose: (4, 4) cam_from_world of the reference view (the gauge).
        angles: (N,) angle of every view (radians; NaN for a view off the turntable).
        radius: distance of the camera centres from the axis (metres).
    """

    axis: np.ndarray
    point: np.ndarray
    reference: int
    reference_pose: np.ndarray
    angles: np.ndarray
    radius: float

    def __post_init__(self) -> None:
        a = np.asarray(self.axis, np.float64)
        if a.shape != (3,) or not np.isfinite(a).all() or abs(np.linalg.norm(a) - 1) > 1e-6:
            raise ValueError(f"Turntable.axis must be a unit 3-vector, got {self.axis}")
        if np.asarray(self.reference_pose).shape != (4, 4):
            raise ValueError("Turntable.reference_pose must be 4x4")
        if not 0 <= self.reference < len(self.angles) or not math.isfinite(self.angles[self.reference]):
            raise ValueError(f"Turntable.reference {self.reference} must index a view on the turntable")

    def pose(self, k: int) -> np.ndarray:
        """cam_from_world of view ``k`` under the model."""
        d = self.angles[self.reference] - self.angles[k]
        return self.reference_pose @ rotation_about_line(self.axis, self.point, d)

    def relative(self, i: int, j: int) -> np.ndarray:
        """cam_i_from_cam_j under the model."""
        return self.pose(i) @ invert_rigid(self.pose(j))

    # ------------------------------------------------------------------ parameters
    def params(self) -> np.ndarray:
        """Axis offsets (2 + 2, zero here: the update is relative) followed by every angle."""
        return np.concatenate([np.zeros(4), self.angles])

    def updated(self, dx: np.ndarray, scale: float) -> Turntable:
        """The model moved by ``dx`` = (axis tilt (2, radians), axis shift (2, in units of
        ``scale`` metres), angle changes (N))."""
        B = _perp_basis(self.axis)
        a = self.axis + dx[0] * B[0] + dx[1] * B[1]
        a /= np.linalg.norm(a)
        p = self.point + scale * (dx[2] * B[0] + dx[3] * B[1])
        return replace(self, axis=a, point=p, angles=self.angles + dx[4:])

    def pair_jacobian(self, i: int, j: int, scale: float) -> np.ndarray:
        """(6, 5) d twist(cam_i_from_cam_j) / d (tilt 2, shift 2, theta_j - theta_i): the left
        twist (w, t) of the pair transform, by finite differences."""
        T = self.relative(i, j)
        Ti = invert_rigid(T)
        J = np.zeros((6, 5))
        for c in range(5):
            dx = np.zeros(4 + len(self.angles))
            if c < 4:
                dx[c] = FD_STEP
            else:
                dx[4 + j] = FD_STEP
            D = self.updated(dx, scale).relative(i, j) @ Ti
            J[:3, c] = 0.5 * np.array([D[2, 1] - D[1, 2], D[0, 2] - D[2, 0], D[1, 0] - D[0, 1]]) / FD_STEP
            J[3:, c] = D[:3, 3] / FD_STEP
        return J


@dataclass(frozen=True)
class TurntableFit:
    """What the nominal poses say about a turntable."""

    model: Turntable | None
    """The fitted model (None when the poses do not allow one)."""
    is_turntable: bool
    """The poses describe a turntable (``rig auto`` uses the prior)."""
    off: dict
    """View index -> reason, for the views whose nominal pose is off the turntable."""
    deviation_deg: np.ndarray
    """(N,) orientation deviation of every nominal pose from the model (degrees)."""
    offset_frac: np.ndarray
    """(N,) distance of every camera centre from the circle, as a fraction of its radius."""
    reason: str
    """One line: why the poses are, or are not, a turntable."""
    axis_sigma_deg: float = float("nan")
    """Uncertainty of the axis against the cameras from the nominal poses (degrees): their median
    deviation from the ring over the square root of their number (the model's reference pose is
    the ring's, ``_ring_pose``, so every view's error averages in)."""


def _axis_in_cameras(R: list[np.ndarray]) -> np.ndarray:
    """World axis a that maps to the same direction in every camera frame: maximises
    a^T (sum R_k^T) b over unit a, b."""
    U, _, Vt = np.linalg.svd(sum(r.T for r in R))
    return U[:, 0]


def _circle_centre(c: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre (on the plane through the centres' mean, perpendicular to ``a``) and radius of the
    circle best fitting the camera centres ``c`` (N, 3) projected on that plane (Kasa fit)."""
    B = _perp_basis(a)
    m = c.mean(axis=0)
    xy = (c - m) @ B.T
    A = np.concatenate([2 * xy, np.ones((len(xy), 1))], axis=1)
    sol, *_ = np.linalg.lstsq(A, np.sum(xy**2, axis=1), rcond=None)
    centre = m + sol[0] * B[0] + sol[1] * B[1]
    return centre, float(np.sqrt(max(sol[2] + sol[0] ** 2 + sol[1] ** 2, 0.0)))


def _angles_and_deviation(poses, a, o, use):
    """Per view: the angle about (a, o) that best matches its orientation to the mean camera
    orientation relative to the turntable, and its deviation (degrees) from it."""
    B = _perp_basis(a)
    W_from_A = np.eye(4)
    W_from_A[:3, :3] = np.stack([B[0], B[1], a], axis=1)
    W_from_A[:3, 3] = o
    CA = [p @ W_from_A for p in poses]  # cam_k_from_A
    centres = [invert_rigid(p)[:3, 3] - o for p in poses]
    theta = np.array([math.atan2(c @ B[1], c @ B[0]) for c in centres])
    for _ in range(ANGLE_ITERATIONS):
        Rc = sum(CA[k][:3, :3] @ rotation([0, 0, 1], theta[k])[:3, :3] for k in use)
        U, _, Vt = np.linalg.svd(Rc)
        Rc = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
        for k in range(len(poses)):
            M = Rc.T @ CA[k][:3, :3]
            theta[k] = math.atan2(M[0, 1] - M[1, 0], M[0, 0] + M[1, 1])
    dev = np.array([np.degrees(np.arccos(np.clip((np.trace(Rc.T @ CA[k][:3, :3] @ rotation([0, 0, 1], theta[k]))
                                                   - 1) / 2, -1, 1))) for k in range(len(poses))])
    return theta, dev, (Rc, W_from_A, CA)


def _ring_pose(ring, theta: np.ndarray, use: list[int], k: int) -> np.ndarray:
    """cam_from_world of view ``k`` on the ring that best fits all the ``use`` views at once: the
    mean orientation relative to the turntable (``Rc``) turned by its angle, at the mean camera
    centre turned likewise.  Its tilt against the axis is the mean of all the views' (error
    shrinking with their number), not the tilt of one nominal pose."""
    Rc, W_from_A, CA = ring
    Rz = [rotation([0, 0, 1], theta[j])[:3, :3] for j in range(len(theta))]
    c0 = np.mean([Rz[j].T @ invert_rigid(CA[j])[:3, 3] for j in use], axis=0)
    M = np.eye(4)
    M[:3, :3] = Rc @ Rz[k].T
    M[:3, 3] = -Rc @ c0
    return M @ invert_rigid(W_from_A)


def fit_turntable(poses: list[np.ndarray]) -> TurntableFit:
    """Fit a turntable to nominal cam_from_world poses (robustly: views off it are left out
    and named); ``is_turntable`` answers ``rig auto``."""
    n = len(poses)
    poses = [np.asarray(p, np.float64) for p in poses]
    centres = np.array([invert_rigid(p)[:3, 3] for p in poses])
    use = list(range(n))
    off: dict = {}
    for _ in range(4):
        if len(use) < 3:
            return TurntableFit(None, False, off, np.full(n, np.nan), np.full(n, np.nan),
                                f"only {len(use)} views agree on a turntable")
        a = _axis_in_cameras([poses[k][:3, :3] for k in use])
        o, rho = _circle_centre(centres[use], a)
        theta, dev, ring = _angles_and_deviation(poses, a, o, use)
        rel = centres - o
        dist = np.linalg.norm(rel - np.outer(rel @ a, a), axis=1)
        height = rel @ a
        h0 = np.median(height[use])
        offset = np.hypot(dist - rho, height - h0) / max(rho, 1e-12)
        off = {k: (f"nominal pose {dev[k]:.1f} degrees off the turntable" if dev[k] > MAX_VIEW_DEVIATION_DEG else
                   f"camera centre {offset[k]:.0%} of the radius off the turntable circle")
               for k in range(n) if dev[k] > MAX_VIEW_DEVIATION_DEG or offset[k] > MAX_VIEW_OFFSET_FRAC}
        new = [k for k in range(n) if k not in off]
        if new == use:
            break
        use = new
    ref = use[0] if use else 0
    # the axis point level with the reference camera, its angle as the reference angle
    o = o + a * height[ref]
    ang = np.where([k in off for k in range(n)], np.nan, theta)
    span = _span_deg(ang[use])
    frac = len(use) / n
    ok = n >= MIN_VIEWS and frac >= MIN_ON_FRACTION and span >= MIN_SPAN_DEG
    reason = (f"{len(use)}/{n} nominal poses on one circle (radius {rho:.3f} m) about one axis, spanning "
              f"{span:.0f} degrees, median deviation {np.median(dev[use]):.1f} degrees")
    if not ok:
        reason = "not a turntable: " + reason
    ref_pose = _ring_pose(ring, theta, use, ref) if use else poses[ref]
    model = Turntable(a, o, ref, ref_pose, ang, rho)
    axis_sigma = float(np.median(dev[use])) / math.sqrt(len(use)) if use else float("nan")
    return TurntableFit(model, ok, off, dev, offset, reason, axis_sigma)


def _span_deg(theta: np.ndarray) -> float:
    """Angular extent (degrees) covered by the angles: 360 minus the largest gap."""
    t = np.sort(np.mod(theta[np.isfinite(theta)], 2 * np.pi))
    if len(t) < 2:
        return 0.0
    gaps = np.diff(np.concatenate([t, t[:1] + 2 * np.pi]))
    return float(np.degrees(2 * np.pi - gaps.max()))


@dataclass(frozen=True)
class AxisPrior:
    """The nominal ring's axis as a measurement: ``start``'s axis and point, with standard
    deviations ``tilt_rad`` (radians) and ``shift_frac`` (fraction of the object size)."""

    start: Turntable
    tilt_rad: float
    shift_frac: float

    def system(self, model: Turntable, size: float) -> tuple[np.ndarray, np.ndarray]:
        """(W 4x4, b 4): the prior's normal equations in the axis offsets of ``model``."""
        off = self.offsets(model, size)
        W = np.diag([self.tilt_rad ** -2] * 2 + [self.shift_frac ** -2] * 2)
        return W, -W @ off

    def offsets(self, model: Turntable, size: float) -> np.ndarray:
        """(4,) the axis offsets of ``model`` from the prior's (tilt radians 2, shift / size 2)."""
        B = _perp_basis(self.start.axis)
        da = model.axis - self.start.axis
        dp = (model.point - self.start.point) / size
        return np.array([da @ B[0], da @ B[1], dp @ B[0], dp @ B[1]])

    def sigmas(self, model: Turntable, size: float) -> float:
        """How far ``model``'s axis is from the prior's, in prior sigmas (the larger of tilt and shift)."""
        o = self.offsets(model, size)
        return float(max(np.hypot(o[0], o[1]) / self.tilt_rad, np.hypot(o[2], o[3]) / self.shift_frac))

    def tilt_deg(self, model: Turntable) -> float:
        """Angle (degrees) between ``model``'s axis and the prior's."""
        return math.degrees(math.acos(float(np.clip(model.axis @ self.start.axis, -1, 1))))


def axis_prior(model: Turntable, sigma_deg: float | None) -> AxisPrior | None:
    """The prior of ``model``'s axis from the ring's uncertainty ``sigma_deg`` (None: no prior)."""
    if sigma_deg is None or not math.isfinite(sigma_deg):
        return None
    s = max(sigma_deg, AXIS_PRIOR_FLOOR_DEG)
    return AxisPrior(model, math.radians(s), s * AXIS_SHIFT_FRAC_PER_DEG)


def ring_pairs(model: Turntable, active: list[int], max_deg: float) -> list[tuple[int, int]]:
    """Ordered pairs (target, source) of active views within ``max_deg`` about the axis (or 1.5
    ring steps, the median gap between neighbouring angles, when wider), and every view with
    its nearest active neighbour on either side up to ``MAX_GAP_DEG`` (a view left out must not
    cut the ring in two)."""
    order = sorted(active, key=lambda k: model.angles[k] % (2 * math.pi))
    t = np.array([model.angles[k] % (2 * math.pi) for k in order])
    if len(t) > 1:
        step = float(np.median(np.diff(np.concatenate([t, t[:1] + 2 * math.pi]))))
        max_deg = max(max_deg, 1.5 * math.degrees(step))

    def gap(i, j):
        d = (model.angles[j] - model.angles[i] + math.pi) % (2 * math.pi) - math.pi
        return abs(math.degrees(d))

    out = {(i, j) for i in active for j in active if i != j and gap(i, j) <= max_deg}
    for a, b in zip(order, order[1:] + order[:1]):
        if a != b and gap(a, b) <= MAX_GAP_DEG:
            out |= {(a, b), (b, a)}
    return sorted(out)


def opposite_pairs(model: Turntable, active: list[int], tol_deg: float) -> list[tuple[int, int]]:
    """Ordered pairs of active views within ``tol_deg`` of opposite each other (180 degrees)."""
    def off(i, j):
        d = (model.angles[j] - model.angles[i]) % (2 * math.pi)
        return abs(math.degrees(d) - 180.0)

    return [(i, j) for i in active for j in active if i != j and off(i, j) <= tol_deg]


@dataclass(frozen=True)
class AnglePrior:
    """The input angles as a measurement (issue 31): view k's angle ``centre[k]`` (radians) with
    standard deviation ``sigma`` and a hard ``bound`` (radians) on its distance from it.  A shift
    common to every angle changes no pose (``Turntable.pose`` depends on angle differences): it is
    the gauge, and the bound applies to each angle's offset relative to the mean offset."""

    centre: np.ndarray
    sigma: float
    bound: float

    def shift(self, model: Turntable, active: list[int]) -> float:
        """The common offset (radians) of the ``active`` views' angles from their centres."""
        d = model.angles[active] - self.centre[active]
        return float(np.mean(d)) if len(d) else 0.0

    def offsets(self, model: Turntable, active: list[int]) -> np.ndarray:
        """(N,) every angle's offset from its centre, less the common shift (radians)."""
        return model.angles - self.centre - self.shift(model, active)

    def system(self, model: Turntable) -> tuple[np.ndarray, np.ndarray]:
        """(diagonal of H (N,), g (N,)): the prior's normal equations in the angle updates."""
        w = self.sigma ** -2
        d = np.nan_to_num(model.angles - self.centre)
        return np.full(len(d), w), -w * d

    def clamp(self, model: Turntable, active: list[int]) -> Turntable:
        """The model with every active angle's offset (less the common shift) within the bound."""
        c = self.shift(model, active)
        ang = model.angles.copy()
        a = np.asarray(active, np.int64)
        ang[a] = self.centre[a] + c + np.clip(ang[a] - self.centre[a] - c, -self.bound, self.bound)
        return replace(model, angles=ang)
