"""Seeded procedural scenes with exact ground truth, a turntable rig, noise models and writers.

Modules: ``scenes`` (furball, plant, torus, furrybunny as triangle meshes), ``scanned`` (fur on
the scanned Stanford Bunny shipped in pymeshlab, licence noted there), ``fur`` (strands grown on
any mesh), ``geometry`` (tubes, lathe, ellipsoid, PLY), ``rig`` (turntable cameras),
``lighting`` (environment lighting through ``render.shading``), ``hair_shading`` (the R / TT /
TRT hair lobes under the map), ``noise`` (depth noise, holes, grazing dropouts, pose
perturbation), ``sensor`` (RGB-D sensor traits: z^2 noise, quantisation, flying pixels),
``synth`` (render + write a capture with ``gt/``), ``relight`` (relighting ground truth under
another map), ``preview`` (contact sheet).
CLI: ``furrow synth NAME -o DIR``.
"""
