"""A non-editable ``pip install .`` into a fresh venv runs the CLI from outside the checkout:
bench and eval help, synth -> model -> render (shaders, env maps, benchmarks are package data /
modules).  Slow (minutes) and needs the package index: ``make test-slow``."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from tests.conftest import REPO_DIR


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("git") is None, reason="scripts/check_install.sh copies the tracked files with git")
def test_fresh_venv_install_runs_the_cli(tmp_path):
    r = subprocess.run(["bash", str(REPO_DIR / "scripts" / "check_install.sh"), str(tmp_path / "venv")],
                       capture_output=True, text=True, timeout=3600)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-4000:]
    assert "check_install: OK" in r.stdout
    assert "site-packages/furrow/__init__.py" in r.stdout  # the installed copy, not the checkout
