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
    its number."""
    pattern = STILL_TEXT.format(w=width, h=height, s=samples)
    handle = page.wait_for_function(
        "([p, n]) => { const m = document.body.innerText.match(new RegExp(p)); "
        "return m && parseInt(m[1]) > n ? parseInt(m[1]) : null; }", arg=[pattern, after],
        timeout=timeout_s * 1000)
    return int(handle.json_value())


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


def drag(page, seconds: float, x0: float, y0: float, radius: float = 120.0, steps_per_s: float = 60.0) -> int:
    """Orbit by dragging the mouse in circles around (x0, y0) for ``seconds``; returns the moves made."""
    import math

    page.mouse.move(x0 + radius, y0)
    page.mouse.down()
    n = int(seconds * steps_per_s)
    t0 = time.monotonic()
    for i in range(n):
        a = 2 * math.pi * i / (steps_per_s * 2.0)
        page.mouse.move(x0 + radius * math.cos(a), y0 + 0.3 * radius * math.sin(a))
        wait = t0 + (i + 1) / steps_per_s - time.monotonic()
        if wait > 0:
            time.sleep(wait)
    page.mouse.up()
    return n


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
