"""Registration of range scans and photos into one frame (issue 4).

``points`` (depth -> clouds), ``icp`` (Open3D multiway ICP + pose graph + FPFH fallback),
``colmap`` (pycolmap SfM + Umeyama), ``board`` (ChArUco PnP), ``report`` (thresholds,
errors, registration.json), ``raycast`` (exact reference depth of a mesh), ``perturb``,
``check`` / ``verify`` (the independent check of every placed view: registered, kept nominal
or flagged, never worse than the input; issue 22).
"""

import os as _os

# Open3D's OpenMP threads spin-wait; on a busy 2-core machine that made one ICP call 10x slower
# (0.17 s instead of 0.02 s, measured).  Must be set before open3d is first imported.
_os.environ.setdefault("OMP_WAIT_POLICY", "passive")
