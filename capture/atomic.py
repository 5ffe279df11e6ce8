"""Atomic writes: a file or a folder is built under a temporary name beside its target and
renamed into place only when complete, so an interrupted or failed write leaves the previous
version (or nothing) and no temporary behind. The one implementation every package uses."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np


def _file_mode(base: int = 0o666) -> int:
    """The mode a new file (``base`` 0666) or folder (0777) gets from ``open()`` / ``mkdir()``: less the umask."""
    mask = os.umask(0)
    os.umask(mask)
    return base & ~mask


@contextmanager
def atomic_write(path) -> Iterator[Path]:
    """``with atomic_write(path) as tmp:`` write the file ``tmp`` (same folder, same suffix, so
    writers that choose the format by extension work); on success it replaces ``path``, on an
    exception it is removed and ``path`` is left as it was. Creates the parent folder."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{path.stem}.tmp-", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, _file_mode())  # mkstemp makes 0600; the result gets a normal file's mode
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def atomic_dir(target) -> Iterator[Path]:
    """``with atomic_dir(target) as tmp:`` build the folder ``tmp`` (beside ``target``); on success
    it takes ``target``'s place (a previous ``target`` is moved aside, then deleted), on an
    exception it is deleted and ``target`` is left as it was. Creates the parent folder."""
    target = Path(target)
    parent = target.resolve().parent
    parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.tmp-", dir=parent))
    try:
        yield tmp
        os.chmod(tmp, _file_mode(0o777))  # mkdtemp makes 0700; the result gets a normal folder's mode
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=parent))
            os.rmdir(old)
            os.replace(target, old)
            os.replace(tmp, target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def write_json(path, data, indent: int | None = 1, default=None) -> Path:
    """Write ``data`` as JSON to ``path`` atomically (:func:`atomic_write`: the parent folder made,
    a failed write leaves the previous file); ``default`` as for ``json.dumps``.  Returns the path."""
    text = json.dumps(data, indent=indent, default=default)
    with atomic_write(path) as tmp:
        tmp.write_text(text)
    return Path(path)


def jsonable(x):
    """``x`` made JSON-serialisable: dict keys as strings, tuples as lists, numpy arrays and
    scalars as Python values, anything else unknown as its ``str``."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, (str, int, float, bool)) or x is None:
        return x
    return str(x)
