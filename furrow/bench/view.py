"""``furrow bench view``: is ``furrow view`` fluid on this machine, and where does a frame's time go?

A model built from 18 views of a 640x480 fur capture (``furrow synth furball --views 18`` then
``furrow model``, cached under -o; or --model) is dragged around in a --size view (default
960x720, the browser tab of issue 32): camera updates at 60 Hz along an orbit for --drag-s
seconds, then a stop, --repeats times.  Measured from the viewer's own frame log
(render.viewer.session.FrameLog, as ``furrow view --stats`` writes it):

* while dragging: frames per second sent and their height (lines); target >= 10 fps at >= 400
  lines;
* the stages of the moving frames (median wall ms): queued on the GL thread, render (draw and
  read back), convert (to 8-bit sRGB), send (encode and hand to the client);
* after each stop: seconds from the last camera change to the full frame (one sample per pixel),
  and to the supersampled one ("-" for a method that reads no supersampling, whose full frame is
  the last, sent as PNG); target <= 0.5 s for the full frame;
* with ``--driver browser``, in the page itself: server frames received and decoded per second,
  the median decode time and the frames the page drew per second (furrow.bench._browser
  FRAME_COUNTERS_JS): what the user sees;
* a cost table: wall and process-CPU milliseconds of a whole frame (draw, read back, convert,
  encode) at fixed sizes, with its stages, side by side: the CPU figures do not grow with the
  machine's other load.

Two drivers: ``server`` (default) runs the viewer's GL thread and a client session in this
process and encodes each frame as viser would (render.viewer.session.transport_quality), without a
browser; ``browser`` runs ``furrow view`` and drags in Debian's headless chromium (whose
SwiftShader WebGL competes for the same CPU cores).  In-process GL uses the viewer's llvmpipe
thread count (render.viewer.gl_worker.llvmpipe_threads).  The machine's load average is reported
with the figures: on a shared machine they are pessimistic.

    furrow bench view [--driver server|browser] [--model DIR] [--size 960x720] [--drag-s 4]
                      [--repeats 3] [-o out/bench/view] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from capture.atomic import write_json
from furrow.bench import OUT_ROOT
from furrow.bench._common import print_result
from render.methods import DEFAULT_METHOD, samples_per_pixel_side

#: The capture the issue names: 18 views of a 640x480 fur scan.
VIEWS, CAPTURE_SIZE = 18, (640, 480)
#: The view dragged (the browser tab; issue 32 measured a 960x720 one).
SIZE = (960, 720)
#: Targets: frames per second and lines while dragging; seconds from the stop to the full frame.
TARGET_FPS, TARGET_LINES, TARGET_STILL_S = 10.0, 400, 0.5
#: Camera updates per second while dragging (a browser sends about this many), orbit speed (deg/s).
UPDATE_HZ, DEG_PER_S = 60.0, 45.0
#: Seconds after each stop for the still frames; seconds of each drag not counted (ramp-up).
SETTLE_S, RAMP_S = 2.5, 0.5
#: Cost table: heights of the one-sample frames as shares of the view's (and TARGET_LINES), orbit
#: views per row.
COST_SHARES = (0.25, 0.5, 1.0)
COST_FRAMES = 8
#: Stages of a frame in the viewer's log (render.viewer.session.FrameLog), in order.
STAGE_KEYS = ("wait_ms", "render_ms", "convert_ms", "send_ms")
#: Moving frames further apart than this belong to different drags; shorter drags are ignored.
SEGMENT_GAP_S, MIN_DRAG_S = 2.0, 1.0


def build_model(out: Path) -> Path:
    """The 18-view 640x480 fur model under ``out`` (built once with the CLI, then reused)."""
    scan, model = out / "fur18_scan", out / "fur18_model"
    if not (model / "model.json").is_file():
        run = lambda *a: subprocess.run([sys.executable, "-m", "furrow", *map(str, a)], check=True)
        run("synth", "furball", "-o", scan, "--views", VIEWS, "--size", "x".join(map(str, CAPTURE_SIZE)),
            "--seed", 1, "--overwrite")
        run("model", scan, "-o", model, "--overwrite")
    return model


def orbit_views(model, n: int, width: int, height: int, fov: float):
    """n ViewCameras on the rig's orbit (the capture cameras' mean distance and height)."""
    from viser.transforms import SO3

    from capture.orbit import orbit_cameras
    from render.viewer.session import ViewCamera

    cams = orbit_cameras(model.rgbz.cameras, n, center=np.asarray(model.bounds, float).mean(axis=0))
    return [ViewCamera(tuple(SO3.from_matrix(c.world_from_cam[:3, :3]).wxyz), tuple(c.center), fov, width, height)
            for c in cams]


def encode(image: np.ndarray, jpeg_quality: int | None) -> bytes:
    """The bytes viser would send (JPEG of that quality, or PNG)."""
    import cv2

    bgr = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    if jpeg_quality is not None:
        return cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality])[1].tobytes()
    return cv2.imencode(".png", bgr)[1].tobytes()


def view_fov(model, size) -> float:
    """Vertical field of view (radians) of the first capture camera, for a view of ``size``."""
    cam = model.rgbz.cameras[0]
    return float(2 * np.arctan(0.5 * cam.height / cam.K[1, 1]))


def drive_server(model, drag_s: float, repeats: int, size=SIZE) -> list[dict]:
    """Drag in-process; returns the frame log."""
    from render.viewer.gl_worker import GLWorker
    from render.viewer.session import FrameLog, Session

    steps = int(round(360.0 / DEG_PER_S * UPDATE_HZ))
    views = orbit_views(model, steps, *size, view_fov(model, size))
    worker = GLWorker(model)
    log = FrameLog()
    session = Session(worker, encode, log=log, name="bench").start()
    session.update_camera(views[0])
    time.sleep(SETTLE_S * 2)  # first frames: renderer creation and warm-up
    k = 0
    try:
        for _ in range(repeats):
            t_end = time.monotonic() + drag_s
            while time.monotonic() < t_end:
                k += 1
                session.update_camera(views[k % len(views)])
                time.sleep(1.0 / UPDATE_HZ)
            time.sleep(SETTLE_S)
    finally:
        session.stop()
        worker.close()
    return log.frames()


def drive_browser(model_dir: Path, drag_s: float, repeats: int, out: Path, size=SIZE) -> tuple[list[dict], list[dict]]:
    """Drag in headless chromium against ``furrow view``; returns its --stats frames and, per drag,
    the page's own rates after the ramp (furrow.bench._browser.counter_rates)."""
    from playwright.sync_api import sync_playwright

    from capture.camera import image_up
    from furrow.bench import _browser as B
    from volume.model import load_model

    model = load_model(model_dir)
    c = np.asarray(model.bounds, float).mean(axis=0)
    cam0 = model.rgbz.cameras[0]
    stats = out / "view_stats.json"
    vp = B.ViewProcess(model_dir, "--stats", stats, "--out", out)
    rates = []
    try:
        with sync_playwright() as p:
            browser = B.launch(p)
            page = browser.new_page(viewport={"width": size[0], "height": size[1]})
            page.add_init_script(B.FRAME_COUNTERS_JS)
            page.goto(B.view_url(vp.url, cam0.center, c, image_up(cam0)))
            B.wait_still(page, *size, samples_per_pixel_side(DEFAULT_METHOD))
            B.hide_overlays(page)
            mark = lambda: {**B.frame_counters(page), "cpu": B.process_cpu(vp.proc.pid)}
            for _ in range(repeats):
                marks: list[dict] = []
                B.drag(page, drag_s, size[0] / 2, size[1] / 2, ramp_s=RAMP_S,
                       on_ramp=lambda marks=marks: marks.append(mark()))
                rates.append(B.counter_rates(marks[0], mark()))
                time.sleep(SETTLE_S)
            browser.close()
    finally:
        vp.interrupt()
    return json.loads(stats.read_text())["frames"], rates


def cost_rows(size) -> list[tuple[int, int, int | None]]:
    """(lines, samples per pixel side, JPEG quality or None = PNG) of the cost table's rows."""
    from render.viewer.session import FULL_JPEG_QUALITY, MOVING_JPEG_QUALITY

    lines = sorted({round(size[1] * f) for f in COST_SHARES} | {min(TARGET_LINES, size[1])})
    return ([(h, 1, MOVING_JPEG_QUALITY) for h in lines]
            + [(size[1], 1, FULL_JPEG_QUALITY), (size[1], 2, None)])


def cost_table(model, size=SIZE, n: int = COST_FRAMES) -> list[dict]:
    """Whole-pipeline cost of one frame (draw, read back, convert, encode) at fixed heights, with one
    sample per pixel (moving frames, JPEG) and, at full size, supersampled (the still frame, PNG):
    median wall ms, its stages (render, convert, encode) and median process CPU ms (every thread
    of this process, llvmpipe's included) over ``n`` orbit views.  CPU ms does not grow with other
    load on the machine: on an idle machine a frame takes at most about its CPU time (less when
    llvmpipe's threads overlap)."""
    from render.viewer.gl_worker import GLWorker
    from render.viewer.settings import ViewSettings
    from render.viewer.views import draw

    views = orbit_views(model, n, *size, view_fov(model, size))
    settings = ViewSettings()
    worker = GLWorker(model)
    rows = []
    try:
        worker.call(lambda sc: draw(sc, views[0].camera(*size), settings, 2))  # renderer made, shaders compiled
        for lines, ss, quality in cost_rows(size):
            sz = (round(lines * size[0] / size[1]), lines)
            t = {k: [] for k in ("wall", "cpu", "render", "convert", "encode")}
            for v in list(views) * 2:  # the first pass loads the views' crops; the second is timed
                t0, c0 = time.perf_counter(), time.process_time()
                drawn = worker.call(lambda sc, v=v, sz=sz, ss=ss: draw(sc, v.camera(*sz), settings, ss))
                t1 = time.perf_counter()
                encode(drawn.image, quality)
                t2 = time.perf_counter()
                for k, x in (("wall", t2 - t0), ("cpu", time.process_time() - c0), ("encode", t2 - t1),
                             ("render", t1 - t0 - drawn.stages.get("convert", 0.0) / 1e3),
                             ("convert", drawn.stages.get("convert", 0.0) / 1e3)):
                    t[k].append(x * 1e3)
            rows.append({"width": sz[0], "height": lines, "supersample": ss,
                         "format": "png" if quality is None else f"jpeg{quality}",
                         **{f"{k}_ms": float(np.median(x[n:])) for k, x in t.items()}})
    finally:
        worker.close()
    return rows


def segments(frames: list[dict]) -> list[list[dict]]:
    """The moving frames split into drags (a gap of more than SEGMENT_GAP_S between two)."""
    mv = sorted((f for f in frames if f["moving"]), key=lambda f: f["t"])
    out: list[list[dict]] = []
    for f in mv:
        if out and f["t"] - out[-1][-1]["t"] <= SEGMENT_GAP_S:
            out[-1].append(f)
        else:
            out.append([f])
    return [seg for seg in out if seg[-1]["t"] - seg[0]["t"] >= MIN_DRAG_S]


def _nanmedian(x) -> float:
    """Median ignoring NaN; NaN when every value is (no warning)."""
    x = np.asarray(x, float)
    x = x[~np.isnan(x)]
    return float(np.median(x)) if x.size else float("nan")


def _median(frames: list[dict], key: str) -> float:
    """Median of ``key`` over ``frames`` (NaN where no frame has it: a log of an older viewer)."""
    x = [f[key] for f in frames if key in f]
    return float(np.median(x)) if x else float("nan")


def summarise(frames: list[dict], size=SIZE, browser: list[dict] | None = None) -> dict:
    """Per drag (found from the log alone): fps and median lines of the moving frames (the first
    RAMP_S excluded) and their stages' median ms, seconds from the stop to the full-size and the
    supersampled frame (the viewer's own ``since_change_s``); with ``browser``, the page's rates
    of each drag (same order); medians over the drags."""
    rows = []
    for seg in segments(frames):
        mv = [f for f in seg if f["t"] >= seg[0]["t"] + RAMP_S]
        end = seg[-1]["t"]
        still = [f for f in frames if not f["moving"] and end < f["t"] <= end + SETTLE_S
                 and (f["width"], f["height"]) == tuple(size)]
        full = next((f for f in still if not f.get("refined")), None)
        ref = next((f for f in still if f.get("refined")), None)
        span = mv[-1]["t"] - mv[0]["t"]
        rows.append({"fps": (len(mv) - 1) / span if span > 0 else 0.0,
                     "lines": float(np.median([f["height"] for f in mv])),
                     "moving_ms": _median(mv, "total_ms"), "moving_cpu_ms": _median(mv, "cpu_ms"),
                     **{k: _median(mv, k) for k in STAGE_KEYS},
                     "full_s": full["since_change_s"] if full else float("nan"),
                     "full_ms": full["total_ms"] if full else float("nan"),
                     "full_cpu_ms": full.get("cpu_ms", float("nan")) if full else float("nan"),
                     "refined_s": ref["since_change_s"] if ref else float("nan"),
                     "level": mv[-1].get("level")})
    if not rows:
        raise RuntimeError("no drag found in the frame log (no moving frames)")
    med = {k: _nanmedian([r[k] for r in rows]) for k in rows[0] if k != "level"}
    med["level"] = rows[0]["level"]
    out = {"drags": rows, "median": med}
    if browser:
        out["browser"] = browser
        med.update({k: _nanmedian([b[k] for b in browser]) for k in browser[0]})
    return out


def _secs(x: float) -> str:
    """Seconds with 3 decimals, or "-" where there was no such frame (NaN)."""
    return "-" if np.isnan(x) else f"{x:.3f}"


def print_tables(r: dict) -> None:
    """The bench's tables: drags, their stages, the page's rates, the cost table."""
    m, (W, H) = r["median"], r["size"]
    print(f"furrow view, {r['driver']} driver, {W}x{H} view of {r['model']} (level L={m['level']})")
    print(f"load average before {r['load_before'][0]:.1f}, after {r['load_after'][0]:.1f} on {r['cpus']} cores")
    print(f"{'drag':>4} {'fps':>6} {'lines':>6} {'ms/frame':>9} {'cpu ms':>7} {'full s':>7} {'cpu ms':>7} "
          f"{'supersampled s':>15}")
    for i, d in enumerate(r["drags"]):
        print(f"{i:>4} {d['fps']:>6.1f} {d['lines']:>6.0f} {d['moving_ms']:>9.1f} {d['moving_cpu_ms']:>7.1f} "
              f"{d['full_s']:>7.3f} {d['full_cpu_ms']:>7.1f} {_secs(d['refined_s']):>15}")
    print("moving frames' stages, median wall ms per drag (queued, render = draw + read back, convert, send = "
          "encode + hand-off):")
    print(f"{'drag':>4} " + " ".join(f"{k[:-3]:>8}" for k in STAGE_KEYS) + f" {'total':>8}")
    for i, d in enumerate(r["drags"]):
        print(f"{i:>4} " + " ".join(f"{d[k]:>8.1f}" for k in STAGE_KEYS) + f" {d['moving_ms']:>8.1f}")
    for i, b in enumerate(r.get("browser", [])):
        if i == 0:
            print("in the page, per drag: server frames received / decoded per second, median decode ms, "
                  "frames drawn per second; cores used by the viewer and the browser, browser CPU ms per drawn frame")
            print(f"{'drag':>4} {'recv fps':>9} {'decoded fps':>12} {'decode ms':>10} {'drawn fps':>10} "
                  f"{'viewer cores':>13} {'browser cores':>14} {'browser ms/frame':>17}")
        print(f"{i:>4} {b['received_fps']:>9.1f} {b['decoded_fps']:>12.1f} {b['decode_ms']:>10.1f} "
              f"{b['drawn_fps']:>10.1f} {b.get('viewer_cores', np.nan):>13.2f} {b.get('browser_cores', np.nan):>14.2f} "
              f"{b.get('browser_cpu_ms_per_drawn', np.nan):>17.1f}")
    if not r["costs"]:
        return
    print("whole-frame cost (render = draw + read back, convert, encode), medians over orbit views:")
    print(f"{'size':>9} {'samples':>7} {'format':>7} {'wall ms':>8} {'render':>7} {'convert':>8} {'encode':>7} "
          f"{'CPU ms':>7} {'fps if CPU-bound':>17}")
    for c in r["costs"]:
        print(f"{c['width']:>4}x{c['height']:<4} {c['supersample']:>7} {c['format']:>7} {c['wall_ms']:>8.1f} "
              f"{c['render_ms']:>7.1f} {c['convert_ms']:>8.1f} {c['encode_ms']:>7.1f} {c['cpu_ms']:>7.1f} "
              f"{1000 / c['cpu_ms']:>17.1f}")


def parse_size(text: str) -> tuple[int, int]:
    """``WxH`` -> (W, H) (argparse type)."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WxH (e.g. 960x720), got {text!r}") from None
    if w < 16 or h < 16:
        raise argparse.ArgumentTypeError(f"size must be at least 16x16, got {text!r}")
    return w, h


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="furrow bench view", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--driver", choices=("server", "browser"), default="server")
    ap.add_argument("--model", type=Path, default=None, help="model folder (default: build the 18-view fur model)")
    ap.add_argument("--size", type=parse_size, default=SIZE,
                    help=f"the view dragged, WxH (default {SIZE[0]}x{SIZE[1]}: issue 32's browser tab)")
    ap.add_argument("--drag-s", type=float, default=4.0, help="seconds per drag (default 4)")
    ap.add_argument("--repeats", type=int, default=3, help="drags (default 3)")
    ap.add_argument("--costs", action=argparse.BooleanOptionalAction, default=True,
                    help="measure the whole-frame cost table after the drags (default: yes)")
    ap.add_argument("-o", "--out", type=Path, default=OUT_ROOT / "bench" / "view")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    model_dir = args.model or build_model(args.out)
    from render.viewer.gl_worker import llvmpipe_threads
    from volume.model import load_model

    load0 = os.getloadavg()
    browser = None
    with llvmpipe_threads():  # in-process GL as the viewer runs it
        if args.driver == "server":
            frames = drive_server(load_model(model_dir), args.drag_s, args.repeats, args.size)
        else:
            frames, browser = drive_browser(model_dir, args.drag_s, args.repeats, args.out, args.size)
        costs = cost_table(load_model(model_dir), args.size) if args.costs else []
    res = {"driver": args.driver, "model": str(model_dir), "size": list(args.size), "load_before": list(load0),
           "load_after": list(os.getloadavg()), "cpus": os.cpu_count(), **summarise(frames, args.size, browser),
           "costs": costs}
    write_json(args.out / f"bench_view_{args.driver}.json", {**res, "frames": frames})
    m = res["median"]
    ok = (m["fps"] >= TARGET_FPS and m["lines"] >= TARGET_LINES, m["full_s"] <= TARGET_STILL_S)
    W, H = args.size
    return print_result(res, args.json, print_tables,
                        f"median while dragging: {m['fps']:.1f} fps at {m['lines']:.0f} lines "
                        f"(target >= {TARGET_FPS:g} fps at >= {TARGET_LINES} lines): {'met' if ok[0] else 'NOT met'}",
                        f"median stop -> full {W}x{H} frame: {m['full_s']:.3f} s "
                        f"(target <= {TARGET_STILL_S} s): {'met' if ok[1] else 'NOT met'}")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
