"""The depth-agreement stage of the pipeline (volume/pipeline/stages.py): before any model is built,
whether the views' depths agree with their poses (capture.depth_agreement), said on the console when
they do not; the model record keeps the figures.  Nothing is changed.  Off with ``--no-agreement-check``
(its config None)."""

from __future__ import annotations

import logging
import zlib
from dataclasses import asdict

from capture.depth_agreement import AgreementConfig, agreement, verdict, view_sample


def sample_view(scan, ref, arg):
    """Per view (capture.view_map): (None, :func:`capture.depth_agreement.view_sample` of its depth,
    seeded by the view's name); ``arg``: the number of points."""
    return None, view_sample(scan.depth, scan.camera, arg, zlib.crc32(scan.name.encode()))


def agreement_stage(work, cfg: AgreementConfig, ctx):
    """The depth-agreement stage: each view's sample through ``ctx.map_views``, the share of points
    agreeing at each depth scale, the verdict warned unless it is ``agree``; record: the verdict, the
    scales' shares (rounded), each view's own share and the config; None with fewer than 2 views, status
    ``no depth`` where no view has any (the fuse stage refuses such a capture, and says why)."""
    if len(work.scans) < 2:
        return work.record("depth agreement", None)
    samples = ctx.map_views(sample_view, work, int(cfg.points), "depth agreement")[1]
    if sum(len(p) for p, _, _ in samples) == 0:  # no view has depth: the fuse stage's error says so
        return work.record("depth agreement", {"status": "no depth", "config": asdict(cfg)})
    cams = [s.camera for s in work.scans]
    s, share, per_view = agreement(samples, cams, cfg)
    rec = verdict(s, share)
    log = logging.getLogger("furrow.capture")
    (log.info if rec["status"] == "agree" else log.warning)("depth agreement: %s", rec["message"])
    rec["curve"] = {f"{x:.4g}": round(float(a), 4) for x, a in zip(s, share)}
    rec["per_view"] = {x.name: None if v != v else round(float(v), 4) for x, v in zip(work.scans, per_view)}
    return work.record("depth agreement", {**rec, "config": asdict(cfg)})
