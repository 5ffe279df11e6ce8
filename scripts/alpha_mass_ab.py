"""Gather's coverage pull (render.gather.alpha_mass) on and off, on one saved model's held-out views.

    PYTHONPATH=. .venv/bin/python scripts/alpha_mass_ab.py CAPTURE MODEL [--json OUT] [--holdout K] [--mode on|auto]

CAPTURE: the capture `furrow eval CAPTURE --holdout K --save-model MODEL` was run on (its held-out frames carry the
true matte); MODEL: that saved model.  Renders every held-out view with gather twice (GatherConfig.alpha_mass "off",
then --mode: "on" or "auto"; the same model) and prints, per setting, the mean over the views of the masked PSNR /
SSIM / sharpness over black, PSNR over white and over dark, alpha MSE (render.evaluate.score_view) and the pull
given."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def scores(capture: Path, model_dir: Path, holdout: int = 2, mode: str = "on") -> dict:
    """{"off": ..., "on": ...} ("on": GatherConfig.alpha_mass ``mode``): each the mean of gather_ab.KEYS over the
    held-out views and ``pulls`` (per view); scripts/gather_ab.py's two arms."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from gather_ab import scores as arm_scores

    out = arm_scores(capture, model_dir, ["alpha_mass=off", f"alpha_mass={mode}"], holdout)
    return {"off": out["alpha_mass=off"], "on": out[f"alpha_mass={mode}"]}


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("capture", type=Path)
    p.add_argument("model", type=Path)
    p.add_argument("--holdout", type=int, default=2)
    p.add_argument("--json", type=Path, help="write both settings' numbers here")
    p.add_argument("--mode", default="on", choices=("on", "auto"), help="GatherConfig.alpha_mass against off")
    a = p.parse_args(argv)
    out = scores(a.capture, a.model, a.holdout, a.mode)
    off, on = out["off"], out["on"]
    s = np.array(on["pulls"])
    print(f"{a.capture}: over black {off['psnr_masked']:.3f} / {off['ssim_masked']:.4f} / {off['sharpness']:.3f} -> "
          f"{on['psnr_masked']:.3f} / {on['ssim_masked']:.4f} / {on['sharpness']:.3f}; over white "
          f"{off['psnr_white']:.2f} -> {on['psnr_white']:.2f}; over dark {off['psnr_dark']:.2f} -> "
          f"{on['psnr_dark']:.2f}; alpha MSE {off['alpha_mse']:.4f} -> {on['alpha_mse']:.4f}; "
          f"pull {s.min():.3f}-{s.max():.3f} ({int((s > 0).sum())} of {len(s)} views)")
    if a.json:
        from capture.atomic import write_json

        write_json(a.json, out)
    return out


if __name__ == "__main__":
    main()
