"""``furrow view MODEL``: the interactive web viewer (render.viewer)."""

from __future__ import annotations

import argparse
import signal
import threading
from pathlib import Path

from render.methods import DEFAULT_METHOD

HELP = "interactive web viewer: renders the model on this machine, shows it in a browser (viser)"
DESCRIPTION = """Serve a furrow model to web browsers: the server renders every frame with furrow's own
renderers (any method of the registry) and the browser shows it (viser).  While the camera moves,
frames are drawn smaller to hold about 12 frames per second (sized from each stage's measured
cost, never sent more than 1.5x that often); 0.2 s after it stops, the full frame is drawn, then supersampled.
Without a GPU (Mesa llvmpipe) one core is left to the browser (--gl-threads); docs/viewer.md has
where a frame's time goes.  The capture cameras are clickable frustums; the panel holds the
method and its own options (from its spec), supersampling, environment compositing, debug views, a PNG
screenshot and MP4 export (saved under --out and downloaded).  Ctrl-C stops it.

examples:
  furrow view out/demo/furball_model
  furrow view out/demo/furball_model --cameras out/demo/furball_scan --port 8090 --stats view_stats.json
  furrow view out/fur_model --env sunset --ground --host 0.0.0.0"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", type=Path, help="model folder written by `furrow model`")
    p.add_argument("--cameras", type=Path, default=None,
                   help="transforms.json (or a folder holding one) whose cameras are shown as frustums "
                        "(default: the model's own input cameras)")
    p.add_argument("--port", type=int, default=8080, help="port to serve on (default 8080; 0 = any free port)")
    p.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1; 0.0.0.0 = all)")
    p.add_argument("--stats", type=Path, default=None, metavar="FILE",
                   help="on exit, write every frame sent as JSON {\"frames\": [{t, ms, width, height, moving, method, "
                        "...}]}")
    p.add_argument("--method", default=DEFAULT_METHOD,
                   help=f"initial rendering method (any registered name; default {DEFAULT_METHOD}, as furrow render)")
    p.add_argument("--env", default=None, metavar="MAP",
                   help="initial environment map: a bundled name or a .exr/.hdr file (default: none, black)")
    p.add_argument("--ground", action="store_true", help="with --env: start with the ground shadow on")
    from furrow.relight_flags import add_map_orientation_arguments

    add_map_orientation_arguments(p, "the environment maps (--env and the GUI's; the GUI's slider starts here)")
    p.add_argument("--fps", type=float, default=None,
                   help="frames per second to hold while moving (default 12): moving frames are sized to it and "
                        "sent at most 1.5x that often")
    p.add_argument("--gl-threads", type=int, default=None, metavar="N",
                   help="llvmpipe rasteriser threads when there is no GPU (default: the cores less one, at least 1, "
                        "so that a browser on this machine keeps a core for its software WebGL; LP_NUM_THREADS in "
                        "the environment wins)")
    p.add_argument("--out", type=Path, default=Path("out/view"), help="where screenshots and videos are saved")
    p.add_argument("--debug", action="store_true", help="show tracebacks")


def settings_from_args(args):
    """The initial ViewSettings and the environment maps offered (bad names fail here)."""
    from render.methods import METHODS
    from render.shading.envmap import BUNDLED_NAMES, named_envmap
    from render.viewer.settings import EnvSettings, ViewSettings

    if args.method not in METHODS:
        raise ValueError(f"unknown method {args.method!r}; use one of {', '.join(METHODS)}")
    names = list(BUNDLED_NAMES)
    if args.env is not None:
        named_envmap(args.env, args.env_convention)  # a missing file or unknown name fails now, in one line
        if args.env not in names:
            names.append(args.env)
    elif args.ground:
        raise ValueError("--ground needs --env MAP")
    env = EnvSettings(map=args.env, ground=args.ground, rotation_deg=args.env_rotation, convention=args.env_convention)
    return ViewSettings(method=args.method, env=env), names


def run(args, console) -> int:
    from render.viewer.gl_worker import llvmpipe_threads

    with llvmpipe_threads(args.gl_threads):  # around the process's first GL context
        return _serve(args, console)


def _serve(args, console) -> int:
    from capture.io import read_cameras
    from render.viewer.adaptive import AdaptiveConfig
    from render.viewer.server import Viewer
    from volume.model import load_model

    settings, env_names = settings_from_args(args)
    model = load_model(args.model)
    cameras = [f.camera for f in read_cameras(args.cameras)] if args.cameras else list(model.rgbz.cameras)
    cfg = AdaptiveConfig() if args.fps is None else AdaptiveConfig(target_fps=args.fps)
    viewer = Viewer(model, cameras, host=args.host, port=args.port, settings=settings, cfg=cfg, out_dir=args.out,
                    env_names=env_names)
    stop = threading.Event()
    previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        print(viewer.url, flush=True)  # stdout: the one machine-readable line
        console.print(f"[green]furrow view[/] serving {args.model} at [bold]{viewer.url}[/]  (Ctrl-C to stop)")
        while not stop.wait(0.5):
            pass
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        released = viewer.close(args.stats)
    console.print(f"stopped; GL {'released' if released else 'NOT released'}"
                  + (f", {len(viewer.log.frames())} frames logged to {args.stats}" if args.stats else ""))
    return 0 if released else 1
