"""Seeded procedural scenes with exact ground truth, a turntable rig, noise models and writers.

Modules: ``scenes`` (furball, plant, torus as triangle meshes), ``geometry`` (tubes, lathe,
ellipsoid, PLY), ``rig`` (turntable cameras), ``lighting`` (environment lighting through
``render.shading``), ``noise`` (depth noise, holes, grazing dropouts, pose perturbation),
``synth`` (render + write a capture with ``gt/``), ``preview`` (contact sheet).
CLI: ``furrow synth NAME -o DIR``.
"""
