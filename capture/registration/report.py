"""Failure detection thresholds, pose error metrics and the ``registration.json`` report.

Every threshold that decides whether a registration is accepted is a named constant here,
documented with its unit.  A pair registration is *accepted* only if it passes all of them;
a scan is *flagged* (reported by name with its figures, and written at its input pose) when no
accepted, pose-graph-consistent pair connects it to the gauge scan.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from capture.camera import invert_rigid

#: Minimum fitness (fraction of the source's range pixels that land, under the estimated
#: pose, on a target range pixel within the finest depth gate with a compatible normal) for
#: an accepted pair.  Turntable neighbours 30 degrees apart overlap by 0.6-0.8, 60 degrees
#: apart by about 0.35; a different object or a diverged ICP lands well below.
MIN_FITNESS = 0.25
#: Maximum point-to-plane inlier RMSE of an accepted pair, as a fraction of object size
#: (0.2 % = 0.6 mm on a 0.3 m object: several times the depth noise of a structured-light scanner).
MAX_RMSE_FRAC = 0.002
#: ICP from an initial guess may move the relative pose by at most this much (degrees) ...
MAX_CORRECTION_DEG = 30.0
#: ... and this fraction of the object size (bounds diagonal) at the object centre;
#: a larger jump is a diverged ICP and is never accepted.
MAX_CORRECTION_FRAC = 0.3
#: After the pose-graph optimisation an edge whose measured relative pose disagrees with the
#: optimised poses by more than this (degrees) ...
MAX_EDGE_RESIDUAL_DEG = 1.0
#: ... or this fraction of object size at the object centre is inconsistent and is removed.
MAX_EDGE_RESIDUAL_FRAC = 0.01

#: Maximum RMS chromaticity difference (projective/chroma in ``projective.py``) of an accepted
#: pair when the colour term is on.  Measured on the glossy synthetic torus: correct pairs
#: 0.03-0.06, pairs slid along its symmetry 0.10-0.13.
MAX_COLOR_RMSE = 0.08
#: Before the pose graph, an edge that disagrees by more than this (degrees) ...
MAX_TRIANGLE_DEG = 3.0
#: ... or this fraction of object size with every two-edge path through better-fitting edges
#: (and agrees with none) is inconsistent.  Looser than the edge residual: two measured
#: edges add their errors.
MAX_TRIANGLE_FRAC = 0.02


def rotation_angle_deg(R: np.ndarray) -> float:
    """Angle (degrees) of a (3, 3) rotation matrix."""
    c = (np.trace(np.asarray(R)[:3, :3]) - 1.0) / 2.0
    return math.degrees(math.acos(float(np.clip(c, -1.0, 1.0))))


def transform_delta(a: np.ndarray, b: np.ndarray, center: np.ndarray) -> tuple[float, float]:
    """Difference of two (4, 4) rigid maps of the same frames: (rotation degrees,
    displacement in metres of ``center`` (in the maps' source frame))."""
    d = a @ invert_rigid(b)
    c = np.asarray(center, dtype=np.float64)
    disp = np.linalg.norm((a[:3, :3] @ c + a[:3, 3]) - (b[:3, :3] @ c + b[:3, 3]))
    return rotation_angle_deg(d[:3, :3]), float(disp)


def align_gauge(est: list[np.ndarray], gt: list[np.ndarray], gauge: int = 0) -> list[np.ndarray]:
    """Re-express estimated ``cam_from_world`` poses so that scan ``gauge`` equals its ground truth.

    est_k @ inv(est_g) @ gt_g: the rigid (gauge) freedom of the reconstruction is fixed by one scan.
    """
    g = invert_rigid(est[gauge]) @ gt[gauge]
    return [e @ g for e in est]


def fit_gauge(poses: list[np.ndarray], ref: list, mask: list[bool]) -> list[np.ndarray]:
    """Right-multiply ``poses`` (cam_from_world) by the rigid G that best maps them onto the
    reference poses where both exist (chordal mean of the rotations, mean of the translations)."""
    Gs = [invert_rigid(p) @ r for p, r, m in zip(poses, ref, mask) if m and r is not None]
    if not Gs:
        return poses
    U, _, Vt = np.linalg.svd(sum(G[:3, :3] for G in Gs))
    G = np.eye(4)
    G[:3, :3] = U @ np.diag([1, 1, np.sign(np.linalg.det(U @ Vt))]) @ Vt
    G[:3, 3] = np.mean([g[:3, 3] for g in Gs], axis=0)
    return [p @ G for p in poses]


def pose_errors(est: list[np.ndarray], gt: list[np.ndarray], center: np.ndarray, gauge: int | None = 0) -> dict:
    """Rotation (degrees) and translation (metres) errors of ``cam_from_world`` poses after aligning
    the gauge scan (``gauge`` index, left out of the figures), or, with ``gauge=None``, after the
    rigid transform that best fits all poses to the truth (``fit_gauge``).  Translation error = how
    far the object centre lands from where ground truth puts it in camera coordinates (independent
    of the camera distance, unlike camera-centre error)."""
    al = fit_gauge(est, gt, [True] * len(est)) if gauge is None else align_gauge(est, gt, gauge)
    rot, trans = [], []
    for i, (e, t) in enumerate(zip(al, gt)):
        if i == gauge:
            continue
        r, d = transform_delta(e, t, center)
        rot.append(r)
        trans.append(d)
    rot_a, tr_a = np.array(rot or [0.0]), np.array(trans or [0.0])
    return {
        "rot_median_deg": float(np.median(rot_a)),
        "rot_max_deg": float(rot_a.max()),
        "trans_median_m": float(np.median(tr_a)),
        "trans_max_m": float(tr_a.max()),
        "rot_deg": [float(x) for x in rot],
        "trans_m": [float(x) for x in trans],
    }


@dataclass
class PairRecord:
    """One pair registration, as reported."""

    source: str
    target: str
    method: str
    status: str  # "ok", "low_fitness", "high_rmse", "color_mismatch", "diverged", "inconsistent"
    fitness: float = 0.0
    inlier_rmse_m: float = float("nan")
    correction_deg: float = float("nan")
    residual_deg: float = float("nan")
    residual_m: float = float("nan")


@dataclass
class ScanRecord:
    """One scan, as reported."""

    name: str
    registered: bool
    reason: str = ""
    best_fitness: float = 0.0
    best_inlier_rmse_m: float = float("nan")
    max_residual_deg: float = float("nan")
    max_residual_m: float = float("nan")
    pairs_ok: int = 0
    evidence: list = field(default_factory=list)
    """What placed it: any of "geometry", "colour", "silhouette", "features", "board"."""
    residuals: dict = field(default_factory=dict)
    """Per evidence: its residual figures against the scan's neighbours."""
    angle_sigma_deg: float = float("nan")
    """Turntable rig: standard deviation of its angle (degrees) from the inverse information."""
    status: str = ""
    """"registered" (the output holds its registered pose), "kept at input" (the output holds its
    input pose: the evidence could not beat it, see ``reason``) or "flagged" (kept at its input
    pose, and the registration found it wrong: a foreign object, off the rig, no accepted pair)."""
    check: dict = field(default_factory=dict)
    """The independent check's comparison of its registered and input pose (``verify.ViewVerdict``)."""
    angle: dict = field(default_factory=dict)
    """Turntable rig: where its angle comes from, the evidence or its input, with the hypotheses
    that fit within noise (``angles.AngleDecision``)."""
    move: dict = field(default_factory=dict)
    """How far its registered pose is from its input pose, against the stated uncertainty
    (``prior.move``): rot_deg, trans_frac, within."""


@dataclass
class RegistrationReport:
    """The content of ``registration.json``."""

    method: str
    init: str
    gauge: str
    object_size_m: float
    thresholds: dict
    rig: str = "free"
    """"free" (a pose per scan) or "turntable" (one axis, one angle per scan)."""
    rig_detection: str = ""
    """What the nominal poses say about a turntable (``turntable.fit_turntable``)."""
    scans: list[ScanRecord] = field(default_factory=list)
    pairs: list[PairRecord] = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    check: dict = field(default_factory=dict)
    """Summary of the independent check: views per status and whether any view was improved."""
    pose_prior: dict = field(default_factory=dict)
    """The input's stated uncertainty that bounded every move (``prior.PosePrior``), or empty for a
    global search (``--init none``)."""

    @property
    def flagged(self) -> list[str]:
        return [s.name for s in self.scans if (s.status == "flagged" if s.status else not s.registered)]

    @property
    def kept(self) -> list[str]:
        """Views kept at their input pose because the evidence could not beat it (not failures)."""
        return [s.name for s in self.scans if s.status == "kept at input"]

    def to_json(self) -> dict:
        def clean(v):
            if isinstance(v, float) and not math.isfinite(v):
                return None
            if isinstance(v, dict):
                return {k: clean(x) for k, x in v.items()}
            if isinstance(v, list):
                return [clean(x) for x in v]
            return v

        d = asdict(self)
        d["flagged"] = self.flagged
        d["kept_at_input"] = self.kept
        d["n_scans"] = len(self.scans)
        d["n_registered"] = sum(s.registered for s in self.scans)
        d["n_written"] = len(self.scans)
        return clean(d)


def thresholds() -> dict:
    """The named thresholds in force, for the report."""
    return {
        "MIN_FITNESS": MIN_FITNESS,
        "MAX_RMSE_FRAC": MAX_RMSE_FRAC,
        "MAX_CORRECTION_DEG": MAX_CORRECTION_DEG,
        "MAX_CORRECTION_FRAC": MAX_CORRECTION_FRAC,
        "MAX_EDGE_RESIDUAL_DEG": MAX_EDGE_RESIDUAL_DEG,
        "MAX_EDGE_RESIDUAL_FRAC": MAX_EDGE_RESIDUAL_FRAC,
        "MAX_TRIANGLE_DEG": MAX_TRIANGLE_DEG,
        "MAX_COLOR_RMSE": MAX_COLOR_RMSE,
        "MAX_TRIANGLE_FRAC": MAX_TRIANGLE_FRAC,
    }
