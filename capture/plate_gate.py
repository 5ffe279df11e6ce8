"""Whether each view's background plate beats doing nothing, and the plate refused where it does not
(issue 30; capture.plate.background_plates).

A plate is a prediction of the background behind the object from *other* frames (or from the user's
plate).  Where the background changed between frames (a person walked behind the plant, a door opened, a
screen played, the room's light went out), that prediction is wrong in the frames that differ, and a
matte that trusts it puts the difference into the object's colour and alpha: a wrong answer reported as a
plate.  The plate's own held-back error (each view's ring of background pixels just outside the matting
band, predicted from the other views only) says how wrong it is, but not against what.

Doing nothing is the matte estimated without a plate, which takes the background behind a partial pixel
from the view's own background nearby.  Its stand-in on the same ring is :func:`local_prediction`: each
ring pixel predicted by the mean of the view's own background pixels at least LOCAL_GAP_FRACTION of the
width beyond the ring, within LOCAL_WINDOW_FRACTION of it.  That predictor sees the view's real
background, whatever the other frames show, and it is generous (the estimate reaches further into a
crown than the gap), so a plate it beats on the ring is worth its keep.

A view's plate is refused (:func:`refused`) when it cannot beat that predictor on the ring: counted over
the ring pixels where either is off by more than DECISIVE_ERROR (elsewhere both are right within noise, and a
smooth or dark background predicts itself), the plate is the closer one in under GATE_MIN_WINS of them (a sign
test, as capture.plate_exposure's; at least GATE_MIN_PIXELS such pixels, else nothing is measured and the plate
is kept).  The views' RMS would not do: on the courtyard behind the path-traced conifer the local predictor's
RMS is 0.18-0.22 (the sunlit wall's edges), ten to a hundred times a right plate's and about a wrong one's.  A
refused view gets no plate: the matte estimates it as without plates, and the record and the console say
which views and why.  ``GATE = False`` is the rule before (every plate used).

The same test is counted in SECTORS angular sectors of the ring about the object (:func:`ring_sectors`), for a
background that changed behind one side only: a kept view's plate is dropped in the sectors it loses, a refused
view keeps it in the sectors it clearly wins (SECTOR_GATE, :func:`sectors_out`, :func:`without_sectors`).

A refused view's background is not the others' either, yet it lent them its pixels: on the path-traced orbit
whose room was shaded in 3 of 18 frames, the 3 views beside them, which borrow them as panorama neighbours,
were refused as well.  :func:`gated` therefore draws every plate once more without the refused views as
sources (:func:`without`: no panorama neighbour, no fixed-camera sample) and gates them again
(``DROP_SOURCES = False``: one round, the refused views still lending).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

#: Refuse plates that lose to the local predictor (True), else use every plate (the rule before).
GATE = True
#: The local predictor's pixels lie at least this fraction of the width beyond the held-back ring ...
LOCAL_GAP_FRACTION = 12 / 640
#: ... within a square window of this half-width (fraction of the width) around the ring pixel.
LOCAL_WINDOW_FRACTION = 24 / 640
#: The refused views lend the others nothing, the plates drawn again (True), else one round (:func:`gated`).
DROP_SOURCES = True
#: A ring pixel decides between the plate and the local predictor where either is off by more than this
#: (linear, the largest channel; about 8 8-bit steps at a mid grey) ...
DECISIVE_ERROR = 0.02
#: ... the plate must be the closer one at this share of the deciding pixels ...
GATE_MIN_WINS = 0.5
#: ... counted over at least this many of them (fewer: the plate is kept).
GATE_MIN_PIXELS = 100
#: Angular sectors of the ring about the object, counted apart (the record: where the plate fails) ...
SECTORS = 8
#: ... and the plate is kept or dropped sector by sector (True; False: the whole view only, the rule before):
#: a kept view loses it in the sectors it lost, a refused one keeps it in those it won (:func:`sectors_out`).
#: With the room shaded behind the crown's left half in 3 of 18 frames, refusing the whole view cost 1.3 dB
#: (turntable) and 0.5 dB (orbit) against using every plate; by sectors it gains 0.45 and 0.24 dB
#: (docs/matting.md "A background that changes between frames").
SECTOR_GATE = True
#: A sector is lost at under SECTOR_MIN_WINS of at least SECTOR_MIN_PIXELS deciding pixels; in a
#: refused view a sector keeps its plate only where it wins SECTOR_KEEP_WINS of them (a view that lost overall
#: needs more in a sector: another room behind two frames of a seeded turntable "passed" 2 of 8 sectors at
#: 51-68 %, its plate 0.22 off there; the unshaded sectors of the path-traced half-shaded frames won 83-100 %).
SECTOR_MIN_WINS = 0.5
SECTOR_KEEP_WINS = 0.75
SECTOR_MIN_PIXELS = 25


def local_prediction(linear: np.ndarray, object_depth: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """(N, 3) float64 each ring pixel's colour predicted from the view's own background (module
    docstring): the mean of ``linear`` over the pixels outside the object's depth grown by the source
    band, the ring and the gap, within the window; NaN rows where the window holds none.  ``ring``:
    (N, 2) int (x, y) (capture.plate.ring_pixels)."""
    import cv2

    from capture.matting_fast import dilate
    from capture.plate import RING_FRACTION, SOURCE_BAND_FRACTION, px

    ring = np.asarray(ring, np.int64).reshape(-1, 2)
    out = np.full((len(ring), 3), np.nan)
    if not len(ring):
        return out
    H, W = np.shape(object_depth)[:2]
    grow = px(SOURCE_BAND_FRACTION, W) + px(RING_FRACTION, W) + px(LOCAL_GAP_FRACTION, W)
    r = px(LOCAL_WINDOW_FRACTION, W)
    x0, y0 = max(0, ring[:, 0].min() - r), max(0, ring[:, 1].min() - r)
    x1, y1 = min(W, ring[:, 0].max() + r + 1), min(H, ring[:, 1].max() + r + 1)
    # the object grown on the box padded by the growth (pixels beyond the box cannot reach it)
    bx0, by0, bx1, by1 = max(0, x0 - grow), max(0, y0 - grow), min(W, x1 + grow), min(H, y1 + grow)
    obj = np.ascontiguousarray(np.asarray(object_depth)[by0:by1, bx0:bx1] > 0)
    far = ~dilate(obj, grow)[y0 - by0:y1 - by0, x0 - bx0:x1 - bx0]
    stack = np.empty((y1 - y0, x1 - x0, 4), np.float32)
    stack[..., :3] = np.asarray(linear[y0:y1, x0:x1], np.float32) * far[..., None]
    stack[..., 3] = far
    sums = cv2.boxFilter(stack, -1, (2 * r + 1, 2 * r + 1), normalize=False, borderType=cv2.BORDER_CONSTANT)
    s = sums[ring[:, 1] - y0, ring[:, 0] - x0].astype(np.float64)
    ok = s[:, 3] > 0.5
    out[ok] = s[ok, :3] / s[ok, 3:4]
    return out


def local_prediction_reference(linear: np.ndarray, object_depth: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """:func:`local_prediction` by brute force: the far pixels from scipy's dilation of the whole frame,
    each ring pixel's window summed in float64 (the test compares the two)."""
    from scipy import ndimage

    from capture.plate import RING_FRACTION, SOURCE_BAND_FRACTION, px

    H, W = np.shape(object_depth)[:2]
    grow = px(SOURCE_BAND_FRACTION, W) + px(RING_FRACTION, W) + px(LOCAL_GAP_FRACTION, W)
    r = px(LOCAL_WINDOW_FRACTION, W)
    far = ~ndimage.binary_dilation(np.asarray(object_depth) > 0, iterations=grow)
    lin = np.asarray(linear, np.float64)
    out = np.full((len(ring), 3), np.nan)
    for k, (x, y) in enumerate(np.asarray(ring, np.int64).reshape(-1, 2)):
        sl = (slice(max(0, y - r), y + r + 1), slice(max(0, x - r), x + r + 1))
        f = far[sl]
        if f.any():
            out[k] = lin[sl][f].mean(axis=0)
    return out


def refused(observed: np.ndarray, predicted: np.ndarray, local: np.ndarray,
            sector: np.ndarray | None = None) -> tuple[str | None, dict]:
    """(why the view's plate is refused or None when it is kept, the counts) from the ring's ``observed``
    colour, the plate's ``predicted`` one and the local predictor's ``local`` one (each (N, 3), NaN rows
    unknown; module docstring); ``sector``: (N,) int each ring pixel's angular sector about the object
    (:func:`ring_sectors`; the counts then hold each sector's [deciding, plate wins])."""
    from capture.plate import SENSOR_MAX

    o = np.asarray(observed, np.float64)
    ok = np.isfinite(predicted).all(axis=1) & np.isfinite(local).all(axis=1)
    ep = np.abs(np.minimum(np.asarray(predicted)[ok], SENSOR_MAX) - o[ok]).max(axis=1)
    el = np.abs(np.asarray(local)[ok] - o[ok]).max(axis=1)
    deciding = np.maximum(ep, el) > DECISIVE_ERROR
    n, wins = int(deciding.sum()), int((ep[deciding] < el[deciding]).sum())
    counts = {"deciding": n, "plate_wins": wins}
    if sector is not None:
        sec, won = np.asarray(sector)[ok][deciding], ep[deciding] < el[deciding]
        counts["sectors"] = [[int(a), int(b)] for a, b in zip(np.bincount(sec, minlength=SECTORS),
                                                             np.bincount(sec, won, minlength=SECTORS).astype(int))]
    if not GATE or n < GATE_MIN_PIXELS or wins >= GATE_MIN_WINS * n:
        return None, counts
    return (f"the plate is closer than the view's own nearby background at {wins} of {n} held-back pixels "
            f"(under {GATE_MIN_WINS:.0%})"), counts


def object_centre(object_depth: np.ndarray) -> np.ndarray:
    """(2,) (x, y) the centre of the object's depth pixels (the frame's centre without any)."""
    y, x = np.nonzero(np.asarray(object_depth) > 0)
    h, w = np.shape(object_depth)[:2]
    return np.array([x.mean(), y.mean()]) if len(y) else np.array([w / 2, h / 2])


def ring_sectors(points: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(N,) int the angular sector (0..SECTORS-1) of each pixel (x, y) of ``points`` (N, 2) about ``centre``."""
    r = np.asarray(points, np.float64).reshape(-1, 2) - np.asarray(centre, np.float64)
    ang = np.arctan2(r[:, 1], r[:, 0]) % (2 * np.pi)
    return np.minimum((ang / (2 * np.pi) * SECTORS).astype(np.int64), SECTORS - 1)


def failed_sectors(counts: dict) -> list[int]:
    """The sectors where the plate lost (SECTOR_GATE): at least SECTOR_MIN_PIXELS deciding pixels, the plate
    the closer one at under SECTOR_MIN_WINS of them."""
    return [k for k, (n, won) in enumerate(counts.get("sectors") or [])
            if n >= SECTOR_MIN_PIXELS and won < SECTOR_MIN_WINS * n]


def without_sectors(plate, bad: list[int], centre: np.ndarray):
    """The plate (capture.plate.Plate, cropped or not) with its known pixels in the sectors ``bad`` about
    ``centre`` unknown (the matte estimates the background there); its band shares as measured before."""
    y, x = np.nonzero(plate.known)
    y0, x0 = (0, 0) if plate.frame is None else plate.frame[2:]
    drop = np.isin(ring_sectors(np.stack([x + x0, y + y0], axis=1), centre), bad)
    known = plate.known.copy()
    known[y[drop], x[drop]] = False
    return replace(plate, known=known, estimated=None if plate.estimated is None else plate.estimated & known)


def empty(plate):
    """The plate with nothing known (the matte then estimates the view as without plates), its errors kept
    for the record."""
    none = dict(estimated=None, sigma=None, band_known=0.0, band_estimated=0.0, band_crossing=0.0)
    if plate.frame is None:  # a full-frame plate stays one (Plate.cropped may crop it later)
        return replace(plate, background=np.zeros((*plate.known.shape, 3), np.float32),
                       known=np.zeros(plate.known.shape, bool), **none)
    return replace(plate, background=np.zeros((0, 0, 3), np.float16), known=np.zeros((0, 0), bool),
                   frame=(*plate.frame[:2], 0, 0), **none)


def gate_plates(views, plates: list, local: list | None = None) -> tuple[list, list]:
    """(the plates with the refused ones emptied (:func:`empty`), per view (why its plate was refused or
    None, the counts)) (module docstring).  ``views``: per view (linear (H, W, 3), object depth (H, W),
    ring (N, 2) int (x, y), observed (N, 3), the plate's prediction of the ring (N, 3)); ``plates``:
    capture.plate.Plate per view (None: no plate, kept); ``local``: per view its ring's
    :func:`local_prediction` when already made (it depends on the view alone)."""
    from capture.plate_threads import thread_map

    def one(a):
        (lin, od, ring, obs, pred), loc = a
        if not GATE:
            return None, {}, None
        c = object_centre(od)
        loc = local_prediction(lin, od, ring) if loc is None else loc
        return (*refused(obs, pred, loc, ring_sectors(ring, c)), c)

    got = list(thread_map(one, zip(views, local or [None] * len(views), strict=True)))
    out = []
    for p, (why, counts, c) in zip(plates, got, strict=True):
        bad = sectors_out(why, counts) if SECTOR_GATE and p is not None else []
        if bad:
            counts["sectors_refused"] = bad
        if p is None or (why is None and not bad):
            out.append(p)
        elif SECTOR_GATE and len(bad) < SECTORS:
            out.append(without_sectors(p, bad, c))
        else:
            out.append(empty(p))
    return out, [g[:2] for g in got]


def sectors_out(why: str | None, counts: dict) -> list[int]:
    """The sectors whose plate is dropped (SECTOR_GATE): in a kept view (``why`` None) those that fail
    (:func:`failed_sectors`); in a refused one all but those that pass (at least SECTOR_MIN_PIXELS deciding
    pixels, the plate the closer one at SECTOR_KEEP_WINS of them)."""
    if why is None:
        return failed_sectors(counts)
    secs = counts.get("sectors") or [[0, 0]] * SECTORS
    return [k for k, (n, won) in enumerate(secs) if not (n >= SECTOR_MIN_PIXELS and won >= SECTOR_KEEP_WINS * n)]


def gate_record(rec: dict, gate: list, dropped=()) -> dict:
    """The plate record with each view's ``gate`` (the counts of :func:`refused`) and ``refused`` reason (None:
    kept), ``refused``: the positions of the views whose plate was refused (:func:`gate_plates`), and
    ``dropped_sources``: the views that lent the others nothing (:func:`gated`)."""
    per_view = [{**r, "gate": c, "refused": w} for r, (w, c) in zip(rec.get("per_view", []), gate, strict=True)]
    return {**rec, "per_view": per_view, "refused": [i for i, (w, _) in enumerate(gate) if w is not None],
            "dropped_sources": [int(i) for i in dropped]}


def rings(ps, predicted: list) -> list:
    """Per view of a capture.plate.PlateSet what :func:`gate_plates` reads, with the plate's ring
    prediction ``predicted`` (a capture.plate.Trial's)."""
    return [(p.view.linear, p.view.object_depth, p.ring, p.observed, q)
            for p, q in zip(ps.views, predicted, strict=True)]


def without(ps, drop):
    """The capture.plate.PlateSet whose views ``drop`` lend the others nothing: no panorama neighbour
    (``dropped``), no fixed-camera sample (their weights 0)."""
    views = tuple(replace(p, weight=np.zeros_like(p.weight)) if i in drop and p.weight is not None else p
                  for i, p in enumerate(ps.views))
    return replace(ps, views=views, dropped=frozenset(int(i) for i in drop))


def gated(ps, mode: str, fit, plates: list, crop: bool) -> tuple[list, list, list]:
    """(plates, per view (why refused or None, counts), the views that lent nothing) of
    capture.plate.background_plates: the plates gated (:func:`gate_plates`); where some were refused
    (DROP_SOURCES), every plate drawn again without them (:func:`without`, the same gains ``fit.gains``)
    and gated again (the views' local predictions made once)."""
    from capture.plate import draw_plates, ring_trial
    from capture.plate_threads import thread_map

    views = rings(ps, fit.predicted)
    local = list(thread_map(lambda v: local_prediction(*v[:3]), views)) if GATE else None
    plates, gate = gate_plates(views, plates, local)
    drop = [i for i, (why, _) in enumerate(gate) if why is not None]
    if not drop or not DROP_SOURCES or len(drop) == len(plates):
        return plates, gate, []
    ps2 = without(ps, drop)
    fit2 = ring_trial(ps2, mode, fit.gains)  # the same gains, the rings predicted without them
    plates, gate = gate_plates(rings(ps2, fit2.predicted), draw_plates(ps2, mode, fit2, crop), local)
    return plates, gate, drop
