"""The save stage (the Model assembled from what the stages made, written atomically when asked) and
the model report: ``model.json`` params and the ``furrow model --json`` summary, both from the
stages' records."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from capture.atomic import jsonable
from volume.model import Model, save_model


def _params(work, pc) -> dict:
    """model.json ``params``: every setting used and every stage's numbers."""
    rec = work.records
    fuse = rec["fuse"]
    return {"sdf": pc.fuse.sdf, "lopt": asdict(pc.fuse.lopt), "fusion": asdict(pc.fuse.fusion),
            "sphere_error": pc.spheres.error, "mesh": asdict(pc.mesh), "rgbz": asdict(pc.rgbz),
            "measured_voxels": pc.pyramid.measured_voxels, "sphere_level": pc.sphere_res, "mesh_level": pc.mesh_res,
            "eq1_fraction": fuse["eq1_fraction"], "eq1_sampled": fuse["eq1_sampled"],
            "eq1_flagged_per_measured": fuse["eq1_flagged_per_measured"], "surroundings": surroundings(work),
            "photometric": rec.get("photometric"), "views": rec.get("view selection"),
            "resolution": rec.get("working scale"), "depth_agreement": rec.get("depth agreement"), "stages": list(rec)}


def surroundings(work) -> dict:
    """The extent, background plate and matte stages' records (what ran of them; the plate's as ``plate``)."""
    names = {"extent": "extent", "background plate": "plate", "matte": "matte"}
    return jsonable({key: work.records[k] for k, key in names.items() if k in work.records})


def assemble(work, pc) -> Model:
    """The Model of what the stages made (``work.parts``), with its params and provenance."""
    from dataclasses import replace

    p = work.parts
    verts, faces = p["mesh"]
    prov = {"scans": len(work.scans), "scan_names": [s.name for s in work.scans],
            "scanset_metadata": jsonable(work.metadata), "source": str(work.source.path), "frames": pc.read.frames}
    model = Model(p["pyramid"], p["rgbz"], p["spheres"], verts, faces, p["colors"],
                  np.asarray(work.bounds, np.float64), _params(work, pc), prov)
    if pc.save.capture_env is not None:
        from capture.orbit import estimate_up
        from volume.model import CaptureLighting

        up = estimate_up([s.camera for s in work.scans])
        model = replace(model, capture_env=CaptureLighting(pc.save.capture_env.data, up, pc.save.capture_env_rotation,
                                                           pc.save.capture_env_source))
    return model


def save_stage(work, cfg, ctx):
    """The save stage (cfg: SaveConfig): the Model assembled; written to ``cfg.out`` (atomic:
    volume.model.save_model) when it is set."""
    model = assemble(work, ctx.config)
    if cfg.out is not None:
        save_model(model, cfg.out)
    return work.made(model=model).record("save", {"out": None if cfg.out is None else str(cfg.out)})


def summary(work) -> dict:
    """The summary keys of ``furrow model --json`` (those tests and benches read) from the stages' records."""
    rec, p = work.records, work.parts
    pyr = p["pyramid"]
    verts, faces = p["mesh"]
    fuse = rec["fuse"]
    out = {
        "l_opt": fuse["l_opt"],
        "levels": pyr.resolutions,
        "surface_voxels": {str(lv.resolution): int(len(lv.surface)) for lv in pyr.levels},
        "eq1_fraction": {L: round(v, 6) for L, v in fuse["eq1_fraction"].items()},
        "eq1_sampled": {L: {k: (round(x, 6) if isinstance(x, float) else x) for k, x in v.items()}
                        for L, v in fuse["eq1_sampled"].items()},
        "eq1_flagged_per_measured": {L: round(v, 6) for L, v in fuse["eq1_flagged_per_measured"].items()},
        "spheres": rec["spheres"]["count"],
        "sphere_error": round(rec["spheres"]["error"], 5),
        "sphere_target": rec["spheres"].get("target"),
        "mesh": {"vertices": int(len(verts)), "faces": int(len(faces))},
        "surroundings": surroundings(work),
        "holes": [{k: (round(v, 5) if isinstance(v, float) else v) for k, v in h.items()}
                  for h in rec["rgbz"]["holes"]],
        "photometric": rec.get("photometric"),
        "views": rec.get("view selection"),
        "resolution": rec.get("working scale"),
        "depth_agreement": rec.get("depth agreement"),
    }
    model = p.get("model")
    if model is not None and model.capture_env is not None:
        out["capture_env"] = model.capture_env.record()
    return out
