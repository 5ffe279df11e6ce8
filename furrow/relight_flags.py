"""The ``--relight`` flags of ``furrow render`` (issue 15), kept apart from cmd_render.py: parse
them, and open the relighter (``render.relight.gl.Relighter``) the frames go through."""

from __future__ import annotations

import argparse

#: --relight given without a map: relight to the --env map.
SAME_AS_ENV = ""


def add_map_orientation_arguments(g, maps: str, prefix: str = "env") -> None:
    """``--PREFIX-rotation DEG`` and ``--PREFIX-convention NAME`` for the map arguments named in ``maps``: the
    same two flags (and the same stated orientation) wherever furrow reads an environment map."""
    from render.shading.envmap import DEFAULT_CONVENTION, ENV_CONVENTIONS, ORIENTATION

    g.add_argument(f"--{prefix}-rotation", type=float, default=0.0, metavar="DEG",
                   help=f"turn {maps} about the rig's up axis by DEG degrees (right-handed: seen from above, "
                        f"counter-clockwise); {ORIENTATION}")
    g.add_argument(f"--{prefix}-convention", choices=list(ENV_CONVENTIONS), default=DEFAULT_CONVENTION,
                   help=f"layout of the equirect files of {maps} (default {DEFAULT_CONVENTION}; blender is the same; "
                        "mitsuba: Mitsuba 3's, a quarter turn from furrow's); bundled maps are always furrow's")


def add_relight_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("relighting (the model must store its capture lighting: furrow model --capture-env)")
    g.add_argument("--relight", nargs="?", const=SAME_AS_ENV, default=None, metavar="MAP",
                   help="light the object by MAP (.exr/.hdr equirect or a bundled name) instead of the capture's "
                        "lighting, on black; with --env the same map lights the object, the background, the "
                        "ground shadow and the glare (--relight alone then takes the --env map)")
    g.add_argument("--relight-kernel", default=None, metavar="NAME",
                   help="transfer of the relighting: auto (default: the kernel and the forward scattering that best "
                        "explain the model's own capture views under the capture lighting, judged on views they did "
                        "not see and kept near the default transfer (wrap, forward 1, g 0.8) unless the views show "
                        "better; when the transfers the capture cannot tell apart disagree under the new map, the "
                        "default transfer or the single global gain instead; it prints which and why; "
                        "docs/relight.md), or a fixed kernel: wrap, lambert, fur, half-lambert, or mix:W0,W1,W2,W3 "
                        "(weights of lambert, wrap, half-lambert, uniform)")
    g.add_argument("--relight-strands", action="store_true",
                   help="strand-aware relighting: strand tangents from the capture views and a fibre transfer where "
                        "the capture looks like fur or needles (docs/relight.md; measured -0.25 to +0.23 dB on top "
                        "of the default transfer on our fur balls and plants, no better on the whole, so off by "
                        "default); adds a second or two of setup")
    g.add_argument("--relight-visibility", action="store_true",
                   help="self-visibility from the model's sphere set (SSDF): for concave solids; adds seconds of setup")


def relight_map(args) -> str | None:
    """The map name / file to relight to, or None; one map for all (--relight and --env agree)."""
    if args.relight is None:
        if args.relight_kernel or args.relight_visibility or args.relight_strands:
            raise ValueError("--relight-kernel, --relight-visibility and --relight-strands need --relight")
        return None
    if args.relight == SAME_AS_ENV:
        if not args.env:
            raise ValueError("--relight without a map needs --env MAP (or give --relight MAP)")
        return args.env
    if args.env and args.env != args.relight:
        raise ValueError(f"--relight {args.relight} and --env {args.env}: one map lights everything; give the same "
                         "map (or only --relight)")
    return args.relight


def open_relighter(args, ctx, model, stack):
    """The Relighter of --relight entered on ``stack`` (an ExitStack), or None without --relight; the
    map laid out by --env-convention and turned by --env-rotation like the background."""
    name = relight_map(args)
    if name is None:
        return None
    from render.relight.gl import RelightConfig, Relighter
    from render.shading.envmap import named_envmap

    env = named_envmap(name, args.env_convention, args.env_rotation)
    cfg = RelightConfig(**({"kernel": args.relight_kernel} if args.relight_kernel else {}),
                        visibility=args.relight_visibility, strands=args.relight_strands)
    rel = stack.enter_context(Relighter.from_model(ctx, model, env, cfg))
    from furrow.console import console

    if rel.fit is not None:
        f = rel.fit
        console.print(f"relighting transfer fitted to the capture views: kernel {f.kernel}, forward scattering "
                      f"{f.forward:g} (g {f.forward_g:g}), chosen on views it did not see from {f.samples} "
                      f"(voxel, view) cells; {len(f.plausible)} transfers within noise of the best; "
                      f"{rel.setup_seconds.get('fit', 0):.1f} s", highlight=False)
    if rel.choice is not None:
        colour = "" if rel.choice.source == "fitted" else "[yellow]"
        console.print(f"{colour}relighting with {rel.choice.reason}{'[/yellow]' if colour else ''}", highlight=False)
    elif rel.fit_note:
        console.print(f"[yellow]relighting: {rel.fit_note}[/yellow]")
    return rel
