"""Driving ``furrow view`` in a real headless browser: Debian's chromium through Playwright
(shared docs/pitfalls.md "Added after the first release": Playwright's own browser download cannot work
here; SwiftShader gives the page WebGL).  Used by the viewer's tests and ``furrow bench view``."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

#: Chromium flags: software WebGL (SwiftShader through ANGLE) on a machine without a GPU.
CHROMIUM_ARGS = ("--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader")
#: viser's default vertical field of view of a new client (radians; 75 degrees in viser 1.1.1).
VISER_DEFAULT_FOV = 1.3089969389957472
#: Seconds to wait for the server's URL, the page's first frame, a still frame.
START_TIMEOUT_S = 120.0
FRAME_TIMEOUT_S = 240.0
#: The readout line that says a full frame with these samples per pixel was shown (the still
#: frames' count before the colon).
STILL_TEXT = r"still #(\d+): {w}x{h}, {s}x{s} samples"
#: An init script counting, in the page, the server frames the viewer received and decoded, and
#: the frames the page drew: viser's client makes each background image a blob URL
#: (URL.createObjectURL), decodes it as an image and revokes the URL once it is loaded
#: (MessageHandler.tsx loadBackgroundTexture), so the time between the two is the browser's decode
#: (waiting for its main thread included); a drawn frame is an animation frame in which WebGL drew.
FRAME_COUNTERS_JS = """
(() => {
  const f = window.__furrowCounters = {received: 0, decoded: 0, decode_ms: [], drawn: 0};
  const born = new Map();
  const create = URL.createObjectURL, revoke = URL.revokeObjectURL;
  URL.createObjectURL = function (obj) {
    const url = create.call(URL, obj);
    if (obj instanceof Blob && obj.type.startsWith('image/')) { born.set(url, performance.now()); f.received += 1; }
    return url;
  };
  URL.revokeObjectURL = function (url) {
    const t0 = born.get(url);
    if (t0 !== undefined) { born.delete(url); f.decoded += 1; f.decode_ms.push(performance.now() - t0); }
    return revoke.call(URL, url);
  };
  let drew = false;
  for (const proto of [WebGLRenderingContext.prototype, WebGL2RenderingContext.prototype]) {
    for (const name of ['drawElements', 'drawArrays', 'drawElementsInstanced', 'drawArraysInstanced']) {
      const g = proto[name];
      if (g) proto[name] = function (...a) { drew = true; return g.apply(this, a); };
    }
  }
  const tick = () => { if (drew) { f.drawn += 1; drew = false; } requestAnimationFrame(tick); };
  requestAnimationFrame(tick);
})();
"""


def find_chromium() -> str | None:
    """Path of a Chromium executable (Debian's ``chromium``), or None."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        p = shutil.which(name)
        if p:
            return p
    return None


def skip_reason() -> str | None:
    """Why a real-browser check cannot run here (no Playwright, no Chromium), or None."""
    try:
        import playwright  # noqa: F401
    except ImportError:
        return "playwright is not installed (pip install -e .[dev])"
    if find_chromium() is None:
        return "no chromium executable (apt-get install --no-install-recommends chromium)"
    return None


def launch(playwright, headless: bool = True):
    """A Chromium browser (Debian's) with software WebGL."""
    exe = find_chromium()
    if exe is None:
        raise RuntimeError("no chromium executable found (apt-get install --no-install-recommends chromium)")
    return playwright.chromium.launch(executable_path=exe, headless=headless, args=list(CHROMIUM_ARGS))


def view_url(base: str, eye, target, up) -> str:
    """The viewer's URL with a fixed first camera (viser's initialCamera* parameters) and a fixed
    device pixel ratio: viser's client otherwise drops its canvas to 75 % resolution when its own
    frame rate is low (SwiftShader), and reports that smaller size as the camera's image size."""
    fmt = lambda v: ",".join(f"{float(x):.6f}" for x in v)
    return (f"{base}/?initialCameraPosition={fmt(eye)}&initialCameraLookAt={fmt(target)}"
            f"&initialCameraUp={fmt(up)}&fixedDpr=1")


class ViewProcess:
    """``furrow view`` as a subprocess (``python -m furrow view ...``); ``url`` once serving."""

    def __init__(self, model, *extra, cwd=None, env=None) -> None:
        cmd = [sys.executable, "-m", "furrow", "view", str(model), "--port", "0", *map(str, extra)]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd,
                                     env={**os.environ, **(env or {})})
        self.url = self._read_url()

    def _read_url(self) -> str:
        t0 = time.monotonic()
        while time.monotonic() - t0 < START_TIMEOUT_S:
            line = self.proc.stdout.readline()
            if line.startswith("http://"):
                return line.strip()
            if not line and self.proc.poll() is not None:
                raise RuntimeError(f"furrow view exited with {self.proc.returncode}: {self.proc.stderr.read()}")
        raise TimeoutError("furrow view printed no URL")

    def interrupt(self, timeout: float = 60.0) -> tuple[int, str]:
        """Ctrl-C (SIGINT); returns (exit code, stderr)."""
        self.proc.send_signal(signal.SIGINT)
        _, err = self.proc.communicate(timeout=timeout)
        return self.proc.returncode, err

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.communicate()


def wait_still(page, width: int, height: int, samples: int, after: int = 0,
               timeout_s: float = FRAME_TIMEOUT_S) -> int:
    """Wait until the page's readout reports a full ``width`` x ``height`` frame with ``samples``
    x ``samples`` samples per pixel that is still frame number ``after + 1`` or later; returns
    its number.  The readout is read as ``textContent``, so it is seen while :func:`hide_overlays`
    hides it (``innerText`` leaves hidden text out)."""
    pattern = STILL_TEXT.format(w=width, h=height, s=samples)
    handle = page.wait_for_function(
        "([p, n]) => { const m = document.body.textContent.match(new RegExp(p)); "
        "return m && parseInt(m[1]) > n ? parseInt(m[1]) : null; }", arg=[pattern, after],
        timeout=timeout_s * 1000)
    return int(handle.json_value())


def still_number(page) -> int:
    """The number of the last still frame the page's readout reports (0: none yet), read as
    :func:`wait_still` reads it."""
    pattern = STILL_TEXT.format(w=r"\d+", h=r"\d+", s=r"\d+")
    return int(page.evaluate("(p) => { const m = document.body.textContent.match(new RegExp(p)); "
                             "return m ? parseInt(m[1]) : 0; }", pattern))


def wait_opaque(page, timeout_s: float = FRAME_TIMEOUT_S) -> None:
    """Wait until viser's canvases have faded in (they start translucent over a white page)."""
    page.wait_for_function("() => [...document.querySelectorAll('canvas')]"
                           ".every(c => getComputedStyle(c).opacity === '1')", timeout=timeout_s * 1000)


def hide_overlays(page) -> None:
    """Uncheck the capture-camera frustums and hide viser's panel and notifications, so that a
    screenshot shows the server's picture alone."""
    page.get_by_text("show capture cameras").click()
    page.add_style_tag(content=".mantine-Paper-root, .mantine-Notification-root, "
                               "[class*='Notification'] { visibility: hidden !important; }")


def drag(page, seconds: float, x0: float, y0: float, radius: float = 120.0, steps_per_s: float = 60.0,
         on_ramp=None, ramp_s: float = 0.0) -> int:
    """Orbit by dragging the mouse in circles around (x0, y0) for ``seconds``; returns the moves made.
    ``on_ramp()`` is called once, ``ramp_s`` seconds into the drag (e.g. :func:`frame_counters`)."""
    import math

    page.mouse.move(x0 + radius, y0)
    page.mouse.down()
    n = int(seconds * steps_per_s)
    t0 = time.monotonic()
    for i in range(n):
        a = 2 * math.pi * i / (steps_per_s * 2.0)
        page.mouse.move(x0 + radius * math.cos(a), y0 + 0.3 * radius * math.sin(a))
        if on_ramp is not None and time.monotonic() - t0 >= ramp_s:
            on_ramp()
            on_ramp = None
        wait = t0 + (i + 1) / steps_per_s - time.monotonic()
        if wait > 0:
            time.sleep(wait)
    page.mouse.up()
    return n


def frame_counters(page) -> dict:
    """The page's FRAME_COUNTERS_JS counts now: ``t`` (page clock, s), ``received`` and ``decoded``
    server frames, ``decode_ms`` (each decoded frame's), ``drawn`` animation frames."""
    c = page.evaluate("() => ({...window.__furrowCounters, t: performance.now() / 1000})")
    return {**c, "decode_ms": list(c["decode_ms"])}


def _proc_stat(pid: int) -> tuple[int, float] | None:
    """(parent pid, CPU seconds: user + system of every thread) of a live process (Linux /proc)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return int(fields[1]), (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def process_cpu(viewer_pid: int) -> dict:
    """CPU seconds so far of the ``furrow view`` process (``viewer``) and of the chromium processes
    under this one (``browser``: the page's renderer, GPU (SwiftShader) and other processes);
    ``t`` its wall time (s).  Empty on a system without /proc."""
    if not Path("/proc/self/stat").exists():
        return {}
    stats = {int(d.name): _proc_stat(int(d.name)) for d in Path("/proc").iterdir() if d.name.isdigit()}
    children: dict[int, list[int]] = {}
    for pid, st in stats.items():
        if st is not None:
            children.setdefault(st[0], []).append(pid)
    browser, todo = 0.0, list(children.get(os.getpid(), []))
    while todo:
        pid = todo.pop()
        todo += children.get(pid, [])
        try:
            exe = Path(f"/proc/{pid}/exe").resolve().name
        except OSError:
            continue
        if pid != viewer_pid and "chrom" in exe and stats.get(pid):
            browser += stats[pid][1]
    own = stats.get(viewer_pid)
    return {"t": time.monotonic(), "viewer": own[1] if own else float("nan"), "browser": browser}


def counter_rates(start: dict, end: dict) -> dict:
    """Per second between two :func:`frame_counters` snapshots: frames ``received``, ``decoded``
    and ``drawn`` by the page, and the median ``decode_ms`` of the frames decoded in between; with
    :func:`process_cpu` readings under ``"cpu"`` in both, the cores the viewer and the browser
    used (``viewer_cores``, ``browser_cores``) and the browser's CPU ms per frame it drew."""
    import numpy as np

    dt = max(end["t"] - start["t"], 1e-9)
    dec = end["decode_ms"][len(start["decode_ms"]):]
    out = {"received_fps": (end["received"] - start["received"]) / dt,
           "decoded_fps": (end["decoded"] - start["decoded"]) / dt,
           "drawn_fps": (end["drawn"] - start["drawn"]) / dt,
           "decode_ms": float(np.median(dec)) if dec else float("nan")}
    c0, c1 = start.get("cpu") or {}, end.get("cpu") or {}
    if c0 and c1:
        wall = max(c1["t"] - c0["t"], 1e-9)
        out["viewer_cores"] = (c1["viewer"] - c0["viewer"]) / wall
        out["browser_cores"] = (c1["browser"] - c0["browser"]) / wall
        drawn = end["drawn"] - start["drawn"]
        out["browser_cpu_ms_per_drawn"] = 1e3 * (c1["browser"] - c0["browser"]) / drawn if drawn else float("nan")
    return out


def save_screenshot(page, path: Path) -> None:
    page.screenshot(path=str(path))


# ---------------------------------------------------------------------------- static pages (furrow export --web)
#: Seconds to wait for a static file server to answer.
SERVE_TIMEOUT_S = 30.0
#: Counts the frames in which the page drew with WebGL (an instanced draw call between two
#: animation frames): the page's own frame rate, not the browser's idle 60 Hz ticks.
FRAME_COUNTER_JS = """
(() => {
  window.__furrowFrames = 0; let drew = false;
  const proto = WebGL2RenderingContext.prototype;
  for (const name of ['drawElementsInstanced', 'drawArraysInstanced']) {
    const f = proto[name];
    proto[name] = function (...a) { drew = true; return f.apply(this, a); };
  }
  const tick = () => { if (drew) { window.__furrowFrames += 1; drew = false; } requestAnimationFrame(tick); };
  requestAnimationFrame(tick);
})();
"""


class StaticServer:
    """``python -m http.server`` serving ``folder`` on a free local port (a subprocess, nothing of
    furrow); ``url`` once it answers; ``close()`` ends it."""

    def __init__(self, folder) -> None:
        import socket
        import urllib.request

        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            self.port = s.getsockname()[1]
        self.proc = subprocess.Popen([sys.executable, "-m", "http.server", str(self.port), "--bind", "127.0.0.1",
                                      "--directory", str(folder)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.url = f"http://127.0.0.1:{self.port}"
        t0 = time.monotonic()
        while True:
            try:
                urllib.request.urlopen(self.url, timeout=2).close()
                return
            except OSError:
                if time.monotonic() - t0 > SERVE_TIMEOUT_S or self.proc.poll() is not None:
                    self.close()
                    raise RuntimeError(f"the static server on {self.url} did not answer") from None
                time.sleep(0.2)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(10)


def offline(page, allowed: str) -> list:
    """Abort every request of ``page`` that does not go to ``allowed`` (a URL prefix); returns the
    list the aborted URLs are appended to (the page must need none of them)."""
    blocked = []

    def route(r):
        if r.request.url.startswith(allowed) or r.request.url.startswith(("data:", "blob:")):
            r.continue_()
        else:
            blocked.append(r.request.url)
            r.abort()

    page.route("**/*", route)
    return blocked


def open_offline_page(browser, url: str, width: int, height: int):
    """A ``width`` x ``height`` page on ``url`` that counts its WebGL frames (FRAME_COUNTER_JS) and
    may reach nothing else, once it drew its first frame; returns (page, blocked URLs)."""
    page = browser.new_page(viewport={"width": width, "height": height})
    page.add_init_script(FRAME_COUNTER_JS)
    blocked = offline(page, url)
    page.goto(url + "/")
    page.wait_for_function("() => window.__furrowFrames > 0", timeout=FRAME_TIMEOUT_S * 1000)
    return page, blocked


def frame_rate(page, seconds: float, x0: float, y0: float, radius: float = 120.0, steps_per_s: float = 30.0) -> float:
    """Frames per second the page drew while the mouse orbits for ``seconds`` of wall time (moves
    on a circle around (x0, y0), at most ``steps_per_s``; a slow page gets fewer moves, never a
    longer drag); needs FRAME_COUNTER_JS as an init script."""
    import math

    page.mouse.move(x0 + radius, y0)
    page.mouse.down()
    n0 = page.evaluate("window.__furrowFrames")
    t0 = time.monotonic()
    i = 0
    while time.monotonic() - t0 < seconds:
        i += 1
        a = 2 * math.pi * i / (2.0 * steps_per_s)
        page.mouse.move(x0 + radius * math.cos(a), y0 + 0.3 * radius * math.sin(a))
        wait = t0 + i / steps_per_s - time.monotonic()
        if wait > 0:
            time.sleep(wait)
    n1 = page.evaluate("window.__furrowFrames")
    elapsed = time.monotonic() - t0
    page.mouse.up()
    return (n1 - n0) / elapsed


def page_scores(shot, C, A, mask_level: float = 24.0) -> tuple[float, float]:
    """(silhouette IoU, masked PSNR dB) of a page's screenshot (H, W, 3) uint8 against a render's
    display colour ``C`` (H, W, 3, premultiplied) and alpha ``A`` (H, W) blended over the page's
    background (its top-centre pixel) in display values, as a splat viewer blends: the silhouettes
    are the pixels more than ``mask_level`` (8-bit) from the background, the PSNR is over their union."""
    import numpy as np

    h, w = shot.shape[:2]
    bg = shot[2, w // 2].astype(np.float64) / 255.0
    ref = np.clip(C + (1.0 - A)[..., None] * bg, 0, 1) * 255.0
    s = shot.astype(np.float64)
    ms = np.abs(s - bg * 255.0).max(-1) > mask_level
    mr = np.abs(ref - bg * 255.0).max(-1) > mask_level
    union = ms | mr
    iou = float((ms & mr).sum() / max(union.sum(), 1))
    mse = float(np.mean((s[union] - np.round(ref[union])) ** 2)) if union.any() else 255.0 ** 2
    return iou, float(10 * np.log10(255.0 ** 2 / max(mse, 1e-9)))
