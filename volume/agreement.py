"""The depth-agreement stage of the pipeline (volume/pipeline/stages.py): before any model is built,
whether the views' depths agree with their poses (capture.depth_agreement), said on the console when
they do not; the model record keeps the figures.  Nothing is changed.  Off with ``--depth-agreement off``
(its config None); ``--depth-agreement fix`` scales the depth to the poses where it agrees best at
another scale."""

from __future__ import annotations

import logging
import zlib
from dataclasses import asdict, replace

import numpy as np

from capture.depth_agreement import MAX_PAIR_ANGLE, AgreementConfig, agreement, neighbours, verdict, view_sample


def sample_view(scan, ref, arg):
    """Per view (capture.view_map): (None, :func:`capture.depth_agreement.view_sample` of its depth,
    seeded by the view's name); ``arg``: the number of points."""
    return None, view_sample(scan.depth, scan.camera, arg, zlib.crc32(scan.name.encode()))


def agreement_stage(work, cfg: AgreementConfig, ctx):
    """The depth-agreement stage: each view's sample through ``ctx.map_views``, the share of points
    agreeing at each depth scale, the verdict warned unless it is ``agree``; record: the verdict, the
    scales' shares (rounded), each view's own share and the config; None with fewer than 2 views, status
    ``no depth`` where no view has any (the fuse stage refuses such a capture, and says why), ``no pairs``
    where no two views are within MAX_PAIR_ANGLE of each other."""
    if len(work.scans) < 2:
        return work.record("depth agreement", None)
    samples = ctx.map_views(sample_view, work, int(cfg.points), "depth agreement")[1]
    if sum(len(p) for p, _, _ in samples) == 0:  # no view has depth: the fuse stage's error says so
        return work.record("depth agreement", {"status": "no depth", "config": asdict(cfg)})
    cams = [s.camera for s in work.scans]
    if not (neighbours(cams, cfg.neighbours) >= 0).any():
        logging.getLogger("furrow.capture").info("depth agreement: no two views within %g degrees of each other: "
                                                 "nothing to compare", MAX_PAIR_ANGLE)
        return work.record("depth agreement", {"status": "no pairs", "config": asdict(cfg)})
    s, share, share_all, per_view, blind = agreement(samples, cams, cfg)
    rec = {**verdict(s, share, share_all), "scale_blind": round(blind, 4)}
    log = logging.getLogger("furrow.capture")
    (log.info if rec["status"] == "agree" else log.warning)("depth agreement: %s", rec["message"])
    if cfg.fix and rec["status"] == "scale":
        work, rec = _rescaled(work, rec, ctx)
    rec["curve"] = {f"{x:.4g}": round(float(a), 4) for x, a in zip(s, share)}
    rec["per_view"] = {x.name: None if v != v else round(float(v), 4) for x, v in zip(work.scans, per_view)}
    return work.record("depth agreement", {**rec, "config": asdict(cfg)})


def rescale_view(scan, ref, s: float):
    """Per view: the scan with its depth times ``s``."""
    return replace(scan, depth=(np.asarray(scan.depth, np.float32) * np.float32(s)).astype(np.float32)), None


def _rescaled(work, rec: dict, ctx):
    """(work with every view's depth scaled by the best scale, and its bounds found again from the depth
    where the capture gives none; the record with ``applied``).  The poses stay as they are, so that the
    model keeps the capture's frame: the held-out views of furrow eval, a camera path of the same poses."""
    from capture.io import auto_bounds

    s = float(rec["best_scale"])
    scans, _ = ctx.map_views(rescale_view, work, s, "depth agreement: depth rescaled")
    bounds = work.bounds if work.source.bounds is not None else auto_bounds(scans, str(work.source.path))
    logging.getLogger("furrow.capture").warning(
        "depth agreement: every view's depth scaled by %.4g to the poses (--depth-agreement fix)", s)
    return replace(work, scans=tuple(scans), bounds=bounds), {**rec, "applied": round(s, 6)}
