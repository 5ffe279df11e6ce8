"""The capture-to-model pipeline (docs/design.md "The capture-to-model pipeline").

- ``stages.py``: every stage, in order, in one list (``STAGES``): its function, its kind (per view,
  cameras, whole set) and what it does.
- ``config.py``: one config per stage (``PipelineConfig``, a field each) and the runner's settings.
- ``runner.py``: runs the list (``run_pipeline``): views kept in memory or on disk, progress,
  the stage table.
- ``work.py``: what passes between stages (``Work``), what a stage gets (``Context``) and what a
  command gives the runner (``Hooks``).
- ``report.py``: the save stage, model.json params and the ``--json`` summary.
- ``plan.py``: the stage list as text: ``furrow model --plan`` and the docs diagram.

``build_model(scanset, cfg)`` (here) runs it on scans already in memory and returns (model, summary).
"""

from __future__ import annotations


def build_model(scanset, cfg=None, hooks=None):
    """(Model, summary) of the pipeline run on a ScanSet in memory (the reading stages skipped;
    ``cfg``: volume.pipeline.config.PipelineConfig).  The run's spill folder, if the views were many
    enough to use one, is closed: the model's RGBz crops are then read into memory first."""
    from volume.pipeline.runner import run_pipeline

    with run_pipeline(scanset, cfg, hooks) as run:
        model, summary = run.model, run.summary()
        if run.spill is not None and model.rgbz.crop_file is not None:
            model = _detached(model)
    return model, summary


def _detached(model):
    """``model`` with its RGBz crops read from the spill folder into memory (the encoded crops, as stored)."""
    from dataclasses import replace

    from volume.model import RgbzImages

    rgbz = model.rgbz
    crops = [rgbz.encoded(n) for n in range(len(rgbz))]
    return replace(model, rgbz=RgbzImages.from_crops(rgbz.cameras, crops))
