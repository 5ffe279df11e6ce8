"""``furrow export MODEL [--mesh out.glb|out.ply] [--points out.ply] [--spheres out.ply]
[--splats out.ply [--refine N]] [--web DIR]``."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = ("export a model for other tools: vertex-coloured mesh (GLB/PLY), fused coloured points, occluder "
        "spheres (PLY), 3D Gaussian splats (PLY) and a static web page")
DESCRIPTION = """Write parts of a furrow model as files that Blender, MeshLab, CloudCompare, three.js, glTF viewers
or 3D Gaussian Splatting viewers open.  Coordinates stay in the capture's world frame, in metres (the
frame of the scan set's cameras).  Colours: the GLB holds linear float vertex colours (glTF's COLOR_0 is
linear) and a rough non-metallic material; the PLY files hold 8-bit sRGB colours, as viewers expect.

  --mesh     the baseline mesh with per-vertex colour, .glb (binary glTF) or .ply
  --points   the coloured points of every kept view (the model's RGBz images), fused on a grid of
             --point-voxel metres (default half the finest pyramid voxel; 0 = every point)
  --spheres  the occluder sphere set (docs/methods.md §3): one PLY vertex per sphere, x y z + radius
  --splats   3D Gaussians built from the kept views (not from the mesh; docs/splats.md): positions from
             the views' depth merged on a grid of one pixel footprint, anisotropic shapes from the local
             surface or strand direction, opacity from the matte, view-dependent colour as spherical
             harmonics (--sh-degree, default 2) fitted by least squares to every view that sees each
             Gaussian; the PLY layout of the 3D Gaussian Splatting reference (Kerbl et al. 2023), which
             SuperSplat, the Blender / Unity add-ons and the three.js viewers read; what `--method splat`
             draws
  --size-ratio R  the splats' PLY at most R x the model folder (default 2.95): the merge grid grows until
             the Gaussians fit; 0 = one Gaussian per pixel footprint, whatever the size
  --refine N  after building, refine the opacities against the kept views' mattes (up to N iterations,
             each drawing every kept view; an iteration that does not lower the alpha error is undone and
             ends it): thin needles and strands come out less wide
  --web      a folder (index.html + splats.bin) that any static file server (`python -m http.server`)
             shows as a page drawing the splats in the browser (WebGL2, no dependency, offline; the splat
             method's image formation with the view-dependent colour), orbiting with the mouse about the
             object from the first capture camera

examples:
  furrow export out/furball_model --mesh out/furball.glb
  furrow export out/furball_model --mesh out/furball.ply --points out/points.ply --spheres out/spheres.ply
  furrow export out/furball_model --splats out/furball_splats.ply --web out/furball_web
  (cd out/furball_web && python -m http.server 8000)    then open http://localhost:8000"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", type=Path, help="model folder written by `furrow model`")
    p.add_argument("--mesh", type=Path, default=None, metavar="OUT.glb|OUT.ply", help="write the vertex-coloured mesh")
    p.add_argument("--points", type=Path, default=None, metavar="OUT.ply", help="write the fused coloured points")
    p.add_argument("--point-voxel", type=float, default=None, metavar="M",
                   help="grid edge (metres) that fuses the points (default: half the finest pyramid voxel; 0 = all)")
    p.add_argument("--spheres", type=Path, default=None, metavar="OUT.ply", help="write the occluder spheres")
    p.add_argument("--splats", type=Path, default=None, metavar="OUT.ply",
                   help="write the model's 3D Gaussians (3D Gaussian Splatting PLY)")
    p.add_argument("--sh-degree", type=int, default=None, metavar="D",
                   help="spherical-harmonic degree of the splats' colour, 0-3 (default 2)")
    p.add_argument("--size-ratio", type=float, default=None, metavar="R",
                   help="the splats' PLY at most R x the model's size on disk (default 2.95, under 3; the merge grid "
                        "grows until it fits); 0 = no limit")
    p.add_argument("--refine", type=int, default=0, metavar="N",
                   help="refine the splats' opacities against the kept views' mattes for up to N iterations "
                        "(each draws every kept view; stops when one does not lower the alpha error; default 0)")
    p.add_argument("--web", type=Path, default=None, metavar="DIR",
                   help="write a static web page drawing the splats (serve DIR with any static file server)")
    p.add_argument("--debug", action="store_true", help="show tracebacks")


def run(args, console) -> int:
    from volume.export import write_mesh, write_points, write_spheres
    from volume.model import load_model

    if not (args.mesh or args.points or args.spheres or args.splats or args.web):
        raise ValueError("nothing to export: give --mesh, --points, --spheres, --splats and/or --web")
    if args.point_voxel is not None and not args.points:
        raise ValueError("--point-voxel applies to --points only")
    if (args.sh_degree is not None or args.refine or args.size_ratio is not None) and not (args.splats or args.web):
        raise ValueError("--sh-degree, --size-ratio and --refine apply to --splats / --web only")
    if args.size_ratio is not None and args.size_ratio < 0:
        raise ValueError(f"--size-ratio must be >= 0 (0 = no limit), got {args.size_ratio}")
    if args.refine < 0:
        raise ValueError(f"--refine must be >= 0 iterations, got {args.refine}")
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
    if args.splats or args.web:
        export_splats(args, model, console)
    return 0


def export_splats(args, model, console) -> None:
    """--splats and --web: build the Gaussians once, write what was asked."""
    import dataclasses
    import time

    from furrow.console import track
    from volume.export import write_splats
    from volume.splats import SplatConfig, build

    cfg = SplatConfig()
    if args.sh_degree is not None:
        cfg = dataclasses.replace(cfg, sh_degree=args.sh_degree)
    if args.size_ratio is not None:
        cfg = dataclasses.replace(cfg, budget_ratio=args.size_ratio or None)
    t0, c0 = time.perf_counter(), time.process_time()
    splats, info = build(model, cfg, progress=track)
    budget = f"budget {info.budget} (size ratio {cfg.budget_ratio:g})" if info.budget else "no budget"
    console.print(f"built {len(splats)} Gaussians (SH degree {splats.degree}) from {len(model.rgbz)} views, "
                  f"{info.kept} of {info.samples} samples kept (one layer), grid {info.edge_m * 1e3:.2f} mm = "
                  f"{info.edge_footprints:.2f} pixel footprints, {budget}; {time.perf_counter() - t0:.1f} s "
                  f"({time.process_time() - c0:.1f} s CPU)", highlight=False)
    if args.refine:
        splats = refine(splats, model, args.refine, console)
    if args.splats:
        r = write_splats(splats, args.splats)
        mb = r.path.stat().st_size / 2**20
        console.print(f"[green]wrote[/] {r.count} Gaussians ({mb:.1f} MiB) -> {r.path}", highlight=False)
    if args.web:
        from volume.export_web import write_web

        r = write_web(splats, model, args.web)
        console.print(f"[green]wrote[/] web page ({r.bytes / 2**20:.1f} MiB in {r.files} files) -> {r.path}  "
                      f"(serve it: cd {r.path} && python -m http.server, then open http://localhost:8000)",
                      highlight=False)


def refine(splats, model, iterations: int, console):
    """--refine N: the opacity refinement (volume.splat_refine) drawing with the GL splat renderer."""
    from furrow.console import track
    from render.gl import gl_context
    from render.splat.gl import drawn_alphas
    from volume.splat_refine import refine_opacities

    with gl_context() as ctx:
        splats, rep = refine_opacities(splats, model, lambda s, cams: drawn_alphas(ctx, s, cams), iterations,
                                       progress=track)
    errs = " -> ".join(f"{e:.4f}" for e in rep.errors)
    why = "; stopped: the next iteration did not lower it" if rep.stopped else ""
    console.print(f"refined opacities: {rep.iterations} iteration(s), kept views' alpha error {errs}{why}",
                  highlight=False)
    return splats
