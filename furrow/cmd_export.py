"""``furrow export MODEL [--mesh out.glb|out.ply] [--points out.ply] [--spheres out.ply]``."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "export a model for other tools: vertex-coloured mesh (GLB/PLY), fused coloured points, occluder spheres (PLY)"
DESCRIPTION = """Write parts of a furrow model as files that Blender, MeshLab, CloudCompare, three.js or any glTF
viewer open.  Coordinates stay in the capture's world frame, in metres (the frame of the scan set's
cameras).  Colours: the GLB holds linear float vertex colours (glTF's COLOR_0 is linear) and a rough
non-metallic material; the PLY files hold 8-bit sRGB colours, as viewers expect.

  --mesh     the baseline mesh with per-vertex colour, .glb (binary glTF) or .ply
  --points   the coloured points of every kept view (the model's RGBz images), fused on a grid of
             --point-voxel metres (default half the finest pyramid voxel; 0 = every point)
  --spheres  the occluder sphere set (docs/methods.md §3): one PLY vertex per sphere, x y z + radius

examples:
  furrow export out/furball_model --mesh out/furball.glb
  furrow export out/furball_model --mesh out/furball.ply --points out/points.ply --spheres out/spheres.ply"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", type=Path, help="model folder written by `furrow model`")
    p.add_argument("--mesh", type=Path, default=None, metavar="OUT.glb|OUT.ply", help="write the vertex-coloured mesh")
    p.add_argument("--points", type=Path, default=None, metavar="OUT.ply", help="write the fused coloured points")
    p.add_argument("--point-voxel", type=float, default=None, metavar="M",
                   help="grid edge (metres) that fuses the points (default: half the finest pyramid voxel; 0 = all)")
    p.add_argument("--spheres", type=Path, default=None, metavar="OUT.ply", help="write the occluder spheres")
    p.add_argument("--debug", action="store_true", help="show tracebacks")


def run(args, console) -> int:
    from volume.export import write_mesh, write_points, write_spheres
    from volume.model import load_model

    if not (args.mesh or args.points or args.spheres):
        raise ValueError("nothing to export: give --mesh, --points and/or --spheres")
    if args.point_voxel is not None and not args.points:
        raise ValueError("--point-voxel applies to --points only")
    model = load_model(args.model)
    if args.mesh:
        r = write_mesh(model, args.mesh)
        console.print(f"[green]wrote[/] mesh {r.count} vertices, {r.faces} triangles -> {r.path}", highlight=False)
    if args.points:
        r = write_points(model, args.points, args.point_voxel)
        console.print(f"[green]wrote[/] {r.count} fused points -> {r.path}", highlight=False)
    if args.spheres:
        r = write_spheres(model, args.spheres)
        console.print(f"[green]wrote[/] {r.count} spheres (centre + radius) -> {r.path}", highlight=False)
    return 0
