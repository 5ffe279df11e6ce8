"""Scan set -> model: signed distance volumes, L_opt and the LOD pyramid, RGBz images, sphere sets, mesh.

Modules: ``model`` (the data model and its folder format), ``grid`` (the voxel cube),
``fusion`` (consensus fusion, METHODS §1.1), ``tsdf`` (Open3D TSDF peer), ``pyramid`` (Eq. 1,
surface voxels), ``rgbz`` (METHODS §1.4), ``spheres`` (METHODS §3), ``mesh`` (baseline mesh),
``metrics`` (accuracy against ground truth), ``build`` (the whole chain for ``furrow model``).
"""
