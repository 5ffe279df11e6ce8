"""``furrow bench ambient``: the ambient (diffuse) term of the synthetic ground-truth renderer
against the brute-force irradiance integral (datasets_synthetic/lighting.py, METHODS §2-§3).

The synthetic renderer lights a scene with K dominant lights (shadow-mapped) plus the diffuse
irradiance of the environment minus those lights.  Before 2026-11-22 that residual was lit by its
SH9 projection; now by the exact irradiance table (render.shading.irradiance).  For every bundled
map this prints both against ``irradiance_brute`` of the same residual map at random normals:
mean / max relative error, and the worst error relative to the brightest ambient irradiance.

    furrow bench ambient [--normals 500] [--lights 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="furrow bench ambient", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--normals", type=int, default=500, help="random unit normals compared")
    p.add_argument("--lights", type=int, default=3, help="dominant lights removed from the map")
    p.add_argument("--json", action="store_true", help="print the results as JSON on stdout")
    a = p.parse_args(argv)
    from datasets_synthetic.lighting import LightingConfig, ambient_accuracy, resolve_env
    from render.shading.envmap import BUNDLED_NAMES

    rows = []
    for name in BUNDLED_NAMES:
        t = time.perf_counter()
        r = ambient_accuracy(resolve_env(name), LightingConfig(env=name, lights=a.lights), normals=a.normals)
        r["seconds"] = time.perf_counter() - t
        rows.append(r)
    if a.json:
        print(json.dumps(rows, indent=1))
        return 0
    from rich.table import Table

    from furrow.console import console

    t = Table(title=f"ambient irradiance of env minus {a.lights} lights vs brute force ({a.normals} normals)")
    for c in ("map", "SH9 mean rel", "SH9 max rel", "SH9 max/peak", "table mean rel", "table max rel", "table max/peak"):
        t.add_column(c)
    for r in rows:
        t.add_row(r["env"], *(f"{100 * r[k][m]:.2f}%" for k in ("sh9", "table") for m in ("mean_rel", "max_rel", "max_of_peak")))
    console.print(t)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
