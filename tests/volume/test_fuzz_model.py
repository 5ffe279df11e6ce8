"""Fuzzing the model-bundle reader (hypothesis): a damaged model.json or array file is refused with
ModelError naming the folder or file -- never a bare KeyError / AttributeError / zipfile error."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.fuzz import assert_own_error, damaged_bytes, mutated_json
from tests.volume.test_model import make_model
from volume.model import ARRAY_FILES, Model, ModelError, load_model, save_model

FUZZ = settings(max_examples=300, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("fuzzmodel")
    folder = save_model(make_model(), root / "model")
    for f in list(folder.iterdir()):
        shutil.copy(f, root / f.name)   # pristine copies beside the folder
    return folder


def _restore(folder: Path) -> None:
    for name in ("model.json", *ARRAY_FILES):
        shutil.copy(folder.parent / name, folder / name)


def _load(folder: Path, *names: str):
    try:
        return load_model(folder)
    except Exception as e:  # the point: which exception escapes
        assert_own_error(e, (ModelError,), str(folder), *names)
        return None


@FUZZ
@given(data=st.data())
def test_model_json_mutations(model_dir, data):
    _restore(model_dir)
    doc = data.draw(mutated_json(json.loads((model_dir.parent / "model.json").read_text())))
    (model_dir / "model.json").write_text(json.dumps(doc))
    m = _load(model_dir)
    assert m is None or isinstance(m, Model)


@settings(max_examples=200, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_damaged_files(model_dir, data):
    _restore(model_dir)
    name = data.draw(st.sampled_from(["model.json", *ARRAY_FILES]))
    f = model_dir / name
    f.write_bytes(data.draw(damaged_bytes(f.read_bytes())))
    m = _load(model_dir, str(f))
    assert m is None or isinstance(m, Model)
