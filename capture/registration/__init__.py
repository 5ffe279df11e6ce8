"""Registration of range scans and photos into one frame (issue 4).

``points`` (depth -> clouds), ``icp`` (Open3D multiway ICP + pose graph + FPFH fallback),
``colmap`` (pycolmap SfM + Umeyama), ``board`` (ChArUco PnP), ``report`` (thresholds,
errors, registration.json), ``raycast`` (exact reference depth of a mesh), ``perturb``,
``turntable`` / ``turntable_solve`` / ``turntable_place`` (one axis, one angle per view),
``prior`` (the input's stated uncertainty bounds every move; issue 31), ``angles`` (a turntable
view's angle hypotheses: the evidence's angle only when it is the one clear answer and beats the
input angle), ``check`` / ``verify`` (the independent check: a registered pose is kept only where
it explains the data significantly better than the input pose; issues 22, 31).
"""

import os as _os

# Open3D's OpenMP threads spin-wait; on a busy 2-core machine that made one ICP call 10x slower
# (0.17 s instead of 0.02 s, measured).  Must be set before open3d is first imported.
_os.environ.setdefault("OMP_WAIT_POLICY", "passive")
