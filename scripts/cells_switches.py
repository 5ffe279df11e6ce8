"""`furrow` with issue 30's eighth-round switches set from the environment (docs/matting.md "The eighth round
on captures it was not made on"): GLOBAL, SHRINK, VIEW_BRIGHTNESS, FILLED_CUBES (capture.matting_global,
0 / 1), CELL_LINE_ALPHA (capture.matting_lines) and the ninth round's AGREEING, CONTRAST, VIEW_CHROMA,
CHROMA_RELATIVE (0 / 1) and AGREE_TOL (capture.matting_contrast), the eleventh round's RECROSS
(capture.matting_recross, 0 / 1) and RECROSS_PASSES (an integer),
the twelfth round's BRIGHTNESS_LEVEL (capture.matting_global, 0 / 1), and the exposure check's VIEW_GAINS
(capture.plate_exposure, 0 / 1), the colour across views' AGREEING_GATE (capture.matting_cells, 0 / 1) and the
object colour's MEAN_CHECK (capture.matting_global, 0 / 1) and STICKY_MEAN (capture.matting_recross, 0 / 1).
Use ``--view-workers 1``: the view pool's processes import the modules afresh and would not see the switches.

    ABL="GLOBAL=0,CELL_LINE_ALPHA=0.1" PYTHONPATH=. .venv/bin/python scripts/cells_switches.py \
        eval CAP --holdout 2 --methods gather --view-workers 1 --json X.json -o X
"""
import os
import sys

if __name__ == "__main__":
    import capture.matting_cells as mcl
    import capture.matting_contrast as mk
    import capture.matting_global as mg
    import capture.matting_lines as ml
    import capture.matting_recross as mr
    import capture.plate_exposure as pe
    for kv in filter(None, os.environ.get("ABL", "").split(",")):
        k, v = kv.split("=")
        if k == "CELL_LINE_ALPHA":
            ml.CELL_LINE_ALPHA = float(v)
            import capture.matting_cells as mc
            mc.CELL_LINE_ALPHA = float(v)
        elif k == "AGREE_TOL":
            mk.AGREE_TOL = float(v)
        elif k == "RECROSS_PASSES":
            mr.RECROSS_PASSES = int(v)
        else:
            mod = next((m for m in (mk, mr, pe, mcl) if hasattr(m, k)), mg)
            if not hasattr(mod, k):
                raise SystemExit(f"ABL: no switch {k}")
            setattr(mod, k, bool(int(v)))
    from furrow.cli import main
    sys.exit(main(sys.argv[1:]))
