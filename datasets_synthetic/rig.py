"""Turntable capture rig: rings of cameras around the world z axis looking at the origin.

Like the paper's capture (docs/methods.md §1 "Input": 36 scans every 10 degrees on a turntable, 640x480),
the default is one ring of 36 views at 10 degree steps.  Cameras are pinhole, OpenCV
convention, principal point at the image centre ((W - 1) / 2, (H - 1) / 2), built with
``capture.camera.look_at`` (world +z appears up in every image).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from capture.camera import Camera, make_K
from capture.orbit import ring_cameras


@dataclass(frozen=True)
class TurntableRig:
    """A turntable capture rig."""

    views_per_ring: int = 36
    """Views in each ring, equally spaced in azimuth."""
    elevations_deg: tuple[float, ...] = (25.0,)
    """Elevation of each ring above the xy plane (degrees)."""
    width: int = 640
    """Image width (pixels)."""
    height: int = 480
    """Image height (pixels)."""
    fov_y_deg: float = 36.0
    """Vertical field of view (degrees); square pixels."""
    fill: float = 0.9
    """Fraction of the vertical field of view covered by the object's bounding sphere (when
    ``distance`` is None)."""
    distance: float | None = None
    """Camera distance from the origin (metres); None = fit the object's bounds with ``fill``."""
    azimuth0_deg: float = 0.0
    """Azimuth of the first view of the first ring."""
    stagger: bool = True
    """Offset every other ring by half an azimuth step."""

    def __post_init__(self) -> None:
        if self.views_per_ring < 1 or not self.elevations_deg:
            raise ValueError("rig: need at least one view and one ring")
        if self.width < 8 or self.height < 8:
            raise ValueError(f"rig: image size {self.width}x{self.height} too small")
        if not 1.0 < self.fov_y_deg < 170.0:
            raise ValueError(f"rig: vertical field of view {self.fov_y_deg} degrees out of range")
        if any(abs(e) >= 89.9 for e in self.elevations_deg):
            raise ValueError("rig: ring elevations must be within (-89.9, 89.9) degrees")

    @property
    def n_views(self) -> int:
        return self.views_per_ring * len(self.elevations_deg)

    def intrinsics(self) -> np.ndarray:
        """(3, 3) OpenCV K with square pixels and a centred principal point."""
        f = 0.5 * self.height / np.tan(np.radians(self.fov_y_deg) / 2)
        return make_K(f, f, (self.width - 1) / 2, (self.height - 1) / 2)

    def fit_distance(self, radius: float) -> float:
        """Distance at which a sphere of ``radius`` about the origin fills ``fill`` of the
        vertical (or, if narrower, horizontal) field of view."""
        r = float(radius)
        half = np.radians(self.fov_y_deg) / 2
        half_x = np.arctan(np.tan(half) * self.width / self.height)
        return r / np.sin(self.fill * min(half, half_x))

    def cameras(self, radius: float | None = None) -> list[Camera]:
        """The rig's cameras, ring by ring, azimuth increasing (counter-clockwise from above).
        ``radius``: the object's bounding radius about the origin (metres), used when
        ``distance`` is None."""
        if self.distance is None and radius is None:
            raise ValueError("rig: give the object's radius or a fixed distance")
        d = float(self.distance) if self.distance is not None else self.fit_distance(radius)
        focal = float(self.intrinsics()[0, 0])
        step = 360.0 / self.views_per_ring
        cams = []
        for r, el in enumerate(self.elevations_deg):
            off = 0.5 * step if (self.stagger and r % 2) else 0.0
            az = [np.radians(self.azimuth0_deg + off + i * step) for i in range(self.views_per_ring)]
            cams += ring_cameras(self.views_per_ring, self.width, self.height, focal, d, (el,), az,
                                 name=f"r{r}_v{{:03d}}")
        return cams
