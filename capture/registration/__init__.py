"""Registration of range scans and photos into one frame (issue 4).

``points`` (depth -> clouds), ``icp`` (Open3D multiway ICP + pose graph + FPFH fallback),
``colmap`` (pycolmap SfM + Umeyama), ``board`` (ChArUco PnP), ``report`` (thresholds,
errors, registration.json), ``raycast`` (exact reference depth of a mesh), ``perturb``.
"""
