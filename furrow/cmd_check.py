"""``furrow check``: a capture's checks before a model is built, in seconds.

Runs the pipeline's first stages (volume/pipeline/stages.py: reading, view selection, depth agreement) and no
other, then prints what each check found.  Exit status: 0 when every check passed, 1 when one did not (the
depths do not agree with the poses, or agree only at another scale, with other intrinsics, in another pose
convention; the depth sits beside or zoomed from its colour), 1 with the reason when the capture cannot be read.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

HELP = "check a capture before modelling it: its frames, its views and its depth against its poses and colour"
DESCRIPTION = f"""{HELP}.

The first stages of `furrow model` (reading, view selection, depth agreement) and nothing else, so a capture
whose poses, intrinsics or depth are off is found in seconds, not after the model (docs/capture_formats.md):
the depth held against the poses at depth scales 1/4..4, against poses read in other conventions (OpenCV axes,
world-to-camera), other intrinsics (those of another image size, the principal point at the centre) and other
focal lengths; against its colour image (shifted, or zoomed: a depth camera of its own); and the capture's own
mattes (mask_path, masks/) against the depth (inverted ones).

Exit status: 0 every check passed; 1 a check failed (each says what to fix), or the capture could not be read.
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    from capture.lens import DEFAULT_UNDISTORT, UNDISTORT_MODES

    p.add_argument("scans", type=Path,
                   help="scan set: transforms.json, a folder holding one, a plain folder or a COLMAP folder")
    p.add_argument("--frames", default=None, metavar="SPEC",
                   help="which frames, as furrow model takes them (e.g. 0::2; default all)")
    p.add_argument("--views", default="auto", metavar="MODE",
                   help="view selection as furrow model's --views: auto (default), all, or a number")
    p.add_argument("--undistort", choices=list(UNDISTORT_MODES), default=DEFAULT_UNDISTORT,
                   help=f"lens-distorted frames, as furrow model's --undistort (default {DEFAULT_UNDISTORT})")
    p.add_argument("--json", action="store_true", help="print the checks' records on stdout")
    p.add_argument("--debug", action="store_true", help="show tracebacks")


#: The stages furrow check runs: the pipeline up to and with this one.
LAST_STAGE = "depth agreement"


def check_records(source, frames, views: str, undistort: str, hooks=None) -> dict:
    """The records of the pipeline's stages up to :data:`LAST_STAGE` on ``source`` (a capture.sources.Source):
    stage name -> record (volume/pipeline/runner.py)."""
    from capture.depth_agreement import AgreementConfig
    from capture.sources import ReadConfig, UndistortConfig
    from volume.pipeline.config import PipelineConfig, ViewsConfig
    from volume.pipeline.runner import run_pipeline
    from volume.pipeline.stages import STAGES

    last = [s.name for s in STAGES].index(LAST_STAGE)
    cfg = PipelineConfig(read=ReadConfig(frames), undistort=UndistortConfig(undistort), views=ViewsConfig(views),
                         agreement=AgreementConfig())
    run = run_pipeline(source, cfg, hooks, stages=STAGES[:last + 1])
    try:
        return {**run.work.records, "frames": frame_stats(run.work.scans or ())}
    finally:
        run.close()


def frame_stats(scans) -> dict:
    """The views' size, the share of their pixels with depth (median over the views) and the median depth (metres,
    median of the views' medians): what a depth unit off by 1000 or a depth file of another frame shows at once."""
    shares, medians = [], []
    for x in scans:
        z = np.asarray(x.depth, np.float32)
        ok = np.isfinite(z) & (z > 0)
        shares.append(float(ok.mean()))
        if ok.any():
            medians.append(float(np.median(z[ok])))
    c = scans[0].camera if len(scans) else None
    return {"views": len(scans), "size": [c.width, c.height] if c else None,
            "depth_share": round(float(np.median(shares)), 4) if shares else 0.0,
            "depth_median_m": round(float(np.median(medians)), 4) if medians else None}


def verdicts(records: dict) -> list[tuple[str, bool, str]]:
    """(check, passed, what it found) for each check of ``records`` (:func:`check_records`)."""
    from capture.depth_pairing import PAIR_GAIN, PAIR_MIN_VIEWS, PAIR_SHARE
    from volume.agreement import FAILED_AGREEMENT

    out = []
    fr = records.get("frames") or {}
    if fr.get("views"):
        w, h = fr["size"]
        med = fr["depth_median_m"]
        out.append(("frames", med is not None, f"{fr['views']} views of {w}x{h}; depth on {fr['depth_share']:.0%} of "
                    "the pixels (median view), " + (f"median {med:.3g} m" if med is not None else "none at all")))
    sel = records.get("view selection") or {}
    if sel:
        collapsed = any(r.get("collapsed") for r in sel.get("per_view", []))
        out.append(("views", not collapsed, sel["per_view"][0]["reason"] if collapsed else
                    f"{sel['kept']} of {sel['of']} kept (--views {sel['mode']})"))
    agree = records.get("depth agreement")
    if not agree:
        out.append(("depth against poses", True, "not judged: fewer than 2 views"))
        return out
    status = agree.get("status")
    said = {"no depth": "no view has depth: furrow models RGB-D captures (depth_file_path)",
            "no pairs": "not judged: no two views within 75 degrees of each other"}
    out.append(("depth against poses", status not in FAILED_AGREEMENT and status != "no depth",
                said.get(status, agree.get("message", status))))
    if agree.get("given_matte"):
        m = agree["given_matte"]
        out.append(("given mattes against depth", not m["inverted"], f"{m['views']} views: {m['message']}"))
    flip = agree.get("colour_flip") or {}
    if flip.get("flipped"):  # capture.colour_flip
        out.append(("depth against colour", False, flip["message"]))
    elif "colour_offset" in agree:
        off = agree["colour_offset"]
        dx, dy = agree["colour_offset_px"]
        found = agree.get("colour_offset_message") or agree.get("colour_offset_note") or (
            f"the colour's edges sit at the depth's in {agree['colour_offset_views']} views (best shift "
            f"({dx:+g}, {dy:+g}) px): registered")
        out.append(("depth against colour", not off, found))
    if "pairing_views" in agree:  # capture.depth_pairing
        n, gain = agree["pairing_views"], agree["pairing_gain"]
        out.append(("depth files against frames", not agree["mispaired"], agree.get("pairing_message") or (
            f"{n} colour images: {agree['pairing_other_best']} fit a neighbouring view's depth edges better than "
            f"their own (median {gain:.2f} times, from {PAIR_GAIN} with {PAIR_SHARE:.0%} of them a fault)"
            if n >= PAIR_MIN_VIEWS else f"not judged: {n} colour images scored (fewer than {PAIR_MIN_VIEWS})")))
    return out


def run(args, console) -> int:
    from rich.table import Table

    from capture.sources import open_source
    from furrow.console import StageTimer
    from furrow.model_flags import pipeline_hooks

    timer = StageTimer()
    records = check_records(open_source(args.scans, args.undistort), args.frames, str(args.views), args.undistort,
                            pipeline_hooks(timer))
    found = verdicts(records)
    table = Table(title=f"furrow check: {args.scans}")
    for col in ("check", "result", "found"):
        table.add_column(col, overflow="fold")
    for name, ok, text in found:
        table.add_row(name, "[green]pass[/]" if ok else "[bold red]FAIL[/]", text)
    console.print(timer.table("furrow check: stage timings"))
    console.print(table)
    if args.json:
        print(json.dumps({"checks": [{"check": n, "passed": ok, "found": t} for n, ok, t in found],
                          "records": {k: records.get(k) for k in ("frames", "view selection", "depth agreement")}},
                         default=str))
    return 0 if all(ok for _, ok, _ in found) else 1
