"""Path-traced hard cases (Mitsuba 3): captures furrow has not made itself, for issues 30 and 31.

Each case is rendered by an independent path tracer (Mitsuba 3's ``path`` integrator, ``hair``
BSDF on B-spline strands, needles as round linear curves, the room as a visible environment map)
and written in furrow's scan format with the true coverage matte of every view (``mask_path``),
16-bit millimetre z-depth, and gt/ (datasets_synthetic/pathtraced/). Cases, in priority order:

  conifer_room_turntable      (+ conifer_black_turntable)  conifer, room kept / black held, turntable
  conifer_room_orbit          (+ conifer_black_orbit)      the same, camera circling
  furball_uniform_turntable   (+ _pose5)                   uniform fur ball, poses off 2/2 (and 5/5)
  furball_uniform_relit                                    fur ball under forest, truth under city
  conifer_room_table_ae_lens                               room + table + auto exposure + OPENCV lens
  conifer_black_lens                                       the OPENCV lens alone (twin: conifer_black_turntable)
  fur_similar_bg              (+ fur_black_similar)        brown fur before brown bricks
  furball_uniform_ae          (+ furball_uniform_fixed)    auto exposure on the uniform fur ball
  furball_uniform_orbit                                    the fur ball, camera circling
  conifer_room_orbit_ae                                    the orbit conifer, auto exposure (twin: conifer_black_orbit)
  conifer_room_turntable_jump_ae                           the turntable conifer, +0.5 EV in 3 kept views only
  conifer_room_orbit_jump_ae                               the orbit conifer, the same
  fur_similar_bg_jump_ae                                   the brown fur before bricks, the same
  fur_similar_bg_orbit        (+ fur_black_similar_orbit)  the brown fur, camera circling
  conifer_room_turntable_shade                             the room behind the crown shaded in 3 kept views
  conifer_room_orbit_shade                                 the orbit conifer, the same
  conifer_room_{turntable,orbit}_shade_left                the same, behind the crown's left half only
  fur_room_table_ae_lens      (+ fur_black_table_lens)     the brown fur on the table, auto exposure, OPENCV lens
                                                           (twins: fur_black_similar at the same --size; its own
                                                           renders over black, the table's light kept)
  bunny_room_turntable        (+ bunny_black_turntable)    furry bunny (scanned body, 30,000 strands) before the room
  bunny_room_table_ae_lens    (+ bunny_black_table_lens)   the bunny on the table, auto exposure, OPENCV lens
  bunny_room_orbit            (+ bunny_black_orbit)        the bunny, camera circling

Renders are cached per view under --cache (an interrupted run resumes; captures that share pixels
render once). Each case runs in a child process: when the renderer kills it (Mitsuba 3.9.1 segfaulted on
some fur views), the case is run again and the view that was being rendered draws other samples
(datasets_synthetic.pathtraced.render.MAX_ATTEMPTS times at most; gt/scene.json records the attempt).
INDEX.md in --out lists every capture made: what it is, the command, size, spp, render time, and how
partial its mattes are. Needs `pip install -e '.[pathtrace]'` and Debian's libllvm19
(`make hardcases` installs both and runs this script).

    python scripts/hardcases.py                                  # every case into /work/cache/hardcases
    python scripts/hardcases.py conifer_room_turntable --size 320x240 --spp 16 -o out/hard
    python scripts/hardcases.py --noise conifer_room_turntable   # PSNR of one view against 2x spp
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: Default output folder (shared between the project's sessions).
DEFAULT_OUT = Path("/work/cache/hardcases")
INDEX_JSON, INDEX_MD = "INDEX.json", "INDEX.md"
#: Free text appended to INDEX.md when present in the output folder (measurements made with the captures).
NOTES_MD = "NOTES.md"
#: Set in the child process that makes one case (``run_isolated``); unset, main() runs every case in a child.
WORKER_ENV = "FURROW_HARDCASES_WORKER"


def parse(argv=None) -> argparse.Namespace:
    from datasets_synthetic.pathtraced.cases import CASES

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("cases", nargs="*", metavar="CASE", help=f"cases to make (default: all): {', '.join(CASES)}")
    p.add_argument("-o", "--out", type=Path, default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})")
    p.add_argument("--cache", type=Path, default=None, help="per-view render cache (default OUT/_renders)")
    p.add_argument("--env-dir", type=Path, default=None,
                   help="folder with the maps that are not bundled (city.exr): Blender's studio lights, "
                        "usr/share/blender/datafiles/studiolights/world of Debian's blender-data")
    p.add_argument("--size", default=None, metavar="WxH", help="image size of every case (default: 640x480 for the "
                   "conifer, 320x240 for the fur balls)")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel of every case (default 64; 16 for "
                   "conifer_room_table_ae_lens, the fur orbit, its relit truth and fur_similar_bg)")
    p.add_argument("--views", type=int, default=36, help="views per capture (default 36)")
    p.add_argument("--seed", type=int, default=0, help="seed of geometry, samples, exposure and poses (default 0)")
    p.add_argument("--room-rotation", type=float, default=None, metavar="DEG",
                   help="turn of the map behind the room cases (conifer default 340: the crown before the sunlit "
                        "wall and floor; 315: before the shaded bricks; fur_similar_bg default 270: the brown "
                        "floor); write to another -o, the names are the same")
    p.add_argument("--room-map", default=None, metavar="NAME",
                   help="map behind the room cases (conifer, fur_similar_bg) instead of the courtyard (a bundled "
                        "name, or NAME.exr in --env-dir: interior, forest, city, ...); write to another -o, the "
                        "names are the same")
    p.add_argument("--noise", action="store_true", help="instead of writing: render view 0 of each case's first "
                   "render at 2x spp and print the PSNR of the case's spp against it")
    p.add_argument("--list", action="store_true", help="list the cases and exit")
    p.add_argument("--in-process", action="store_true", help="make the cases in this process (no child process, "
                   "so no retry after a crash of the renderer)")
    a = p.parse_args(argv)
    bad = [c for c in a.cases if c not in CASES]
    if bad:
        p.error(f"unknown case(s) {', '.join(bad)}; choose from {', '.join(CASES)}")
    if a.size is not None:
        try:
            w, h = (int(v) for v in a.size.lower().split("x"))
        except ValueError:
            p.error(f"--size {a.size!r}: expected WxH, e.g. 640x480")
        a.size = (w, h)
    return a


def _entries(out: Path) -> list[dict]:
    p = out / INDEX_JSON
    return json.loads(p.read_text()) if p.is_file() else []


def write_index(out: Path, new: list[dict]) -> None:
    """Merge ``new`` entries (by name) into OUT/INDEX.json and rewrite OUT/INDEX.md."""
    from capture.atomic import atomic_write

    old = {e["name"]: e for e in _entries(out)}
    old.update({e["name"]: e for e in new})
    entries = list(old.values())
    with atomic_write(out / INDEX_JSON) as tmp:
        tmp.write_text(json.dumps(entries, indent=1))
    lines = ["# Path-traced hard cases (Mitsuba 3)", "",
             "Made by `scripts/hardcases.py` (datasets_synthetic/pathtraced/). Each folder is a transforms.json "
             "capture with true mattes (mask_path), 16-bit mm z-depth and gt/ (scene.json, mesh.ply; "
             "cameras_true.json / exposure.json where poses / exposure are perturbed; maps/ the map that lit it, "
             "furrow's layout: read with the default --env-convention furrow). Render times were measured on a "
             "shared, loaded 2-core machine: compare them with each other only.", "",
             "Partiality (over all views, 8-bit mattes): *partial* = share of object pixels (alpha > 0) with "
             "alpha < 1; *bin MSE* = alpha MSE of the binary mask alpha > 0.5 over object pixels; *depth-mask MSE* "
             "= alpha MSE of the binary mask depth > 0 (object depth) over object-or-depth pixels; *frame* = "
             "object pixels' share of the frame.", "",
             "| capture | what | size | spp | views | render s | partial | bin MSE | depth-mask MSE | frame "
             "| command |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for e in entries:
        lines.append(f"| {e['name']} | {e['what']} | {e['size']} | {e['spp']} | {e['views']} | {e['render_s']:.0f} | "
                     f"{e['partial_fraction']:.3f} | {e['binary_alpha_mse']:.3f} | {e['depth_mask_alpha_mse']:.3f} | "
                     f"{e['object_frame_fraction']:.3f} | `{e['command']}` |")
    notes = [e for e in entries if e.get("noise_psnr")]
    if notes:
        lines += ["", "Noise: PSNR (8-bit sRGB, whole frame / object pixels; then the object over black, object "
                  "pixels) of view 0 at the case's spp against the same view at twice the spp (against the converged "
                  "image: about 1.8 dB more):", ""]
        lines += [f"- {e['name']}: {e['noise_psnr']}" for e in notes]
    notes = out / NOTES_MD
    if notes.is_file():  # measurements made with the captures (e.g. furrow eval), kept by hand
        lines += ["", notes.read_text().rstrip()]
    with atomic_write(out / INDEX_MD) as tmp:
        tmp.write_text("\n".join(lines) + "\n")


def noise_check(name: str, opts, log) -> str:
    """PSNR of view 0 at the case's spp against twice the spp (rendered now, not cached): everything the
    camera sees (whole frame / object pixels), and the object over black (object pixels, as a held-out view).
    Against the converged image the case's spp would score about 1.8 dB more (two noises, variance 1 + 1/2)."""
    from capture.scan import to_uint8_srgb
    from datasets_synthetic.lighting import resolve_env
    from datasets_synthetic.pathtraced import cases
    from datasets_synthetic.pathtraced.film import render_view
    from datasets_synthetic.pathtraced.render import view_seed
    from datasets_synthetic.pathtraced.scene import PathScene, Room, exposure_for
    from render.metrics import psnr

    spec = cases.case_spec(name, opts)
    obj = spec.build_object()
    cam = spec.cameras(obj)[0]
    emap = resolve_env(spec.env)
    ex = exposure_for(emap, cases.Layout().key)
    out = []
    with PathScene(obj, Room(emap, spec.env_rotation_deg, spec.support), spec.seed) as ps:
        for spp, seed in ((spec.spp, view_seed(spec.seed, 0)), (2 * spec.spp, view_seed(spec.seed + 1, 0))):
            t = time.perf_counter()
            v = render_view(ps, cam, spp, seed, spec.lens, spec.max_depth)
            out.append((to_uint8_srgb(v.room * ex), to_uint8_srgb(v.black * ex), v.alpha > 0,
                        time.perf_counter() - t))
            log(f"  {spp} spp: {out[-1][3]:.1f} s")
    a, b = out
    m = a[2] | b[2]
    return (f"{psnr(a[0], b[0]):.1f} dB / {psnr(a[0], b[0], m):.1f} dB, over black {psnr(a[1], b[1], m):.1f} dB "
            f"({spec.spp} vs {2 * spec.spp} spp, {spec.rig.width}x{spec.rig.height}; {a[3]:.0f} s vs {b[3]:.0f} s)")


def main(argv=None) -> int:
    from furrow.console import console, fail

    a = parse(argv)
    from datasets_synthetic.pathtraced.cases import CASES, Options
    from datasets_synthetic.pathtraced.runtime import MitsubaUnavailable, load_mitsuba

    if a.list:
        for name, fn in CASES.items():
            console.print(f"{name}: {(fn.__doc__ or '').strip().splitlines()[0] if fn.__doc__ else ''}")
        return 0
    log = lambda msg: console.print(msg, highlight=False)
    try:
        load_mitsuba()
    except MitsubaUnavailable as e:
        fail(str(e))
        return 2
    if not a.in_process and not os.environ.get(WORKER_ENV):
        for name in a.cases or list(CASES):
            rc = run_isolated(name, [sys.executable, str(Path(__file__).resolve()), *_case_args(name, a, child=True)],
                              log)
            if rc != 0:
                return rc
        return 0
    opts = Options(out=a.out, cache=a.cache or a.out / "_renders", env_dir=a.env_dir, size=a.size, spp=a.spp,
                   views=a.views, seed=a.seed, room_rotation=a.room_rotation,
                   room_map=a.room_map)
    for name in a.cases or list(CASES):
        t0 = time.perf_counter()
        console.rule(name)
        try:
            if a.noise:
                res = noise_check(name, opts, log)
                log(f"{name}: noise {res}")
                write_index(a.out, [dict(e, noise_psnr=res) for e in _entries(a.out) if e["name"] == name])
                continue
            entries = CASES[name](opts, log)
        except (ValueError, FileNotFoundError, RuntimeError) as e:  # RuntimeError: MitsubaUnavailable, a view
            # that crashed the renderer MAX_ATTEMPTS times
            fail(f"{name}: {e}")
            return 1
        for e in entries:
            e["command"] = _case_command(name, a)
        write_index(a.out, entries)
        log(f"{name}: {time.perf_counter() - t0:.0f} s; INDEX: {a.out / INDEX_MD}")
    return 0


def run_isolated(name: str, cmd: list[str], log, runner=subprocess.run) -> int:
    """Run ``cmd`` (this script for case ``name``, as a worker) until it exits by itself; a run killed by a
    signal (a crash inside the renderer) is run again, at most ``MAX_ATTEMPTS`` times in all: the view it
    was rendering resumes from the cache with other samples (``render._attempt``).  Its exit status."""
    from datasets_synthetic.pathtraced.render import MAX_ATTEMPTS

    env = {**os.environ, WORKER_ENV: "1"}
    rc = 0
    for attempt in range(1, MAX_ATTEMPTS + 1):
        rc = runner(cmd, env=env).returncode
        if rc >= 0:
            return rc
        log(f"{name}: the renderer was killed by signal {-rc} (run {attempt} of {MAX_ATTEMPTS})"
            + ("; running it again with other samples for that view" if attempt < MAX_ATTEMPTS else ""))
    return 128 - rc


def _case_args(name: str, a, child: bool = False) -> list[str]:
    """Arguments that remake case ``name`` with the options given (``child``: also the cache and --noise)."""
    opts = [name]
    if a.out != DEFAULT_OUT:
        opts += ["-o", str(a.out)]
    if child and a.cache is not None:
        opts += ["--cache", str(a.cache)]
    if a.env_dir is not None:
        opts += ["--env-dir", str(a.env_dir)]
    if a.size is not None:
        opts += ["--size", f"{a.size[0]}x{a.size[1]}"]
    for flag, v, default in (("--spp", a.spp, None), ("--views", a.views, 36), ("--seed", a.seed, 0),
                             ("--room-rotation", a.room_rotation, None), ("--room-map", a.room_map, None)):
        if v != default:
            opts += [flag, str(v)]
    return opts + (["--noise"] if child and a.noise else [])


def _case_command(name: str, a) -> str:
    """The command line that remakes case ``name`` with the options given."""
    return "python scripts/hardcases.py " + shlex.join(_case_args(name, a))

if __name__ == "__main__":
    sys.exit(main())
