"""Scan set -> model: signed distance volumes, L_opt and the LOD pyramid, RGBz images, sphere sets, mesh.

Modules: ``model`` (the data model and its folder format), ``grid`` (the voxel cube),
``fusion`` (consensus fusion, docs/methods.md §1.1), ``tsdf`` (Open3D TSDF peer), ``pyramid`` (Eq. 1,
surface voxels), ``rgbz`` (docs/methods.md §1.4), ``spheres`` (docs/methods.md §3), ``mesh`` (baseline mesh),
``metrics`` (accuracy against ground truth), ``build`` (the whole chain for ``furrow model``).
"""
