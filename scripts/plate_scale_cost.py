"""`furrow` with the background plate's working scale forced (docs/speed.md "What the plate's working scale
costs"): the held-out cost of the coarser plate that large captures get from the memory budget
(capture.plate_scale).

    PLATE_FORCE=0.4 PYTHONPATH=. .venv/bin/python scripts/plate_scale_cost.py \
        eval CAP --holdout 2 --methods gather --json X.json -o X
"""
import os
import sys

if __name__ == "__main__":
    import volume.surroundings as su
    s = float(os.environ["PLATE_FORCE"])
    su.plate_scale = lambda *a, **k: s
    from furrow.cli import main
    sys.exit(main(sys.argv[1:]))
