"""``furrow bench model --scale``: peak memory, time and model size of ``furrow model`` against the
number of frames and the frame size (issue 24).

For every frame size in ``--sizes`` one capture of the scene with the largest count in
``--frame-counts`` is synthesised (``furrow synth``, cached under ``OUT/data``; or given with
``--scale-scans WxH=PATH``), and the smaller counts are evenly spaced subsets of it
(``--frames 0::k``), so every count sees the same object.  Each build runs in a fresh process
(``furrow model --json`` of this tree; ``--before git:REF`` adds that commit's build, interleaved):
wall and CPU seconds (the child's rusage), peak resident memory (its ru_maxrss), the size of the
model folder and of the capture on disk (colour + depth files the kept frames read).  The plot
(``OUT/model_scale.png``) shows peak memory against frames, one line per frame size (and
variant); ``OUT/model_scale.json`` holds the rows.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from capture.atomic import write_json

#: Frame counts measured by default.
FRAME_COUNTS = (18, 36, 72, 144)
#: Frame sizes measured by default.
SIZES = ("640x480", "1280x960", "1920x1440")
#: The scene built.
SCENE = "plant"


def folder_mb(path: Path) -> float:
    """Size (MiB) of the files under ``path``."""
    return sum(f.stat().st_size for f in Path(path).rglob("*") if f.is_file()) / 2 ** 20


def capture_mb(scans: Path, frames: list[int]) -> float:
    """Size (MiB) of the colour and depth files of the frames ``frames`` of a transforms.json capture."""
    meta = json.loads((Path(scans) / "transforms.json").read_text())
    total = 0
    for i in frames:
        fr = meta["frames"][i]
        for key in ("file_path", "depth_file_path"):
            if fr.get(key):
                total += (Path(scans) / fr[key]).stat().st_size
    return total / 2 ** 20


def scale_capture(size: str, n: int, data: Path, given: dict[str, Path]) -> Path:
    """The capture of ``size`` with ``n`` frames (synthesised once, or the one given)."""
    import subprocess
    import sys

    if size in given:
        return given[size]
    out = data / f"{SCENE}-{n}-{size}"
    if not (out / "transforms.json").is_file():
        # in a child process: a build's ru_maxrss starts at its parent's resident memory when forked,
        # so a capture synthesised in this process (2.7 GB for 144 views at 640x480) would read as
        # every build's peak
        args = ["synth", SCENE, "--views", str(n), "--size", size, "-o", str(out), "--overwrite"]
        if subprocess.run([sys.executable, "-m", "furrow", *args]).returncode != 0:
            raise SystemExit(f"furrow {' '.join(args)} failed")
    return out


def _peak(stage_peaks: dict, rusage_mb: float) -> float:
    """The build's peak resident memory: the largest of its stages' (VmHWM reset per stage,
    furrow.console.StageTimer), which only the build's own pages reach; ru_maxrss (``rusage_mb``)
    when the build gave none."""
    return max(stage_peaks.values()) if stage_peaks else rusage_mb


def run_scale(sizes, counts, before: str, work: Path, data: Path, given: dict[str, Path], run_child, tree_of,
              root: Path, spill: str | None = None) -> list[dict]:
    """One row per (variant, size, frames): wall / CPU seconds, peak MiB, model and capture MiB
    (``spill``: furrow model --spill, None = its default)."""
    import sys

    env = {**os.environ, "OMP_WAIT_POLICY": "passive"}
    variants = [("this tree", root)]
    if before.startswith("git:"):
        variants.append((before, tree_of(before, work)))
    rows = []
    top = max(counts)
    for size in sizes:
        scans = scale_capture(size, top, data, given).resolve()
        n_all = len(json.loads((scans / "transforms.json").read_text())["frames"])
        for n in counts:
            if n > n_all:
                continue
            step = max(n_all // n, 1)
            frames = list(range(0, n_all, step))[:n]
            spec = ",".join(map(str, frames))
            for name, tree in variants:
                out = work / f"m-{size}-{n}-{name.replace(':', '_').replace(' ', '_')}"
                cmd = [sys.executable, "-m", "furrow", "model", str(scans), "-o", str(out), "--overwrite", "--json",
                       "--frames", spec, *(["--spill", spill] if spill else [])]
                r = run_child(cmd, tree, {**env, "PYTHONPATH": str(tree)})
                stages = r["summary"].get("peak_mb", {})
                rows.append({"variant": name, "size": size, "frames": len(frames), "wall_s": round(r["wall_s"], 2),
                             "cpu_s": round(r["cpu_s"], 2), "peak_mb": round(_peak(stages, r["peak_mb"]), 1),
                             "peak_mb_rusage": round(r["peak_mb"], 1),
                             "model_mb": round(folder_mb(out), 2), "capture_mb": round(capture_mb(scans, frames), 2),
                             "stage_peak_mb": r["summary"].get("peak_mb", {}), "l_opt": r["summary"].get("l_opt"),
                             "spill": r["summary"].get("spill")})
                print(json.dumps(rows[-1]), flush=True)
    return rows


def plot_scale(rows: list[dict], out: Path) -> Path:
    """Peak memory (and model size) against frames, one line per frame size and variant."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from furrow.bench._common import save_figure

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    keys = sorted({(r["variant"], r["size"]) for r in rows})
    for variant, size in keys:
        rs = sorted((r for r in rows if r["variant"] == variant and r["size"] == size), key=lambda r: r["frames"])
        style = "-o" if variant == "this tree" else "--x"
        axes[0].plot([r["frames"] for r in rs], [r["peak_mb"] / 1024 for r in rs], style, label=f"{size} {variant}")
        axes[1].plot([r["frames"] for r in rs], [r["model_mb"] / max(r["capture_mb"], 1e-9) for r in rs], style,
                     label=f"{size} {variant}")
    axes[0].set_xlabel("frames")
    axes[0].set_ylabel("peak resident memory (GiB)")
    axes[0].set_title("furrow model: peak memory against frames")
    axes[1].set_xlabel("frames")
    axes[1].set_ylabel("model size / capture size")
    axes[1].set_title("model size against frames")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return save_figure(fig, out / "model_scale.png", dpi=110)


def scale_table(rows: list[dict]):
    from rich.table import Table

    t = Table(title="furrow model against frames and frame size")
    for c in ("variant", "size", "frames", "L_opt", "wall s", "cpu s", "peak MiB", "model MiB", "capture MiB"):
        t.add_column(c, justify="right")
    for r in rows:
        t.add_row(r["variant"], r["size"], str(r["frames"]), str(r["l_opt"]), f"{r['wall_s']:.1f}",
                  f"{r['cpu_s']:.1f}", f"{r['peak_mb']:.0f}", f"{r['model_mb']:.1f}", f"{r['capture_mb']:.1f}")
    return t


def scale_main(args, run_child, tree_of, root: Path) -> int:
    """The ``--scale`` run of ``furrow bench model`` (module docstring)."""
    from rich.console import Console

    sizes = [s for s in args.sizes.split(",") if s]
    counts = sorted(int(c) for c in args.frame_counts.split(",") if c)
    given = {}
    for item in [s for s in (args.scale_scans or "").split(",") if s]:
        size, _, path = item.partition("=")
        given[size] = Path(path)
    work = (args.out / "scale").resolve()
    work.mkdir(parents=True, exist_ok=True)
    rows = run_scale(sizes, counts, args.before if args.before != "reference" else "none", work,
                     args.out / "data", given, run_child, tree_of, root, getattr(args, "scale_spill", None))
    args.out.mkdir(parents=True, exist_ok=True)
    write_json(args.out / "model_scale.json", {"rows": rows, "load_average": os.getloadavg()})
    Console(stderr=True, width=200).print(scale_table(rows))
    if rows:
        print(f"plot: {plot_scale(rows, args.out)}")
    if args.json:
        print(json.dumps(rows))
    return 0
