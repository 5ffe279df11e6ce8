"""Step 5 of the fusion (volume.fusion, docs/methods.md §1.1): a band of fused distances and a sign field
completed into a signed distance volume that is finite everywhere (exact Euclidean distance
transforms of the sign field)."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

#: Largest distance (metres) stored for a voxel with nothing to measure from (empty volumes).
FAR = 1.0
#: Threads of the ``edt`` package's transform (``complete_sdf``'s 'numba' backend): None = the cores this
#: process may run on; 1 = one thread (the reference).  Each line of the volume is transformed on its own,
#: so the distances are the same bit for bit (tests/volume/test_fusion_jit.py); 256^3 on this 2-core machine
#: under load: 0.64 s on two threads against 1.10 s on one (docs/speed.md, round 13).
EDT_THREADS: int | None = None


def edt_threads() -> int:
    """The threads of the edt transform: EDT_THREADS, else the cores this process may run on."""
    if EDT_THREADS is not None:
        return max(1, int(EDT_THREADS))
    from capture.plate_threads import cores

    return cores()


def complete_sdf(band_values: np.ndarray, band: np.ndarray, outside: np.ndarray, w: float,
                 backend: str = "numpy") -> np.ndarray:
    """Fill a full signed distance volume (L, L, L) float32 from band values and a sign field.

    Band voxels keep their fused value and sign; every other voxel gets its sign from
    ``outside`` and the magnitude (EDT distance to the nearest voxel of the other sign - w/2),
    an exact Euclidean distance transform of the binary sign field, so the filled part is
    1-Lipschitz and cannot create Eq. 1 discontinuities by itself.  ``backend`` 'numba': both
    sides in one multi-label pass of the ``edt`` package (compiled, float32; 11x faster at
    256^3); 'numpy': one scipy transform per side, the reference.
    """
    L = band.shape[0]
    sign_out = np.where(band, band_values > 0, outside)
    vals = np.empty(band.shape, np.float32)
    far = np.float32(max(FAR, 2 * L * w))
    if backend == "numba" and sign_out.any() and not sign_out.all():
        import edt

        d = edt.edt(sign_out.view(np.uint8) + np.uint8(1), black_border=False, parallel=edt_threads())
        d -= np.float32(0.5)
        d *= np.float32(w)
        np.negative(d, out=d, where=~sign_out)  # in place: np.where(sign_out, d, -d) without two new volumes
        vals = d.astype(np.float32, copy=False)
        vals[band] = band_values[band]
        return vals
    for side in (True, False):
        region = sign_out == side
        if not region.any():
            continue
        if (~region).any():
            mag = (ndimage.distance_transform_edt(region).astype(np.float32) - np.float32(0.5)) * np.float32(w)
        else:
            mag = np.full(band.shape, far, np.float32)
        vals[region] = (mag if side else -mag)[region]
    vals[band] = band_values[band]
    return vals
