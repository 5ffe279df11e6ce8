"""A viewer client's render thread (render.viewer.session) against a simulated renderer: reduced
frames while the camera moves, the full then the supersampled frame after the stop, stale work
dropped, the latest camera drawn, failures reported."""

from __future__ import annotations

import threading
import time
from concurrent.futures import Future
from types import SimpleNamespace

import numpy as np
import pytest

from render.viewer import views
from render.viewer.adaptive import AdaptiveConfig
from render.viewer.session import FrameLog, Session, ViewCamera
from render.viewer.settings import ViewSettings

FULL = (320, 240)


class Stats(SimpleNamespace):
    def record(self):
        return {"ms": self.ms, "supersample": self.supersample}


class FakeWorker:
    """Runs jobs on one thread like render.viewer.gl_worker.GLWorker."""

    def __init__(self):
        self.jobs = []
        self.cv = threading.Condition()
        self.closed = False
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def submit(self, fn, wanted=None):
        fut = Future()
        with self.cv:
            self.jobs.append((fn, fut))
            self.cv.notify()
        return fut

    def _run(self):
        while True:
            with self.cv:
                while not self.jobs and not self.closed:
                    self.cv.wait()
                if self.closed:
                    return
                fn, fut = self.jobs.pop(0)
            try:
                fut.set_result(fn(None))
            except Exception as e:
                fut.set_exception(e)

    def close(self):
        with self.cv:
            self.closed = True
            self.cv.notify()


def view(i: int) -> ViewCamera:
    a = 0.05 * i
    return ViewCamera((np.cos(a / 2), 0.0, 0.0, np.sin(a / 2)), (0.0, 0.0, -1.0), 0.8, *FULL)


class DrawLog(list):
    """The (camera, supersample) of each fake draw, and ``drafts``: whether each was a draft."""

    def __init__(self):
        super().__init__()
        self.drafts = []


@pytest.fixture
def fake_draw(monkeypatch):
    """draw() costing 4 ms + 0.5 ms per 1000 pixels x samples^2 (a full 320x240 frame: ~42 ms,
    supersampled 2x2: ~158 ms); records the cameras it draws (when it starts each), and in
    ``drawn.drafts`` whether each was a draft (RenderOptions.draft)."""
    drawn = DrawLog()

    def draw(scene, camera, settings, supersample, draft=False):
        ms = 4.0 + 0.5e-3 * camera.width * camera.height * supersample ** 2
        drawn.append((camera, supersample))
        drawn.drafts.append(draft)
        time.sleep(ms / 1e3)
        return views.Drawn(np.zeros((camera.height, camera.width, 3), np.uint8), Stats(ms=ms, supersample=supersample))

    monkeypatch.setattr(views, "draw", draw)
    return drawn


#: Settings of a method that reads the supersampling option (its still frame is refined).
SUPERSAMPLED = ViewSettings(method="microfacet")


def run_session(moves, cfg, settle_s=1.0, interval_s=1 / 60, settings=SUPERSAMPLED, sent=None):
    worker, log, sent = FakeWorker(), FrameLog(), [] if sent is None else sent
    s = Session(worker, lambda img, q: sent.append((img.shape, q)), settings, cfg, log).start()
    for i in range(moves):
        s.update_camera(view(i))
        time.sleep(interval_s)
    t_stop = log.now()
    time.sleep(settle_s)
    s.stop()
    worker.close()
    return log.frames(), t_stop, s


def test_moving_then_full_then_supersampled(fake_draw):
    cfg = AdaptiveConfig(target_fps=40.0, still_s=0.2)          # 25 ms budget: a full frame (42 ms) does not fit
    frames, t_stop, _ = run_session(60, cfg)
    moving = [f for f in frames if f["moving"]]
    assert len(moving) >= 10
    late = moving[len(moving) // 2:]
    assert all(f["width"] < FULL[0] and f["supersample"] == 1 for f in late)
    assert np.median([f["total_ms"] for f in late]) <= 1.3 * cfg.budget_ms
    still = [f for f in frames if not f["moving"]]
    assert [(f["width"], f["height"], f["supersample"]) for f in still] == [(*FULL, 1), (*FULL, 2)]
    assert still[0]["t"] >= t_stop + cfg.still_s - 0.02          # not before the camera was still
    assert still[0]["since_change_s"] < cfg.still_s + 0.3         # full frame soon after the stop
    assert still[1]["refined"] and not still[0]["refined"]
    # the moving frames are drafts (gather leaves its second layer out), the still ones are not
    sizes = [(c.width, s) for c, s in fake_draw]
    assert [d for (w, s), d in zip(sizes, fake_draw.drafts) if w == FULL[0]] == [False, False]
    assert all(fake_draw.drafts[i] for i, (w, _) in enumerate(sizes) if w < FULL[0])


def test_one_sample_method_sends_its_full_frame_once_as_png(fake_draw):
    """gather reads no supersampling option: the full frame after the stop is the last one (PNG),
    not drawn again as a 'supersampled' frame that would be the same picture."""
    cfg = AdaptiveConfig(target_fps=40.0, still_s=0.2)
    sent = []
    frames, _, _ = run_session(20, cfg, settings=ViewSettings(method="gather"), sent=sent)
    still = [f for f in frames if not f["moving"]]
    assert [(f["width"], f["height"], f["supersample"], f["refined"]) for f in still] == [(*FULL, 1, False)]
    assert sent[-1] == ((FULL[1], FULL[0], 3), None)


def test_cheap_frames_grow_to_full_size(fake_draw):
    cfg = AdaptiveConfig(target_fps=5.0)                          # 200 ms budget: everything fits
    frames, _, _ = run_session(40, cfg)
    assert [f for f in frames if f["moving"]][-1]["width"] == FULL[0]


#: Seconds a test waits for an event of the session before failing (generous: a loaded machine).
WAIT_S = 60.0


class FakeClock:
    """A session's clock that moves only when told: the session's decisions (moving, full,
    supersampled) then depend on the order of events, not on how fast the machine runs them."""

    def __init__(self):
        self.t = 0.0
        self.lock = threading.Lock()

    def __call__(self) -> float:
        with self.lock:
            return self.t

    def advance(self, s: float) -> None:
        with self.lock:
            self.t += s


class Frames:
    """The frames a session sent (on_frame records), waited for one by one."""

    def __init__(self):
        self.records, self.cv = [], threading.Condition()

    def __call__(self, rec: dict) -> None:
        with self.cv:
            self.records.append(rec)
            self.cv.notify_all()

    def wait(self, n: int) -> list[dict]:
        with self.cv:
            assert self.cv.wait_for(lambda: len(self.records) >= n, WAIT_S), f"{len(self.records)} of {n} frames"
            return list(self.records)


def which_view(camera) -> int:
    """Index i of the view(i) a drawn camera shows (the pose does not depend on the frame size)."""
    hits = [i for i in range(6) if np.allclose(camera.cam_from_world, view(i).camera(*FULL).cam_from_world)]
    assert len(hits) == 1, hits
    return hits[0]


def test_stale_full_frame_is_dropped_and_latest_camera_drawn(monkeypatch):
    """A move while the supersampled frame is drawn: that frame never goes out, and the next
    frame shows the newest camera, not the ones queued meanwhile.  Deterministic: the session runs
    on a clock that moves only when the test (or a draw, by its simulated cost) moves it, and the
    supersampled draw is held on an event until the test has moved the camera five times, so every
    decision of the session is the same however loaded the machine is; the whole sequence of
    frames drawn and sent is checked."""
    clock, frames = FakeClock(), Frames()
    started, release = threading.Event(), threading.Event()
    drawn = []

    def draw(scene, camera, settings, supersample, draft=False):
        drawn.append((which_view(camera), camera.width, supersample))
        clock.advance(0.005 * supersample ** 2)              # the draw's simulated cost (s)
        if supersample == 2 and not release.is_set():
            started.set()
            assert release.wait(WAIT_S)
        return views.Drawn(np.zeros((camera.height, camera.width, 3), np.uint8), Stats(ms=1.0, supersample=supersample))

    monkeypatch.setattr(views, "draw", draw)
    cfg = AdaptiveConfig(still_s=0.2)
    still = 10 * cfg.still_s                                  # a stop: well past still_s and the moving pace
    worker, log = FakeWorker(), FrameLog()
    s = Session(worker, lambda img, q: None, SUPERSAMPLED, cfg, log, on_frame=frames, clock=clock).start()
    try:
        s.update_camera(view(0))
        assert frames.wait(1)[0]["moving"]                    # the clock stands: one moving frame, then it waits
        clock.advance(still)                                  # the camera stops: full, then supersampled
        assert started.wait(WAIT_S), "the supersampled frame never started"
        for i in range(1, 6):                                 # moves during the supersampled frame
            s.update_camera(view(i))
        release.set()
        assert frames.wait(3)[2]["moving"]                    # the stale frame dropped, a moving frame drawn
        clock.advance(still)                                  # stops again
        sent = frames.wait(5)
    finally:
        s.stop()
        worker.close()
    assert [(v, ss) for v, _, ss in drawn] == [(0, 1), (0, 1), (0, 2), (5, 1), (5, 1), (5, 2)]
    assert drawn[3][1] < FULL[0] and drawn[4][1] == FULL[0]   # jumped to the newest, as a moving frame
    assert [(f["moving"], f.get("refined"), f["supersample"]) for f in sent] == [
        (True, None, 1), (False, False, 1), (True, None, 1), (False, False, 1), (False, True, 2)]
    supersampled = [f for f in log.frames() if f["supersample"] == 2]
    assert len(supersampled) == 1                             # the stale one was dropped


def test_failed_frame_is_reported_and_serving_goes_on(monkeypatch):
    notes, noted, framed = [], threading.Event(), threading.Event()
    calls = []

    def draw(scene, camera, settings, supersample, draft=False):
        calls.append(1)
        if len(calls) == 1:
            raise RuntimeError("boom")
        return views.Drawn(np.zeros((camera.height, camera.width, 3), np.uint8), Stats(ms=1.0, supersample=1))

    monkeypatch.setattr(views, "draw", draw)
    worker, log = FakeWorker(), FrameLog()
    s = Session(worker, lambda img, q: None, ViewSettings(), AdaptiveConfig(still_s=0.05), log,
                on_note=lambda m: (notes.append(m), noted.set()), on_frame=lambda rec: framed.set()).start()
    try:
        s.update_camera(view(0))
        assert noted.wait(WAIT_S)
        s.update_camera(view(1))
        assert framed.wait(WAIT_S)
    finally:
        s.stop()
        worker.close()
    assert notes and "boom" in notes[0]
    assert log.frames()


def test_send_failure_is_survived(fake_draw):
    """A client that went away (send raises) does not end the thread with an exception: it says
    so and goes on (tries the frame again)."""
    notes, again = [], threading.Event()

    def send(img, q):
        raise ConnectionError("client gone")

    def note(msg):
        notes.append(msg)
        if len(notes) >= 2:
            again.set()

    worker = FakeWorker()
    s = Session(worker, send, ViewSettings(), AdaptiveConfig(still_s=0.05), FrameLog(), on_note=note).start()
    s.update_camera(view(0))
    assert again.wait(WAIT_S)                                     # a second try after the first failure
    assert s.alive
    s.stop()
    worker.close()
    assert not s.alive and all("client gone" in n for n in notes)


def test_full_size_cap():
    vc = ViewCamera((1.0, 0, 0, 0), (0, 0, 0), 0.8, 1920, 1080)
    assert vc.full_size(720) == (1280, 720)
    assert vc.full_size(2000) == (1920, 1080)


def test_transport_quality():
    from render.viewer.session import FULL_JPEG_QUALITY, MOVING_JPEG_QUALITY, transport_quality

    ss2, ss1 = SUPERSAMPLED, SUPERSAMPLED.changed(options={"supersample": 1})
    assert transport_quality("moving", ss2) == MOVING_JPEG_QUALITY
    assert transport_quality("full", ss2) == FULL_JPEG_QUALITY   # a PNG follows
    assert transport_quality("full", ss1) is None                # the last still frame: PNG
    assert transport_quality("refine", ss2) is None
    assert transport_quality("full", ViewSettings(method="gather")) is None  # one sample: nothing follows


@pytest.mark.parametrize("method,greyed,shown", [("gather", {"supersampling"}, set()),
                                                 ("microfacet", set(), {"tolerance E (px)", "refine steps"}),
                                                 ("mesh-vdtm", set(), set())])
def test_option_controls_follow_the_method(method, greyed, shown):
    """The panel is made from the specs: the shared supersampling control (greyed for a method that
    draws one sample per pixel) and each method's own controls, shown only while it is chosen; the
    settings it builds carry what the controls show."""
    from render.methods import METHODS
    from render.viewer import gui
    from tests.render.viewer.fake_gui import FakeGui

    fake = FakeGui()
    controls = gui.build_controls(fake, ViewSettings(), METHODS)
    assert fake.handles["method"].options == tuple(METHODS)
    applied = []
    gui.on_settings_change(controls, applied.append, lambda msg: None)
    fake.handles["method"].set(method)
    own = {c.handle.label for c in controls.options if c.method is not None and c.handle.visible}
    assert own == shown
    assert {c.handle.label for c in controls.options if c.handle.disabled} == greyed
    fake.handles["tolerance E (px)"].set(4.0)
    fake.handles["refine steps"].set(-1)
    st = applied[-1]
    assert st.method == method and st.options.of("microfacet").tolerance_px == 4.0
    assert st.options.of("microfacet").refine is None  # -1 = the method's default
    fake.handles["refine steps"].set(3)
    assert applied[-1].options.of("microfacet").refine == 3


def test_paused_session_draws_nothing_until_resumed(fake_draw):
    """Client-side splats pause the client's render thread: moves draw nothing; resuming draws
    the current view once more."""
    worker, log = FakeWorker(), FrameLog()
    s = Session(worker, lambda img, q: None, ViewSettings(method="gather"), AdaptiveConfig(still_s=0.05), log).start()
    s.update_camera(view(0))
    time.sleep(0.3)
    n = len(log.frames())
    assert n >= 1
    s.pause(True)
    for i in range(1, 10):
        s.update_camera(view(i))
        time.sleep(0.01)
    time.sleep(0.3)
    assert len(log.frames()) == n
    s.pause(False)
    time.sleep(0.4)
    s.stop()
    worker.close()
    after = log.frames()[n:]
    assert after and not after[-1]["moving"]
    np.testing.assert_allclose(fake_draw[-1][0].cam_from_world, view(9).camera(*FULL).cam_from_world)
