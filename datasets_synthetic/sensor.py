"""RGB-D sensor traits for synthetic depth (issue 16 item 1, issue 14 item 1).

Real RGB-D cameras (structured light, active stereo, time of flight) deliver 16-bit depth in
millimetres whose noise grows with the square of the distance, quantised in disparity and in
the stored unit, with "flying pixels" (depths between the fore- and the background) along depth
discontinuities.  :class:`SensorModel` collects these traits; :func:`apply_sensor` applies them
to an exact z-depth image, in this order:

1. flying pixels (:func:`flying_pixels`): a pixel on a discontinuity (its 3 x 3 neighbourhood
   spans more than ``flying_edge_m``) takes, with probability ``flying_fraction``, a depth drawn
   uniformly between the nearest and the farthest depth of that neighbourhood (a mixed pixel);
   with ``backdrop_m`` set, empty pixels count as a backdrop at that depth, so silhouettes mix
   with it too (and empty pixels next to the object can become flying pixels);
2. z-squared noise (``noise.depth_noise``): sigma(z) = ``sigma_at_1m`` z^2 (a constant
   disparity error);
3. disparity quantisation (:func:`quantise_disparity`): 1/z rounded to steps of
   ``disparity_step_at_1m`` (the depth step is then ``disparity_step_at_1m`` z^2);
4. the sensor's output unit (``depth_unit_m``, 1 mm for the sensors below): z rounded to it.

Presets (:data:`SENSORS`): ``ideal`` (exact float depth, the old generator), ``kinect-v1``,
``d435`` (the default of ``furrow synth``).  The numbers come from the publications named at each
constant; the flying-pixel rate is a chosen value (no publication gives one per pixel).

Usage (also from registration benchmarks)::

    from datasets_synthetic.sensor import SENSORS, SensorModel, apply_sensor
    noisy = apply_sensor(depth, np.random.default_rng(0), SENSORS["d435"])
    custom = SensorModel(name="mine", sigma_at_1m=0.002, depth_unit_m=0.001)
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np
from scipy import ndimage

from datasets_synthetic.noise import depth_noise

#: Kinect v1 (structured light), Khoshelham & Elberink 2012, "Accuracy and Resolution of Kinect
#: Depth Data for Indoor Mapping Applications" (Sensors 12(2)): random error
#: sigma_Z = (m / f) Z^2 sigma_d with m / f = 2.85e-5 cm^-1 and sigma_d = 1/2 disparity unit,
#: i.e. 1.425e-3 Z^2 (metres; 3.6 cm at 5 m) ...
KINECT_V1_SIGMA_AT_1M = 1.425e-3
#: ... and a depth resolution of one disparity unit, (m / f) Z^2 = 2.85e-3 Z^2 (7 cm at 5 m).
KINECT_V1_DISPARITY_STEP_AT_1M = 2.85e-3
#: Intel RealSense D435 (active stereo), Grunnet-Jepsen et al., "Tuning Depth Cameras for Best
#: Performance" (Intel white paper, 2018): RMS error = Z^2 subpixel / (f B) with subpixel 0.08,
#: baseline B = 50 mm, f = 424 / tan(87 deg / 2) = 447 px at 848x480: 3.58e-3 Z^2 (0.66 mm at
#: the 0.43 m of the default rig).  Its disparity (1/32 px subpixel steps, 0.32e-3 Z^2) is far
#: below the 1 mm output unit, so only the unit quantises.
D435_SIGMA_AT_1M = 0.08 / ((424.0 / np.tan(np.radians(87.0 / 2))) * 0.050)
#: Output unit of both sensors (z16 depth in millimetres: librealsense depth_units, OpenNI).
SENSOR_DEPTH_UNIT_M = 1e-3
#: Probability that a pixel on a depth discontinuity reports a mixed depth.  Chosen (not
#: measured): about every third edge pixel, the density of flying pixels on object outlines in
#: unfiltered time-of-flight / stereo depth.
FLYING_FRACTION = 0.3
#: A 3 x 3 neighbourhood spanning more than this is a depth discontinuity (metres): 5 mm, above
#: the noise of both sensors at half a metre (< 1 mm) and below a strand-over-body jump (1-3 cm).
FLYING_EDGE_M = 0.005


@dataclass(frozen=True)
class SensorModel:
    """Depth-sensor traits applied to exact synthetic z-depth (metres; 0 = no measurement)."""

    name: str = "ideal"
    """Label written to gt/scene.json (a preset name or anything else)."""
    sigma_at_1m: float = 0.0
    """z-squared noise: standard deviation sigma(z) = sigma_at_1m z^2 (metres at z = 1 m)."""
    disparity_step_at_1m: float = 0.0
    """Disparity quantisation: depth step = disparity_step_at_1m z^2 (0 = off)."""
    flying_fraction: float = 0.0
    """Probability that a discontinuity pixel reports a mixed depth (0 = off)."""
    flying_edge_m: float = FLYING_EDGE_M
    """Depth span of a 3 x 3 neighbourhood above which its centre is on a discontinuity (metres)."""
    backdrop_m: float | None = None
    """Depth of a backdrop behind the object that empty pixels mix with (None = no backdrop:
    empty pixels never become flying pixels and never pull an edge pixel)."""
    depth_unit_m: float = 0.0
    """Output unit: depth rounded to multiples of it (metres; 0 = float output)."""

    def __post_init__(self) -> None:
        for k in ("sigma_at_1m", "disparity_step_at_1m", "depth_unit_m"):
            v = getattr(self, k)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"sensor {self.name!r}: {k} must be a finite number >= 0, got {v}")
        if not 0 <= self.flying_fraction <= 1:
            raise ValueError(f"sensor {self.name!r}: flying_fraction must be in [0, 1], got {self.flying_fraction}")
        if not self.flying_edge_m > 0:
            raise ValueError(f"sensor {self.name!r}: flying_edge_m must be > 0, got {self.flying_edge_m}")
        if self.backdrop_m is not None and not self.backdrop_m > 0:
            raise ValueError(f"sensor {self.name!r}: backdrop_m must be > 0 or None, got {self.backdrop_m}")

    @property
    def is_ideal(self) -> bool:
        """True when :func:`apply_sensor` returns the depth unchanged."""
        return (self.sigma_at_1m == 0 and self.disparity_step_at_1m == 0 and self.flying_fraction == 0
                and self.depth_unit_m == 0)

    def to_json(self) -> dict:
        return asdict(self)


#: The presets of ``furrow synth --sensor``.
SENSORS: dict[str, SensorModel] = {
    "ideal": SensorModel("ideal"),
    "kinect-v1": SensorModel("kinect-v1", sigma_at_1m=KINECT_V1_SIGMA_AT_1M,
                             disparity_step_at_1m=KINECT_V1_DISPARITY_STEP_AT_1M,
                             flying_fraction=FLYING_FRACTION, depth_unit_m=SENSOR_DEPTH_UNIT_M),
    "d435": SensorModel("d435", sigma_at_1m=float(D435_SIGMA_AT_1M), flying_fraction=FLYING_FRACTION,
                        depth_unit_m=SENSOR_DEPTH_UNIT_M),
}
#: The sensor of ``furrow synth`` when none is named.
DEFAULT_SENSOR = "d435"


def sensor_preset(name: str, **overrides) -> SensorModel:
    """A preset of :data:`SENSORS` with fields replaced (ValueError naming the choices)."""
    if name not in SENSORS:
        raise ValueError(f"unknown sensor {name!r}: choose one of {', '.join(SENSORS)}")
    return replace(SENSORS[name], **overrides) if overrides else SENSORS[name]


def _neighbour_range(depth: np.ndarray, backdrop_m: float | None) -> tuple[np.ndarray, np.ndarray]:
    """(nearest, farthest) depth of every pixel's 3 x 3 neighbourhood (itself included); empty
    pixels are the backdrop, or ignored without one (inf / -inf where all nine are empty)."""
    valid = depth > 0
    if backdrop_m is not None:
        filled = np.where(valid, depth, backdrop_m).astype(np.float64)
        return (ndimage.minimum_filter(filled, 3, mode="nearest"),
                ndimage.maximum_filter(filled, 3, mode="nearest"))
    lo = ndimage.minimum_filter(np.where(valid, depth, np.inf).astype(np.float64), 3, mode="nearest")
    hi = ndimage.maximum_filter(np.where(valid, depth, -np.inf).astype(np.float64), 3, mode="nearest")
    return lo, hi


def discontinuity_mask(depth: np.ndarray, edge_m: float, backdrop_m: float | None = None) -> np.ndarray:
    """(H, W) bool: pixels whose 3 x 3 neighbourhood spans more than ``edge_m`` metres (empty
    pixels take part only with a backdrop; without one only measured pixels are candidates)."""
    d = np.asarray(depth, np.float64)
    lo, hi = _neighbour_range(d, backdrop_m)
    span = np.where(np.isfinite(lo) & np.isfinite(hi), hi - lo, 0.0)
    cand = (d > 0) | (backdrop_m is not None)
    return cand & (span > edge_m)


def flying_pixels(depth: np.ndarray, rng: np.random.Generator, fraction: float, edge_m: float,
                  backdrop_m: float | None = None) -> np.ndarray:
    """Depth where a ``fraction`` of the discontinuity pixels (:func:`discontinuity_mask`) report
    a depth uniform between the nearest and the farthest of their 3 x 3 neighbourhood."""
    d = np.asarray(depth, np.float32)
    out = d.copy()
    if fraction <= 0:
        return out
    lo, hi = _neighbour_range(d.astype(np.float64), backdrop_m)
    edge = discontinuity_mask(d, edge_m, backdrop_m)
    u = rng.uniform(size=d.shape)
    t = rng.uniform(size=d.shape)
    fly = edge & (u < fraction)  # edge pixels have finite lo and hi
    out[fly] = (lo[fly] + t[fly] * (hi[fly] - lo[fly])).astype(np.float32)
    return out


def quantise_disparity(depth: np.ndarray, step_at_1m: float) -> np.ndarray:
    """Depth with 1/z rounded to multiples of ``step_at_1m`` (depth step = step_at_1m z^2)."""
    d = np.asarray(depth, np.float64)
    if step_at_1m <= 0:
        return d.astype(np.float32)
    valid = d > 0
    k = np.round(1.0 / (step_at_1m * np.where(valid, d, 1.0)))
    k = np.maximum(k, 1.0)
    return np.where(valid, 1.0 / (step_at_1m * k), 0.0).astype(np.float32)


def quantise_unit(depth: np.ndarray, unit_m: float) -> np.ndarray:
    """Depth rounded to multiples of ``unit_m`` metres; a measurement never rounds to 0 (no data)."""
    d = np.asarray(depth, np.float64)
    if unit_m <= 0:
        return d.astype(np.float32)
    q = np.maximum(np.round(d / unit_m), 1.0) * unit_m
    return np.where(d > 0, q, 0.0).astype(np.float32)


def apply_sensor(depth: np.ndarray, rng: np.random.Generator, sensor: SensorModel) -> np.ndarray:
    """(H, W) float32 exact z-depth (metres, 0 = none) -> what ``sensor`` reports (module
    docstring: flying pixels, z^2 noise, disparity quantisation, output unit).  The input is
    untouched; the same generator state gives the same output."""
    d = np.asarray(depth, np.float32)
    if sensor.is_ideal:
        return d.copy()
    d = flying_pixels(d, rng, sensor.flying_fraction, sensor.flying_edge_m, sensor.backdrop_m)
    if sensor.sigma_at_1m > 0:
        d = depth_noise(d, rng, sensor.sigma_at_1m)
    d = quantise_disparity(d, sensor.disparity_step_at_1m)
    return quantise_unit(d, sensor.depth_unit_m)
