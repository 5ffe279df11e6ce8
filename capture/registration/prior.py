"""The input poses' stated uncertainty (issue 31): no view moves further from its input pose
than the input's uncertainty says it can be wrong, unless the user asks for a global search
(``--init none``).

A :class:`PosePrior` is a bound: the largest rotation (degrees) and the largest translation (a
fraction of the camera's distance to the object) by which an input pose may be wrong.  The
rotation part bounds the camera's turn; the translation part bounds what its centre moves besides
that turn, about its own centre or about the object centre, whichever explains more (a turn of A
degrees about the object moves the camera centre by about A x distance, and that part is the
rotation's; a phone's pose error turns the camera about itself).  The solvers use it twice:

* as a prior term (a Gaussian of standard deviation ``bound / BOUND_SIGMAS`` about the input,
  ``angle_system``) and a bounded search (every step clamped to the bound, ``clamp_angles``), so
  that an estimate the evidence does not determine stays where the input put it;
* as a final test (:func:`move`): a view whose registered pose is further from its input than the
  bound keeps its input pose, and the report says so with both numbers.

Defaults per rig (``default_prior``; ``--pose-prior DEG,FRACTION`` replaces them):

* ``turntable``: from the input itself: ``BOUND_SIGMAS`` times the scatter of the input poses
  about the fitted ring (their median deviation, per axis), at least ``TURNTABLE_FLOOR``;
* ``free`` (ICP + pose graph from the input poses): ``FREE_DEFAULT``;
* ``board`` / ``colmap``: the board's PnP poses or the SfM poses are the input of the refinement:
  ``BOARD_DEFAULT`` / ``SFM_DEFAULT`` about them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from capture.camera import invert_rigid
from capture.registration.report import rotation_angle_deg

#: The bound is this many standard deviations of the prior term (a Gaussian about the input).
BOUND_SIGMAS = 3.5
#: Rayleigh median over sigma: the median off-ring deviation (two axes) of input poses with per-axis
#: rotation error sigma is ``RAYLEIGH_MEDIAN`` sigma.
RAYLEIGH_MEDIAN = math.sqrt(2 * math.log(2))
#: The turntable's default is never tighter than this (degrees, fraction of distance).
TURNTABLE_FLOOR = (1.0, 0.01)
#: Default bound of the free rig (ICP from the input poses): degrees, fraction of distance.
FREE_DEFAULT = (10.0, 0.10)
#: Default bound about the board's PnP poses (``--method board``).
BOARD_DEFAULT = (3.0, 0.03)
#: Default bound about the SfM poses (``--method colmap``).
SFM_DEFAULT = (5.0, 0.05)


@dataclass(frozen=True)
class PosePrior:
    """How far an input pose may be wrong.

    Attributes:
        rot_deg: largest rotation error (degrees): the bound on a view's turn about the object.
        trans_frac: largest translation error besides that turn, as a fraction of the camera's
            distance to the object centre.
        source: where the numbers come from (``--pose-prior``, or the rig's default and why).
    """

    rot_deg: float
    trans_frac: float
    source: str = "--pose-prior"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.rot_deg) and self.rot_deg > 0 and math.isfinite(self.trans_frac)
                and self.trans_frac > 0):
            raise ValueError(f"a pose prior needs a positive rotation and translation, got "
                             f"{self.rot_deg}, {self.trans_frac}")

    @property
    def sigma_rad(self) -> float:
        """Standard deviation of the rotation prior term (radians)."""
        return math.radians(self.rot_deg) / BOUND_SIGMAS

    def to_json(self) -> dict:
        return {"rot_deg": round(self.rot_deg, 4), "trans_frac": round(self.trans_frac, 5), "source": self.source}


def parse_prior(text: str) -> PosePrior:
    """``DEG,FRACTION`` (e.g. ``2,0.02``) -> PosePrior; ValueError with the reason otherwise."""
    try:
        deg, frac = (float(v) for v in text.split(","))
        return PosePrior(deg, frac, "--pose-prior")
    except ValueError as e:
        raise ValueError(f"--pose-prior {text!r}: {e}; expected DEG,FRACTION, e.g. 2,0.02") from None


def turntable_prior(deviation_deg: np.ndarray, offset_frac: np.ndarray, use: list[int]) -> PosePrior:
    """The turntable's default from the input poses' scatter about the fitted ring:
    ``BOUND_SIGMAS`` per-axis sigmas of their orientation deviation (Rayleigh median) and of their
    centres' offset from the circle (a fraction of its radius, close to one of the distance)."""
    dev = np.asarray(deviation_deg, np.float64)[use]
    off = np.asarray(offset_frac, np.float64)[use]
    sig_r = float(np.median(dev)) / RAYLEIGH_MEDIAN if len(dev) else float("nan")
    sig_t = float(np.median(off)) / RAYLEIGH_MEDIAN if len(off) else float("nan")
    rot = max(BOUND_SIGMAS * sig_r, TURNTABLE_FLOOR[0]) if math.isfinite(sig_r) else FREE_DEFAULT[0]
    trans = max(BOUND_SIGMAS * sig_t, TURNTABLE_FLOOR[1]) if math.isfinite(sig_t) else FREE_DEFAULT[1]
    return PosePrior(rot, trans, f"turntable default: {BOUND_SIGMAS:g} x the input poses' scatter about the ring "
                                 f"({sig_r:.2f} deg, {100 * sig_t:.2f} % per axis)")


def default_prior(rig: str, method: str, fit=None) -> PosePrior:
    """The default bound of a rig / method (see the module docstring); ``fit`` is the
    ``turntable.TurntableFit`` of the input poses for the turntable rig."""
    if rig == "turntable" and fit is not None:
        use = [k for k in range(len(fit.deviation_deg)) if k not in fit.off]
        return turntable_prior(fit.deviation_deg, fit.offset_frac, use)
    if method == "board":
        return PosePrior(*BOARD_DEFAULT, "default about the board's PnP poses")
    if method == "colmap":
        return PosePrior(*SFM_DEFAULT, "default about the SfM poses")
    return PosePrior(*FREE_DEFAULT, "free rig default")


def move(pose: np.ndarray, input_pose: np.ndarray, centre: np.ndarray) -> tuple[float, float]:
    """How far ``pose`` is from ``input_pose`` (cam_from_world): (rotation degrees, translation
    besides the turn, about the camera itself or about ``centre`` whichever is less, as a fraction
    of the input camera's distance to ``centre``)."""
    rot = rotation_angle_deg(pose[:3, :3] @ input_pose[:3, :3].T)
    a, b = invert_rigid(pose), invert_rigid(input_pose)
    c = np.asarray(centre, np.float64)
    dist = max(float(np.linalg.norm(b[:3, 3] - c)), 1e-12)
    # the camera turned about the centre by the orientation change: where that alone puts its centre
    turned = c + (a[:3, :3] @ b[:3, :3].T) @ (b[:3, 3] - c)
    return rot, min(float(np.linalg.norm(a[:3, 3] - turned)), float(np.linalg.norm(a[:3, 3] - b[:3, 3]))) / dist


def within(prior: PosePrior, pose: np.ndarray, input_pose: np.ndarray, centre: np.ndarray) -> tuple[bool, str]:
    """(the move from the input is within the bound, one line with the numbers)."""
    rot, trans = move(pose, input_pose, centre)
    ok = rot <= prior.rot_deg and trans <= prior.trans_frac
    text = (f"moved {rot:.2f} deg / {100 * trans:.2f} % from its input pose "
            f"({'within' if ok else 'beyond'} the stated uncertainty {prior.rot_deg:.2f} deg / "
            f"{100 * prior.trans_frac:.2f} %)")
    return ok, text
