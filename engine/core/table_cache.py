"""Tables computed once per user: small arrays a worker would otherwise compute at every start (the
Principled BSDF's s(mu) tables, engine/materials/principled.py interpolation_factor), kept as .npy
files in the per-user cache directory beside numba's (engine/core/backend.py cache_dir).

A table's file name holds a digest of everything its bits depend on: the text of the source files
of the code that computes it, NumPy's version, Python's and the platform, and its inputs (repr, which
gives a float exactly).  A change of any of them names another file, so a stale table is never read
(tests/core/test_table_cache.py); a file that cannot be read is computed again and rewritten.
Files are written whole under a temporary name and renamed, so two workers that start together
may both compute a table but never read half of one.
"""
from __future__ import annotations

import hashlib
import os
import platform
import sys
import tempfile
from functools import lru_cache

import numpy as np

from .backend import cache_root


def tables_dir() -> str:
    path = os.path.join(os.path.dirname(cache_root()), "tables")
    os.makedirs(path, exist_ok=True)
    return path


@lru_cache(maxsize=64)
def code_digest(paths: tuple) -> str:
    """The digest of the source files `paths` and of the versions a table's bits depend on."""
    h = hashlib.sha1()
    for key in (np.__version__, sys.version, platform.machine(), sys.platform):
        h.update(key.encode() + b"\0")
    for path in paths:
        with open(path, "rb") as fh:
            h.update(fh.read() + b"\0")
    return h.hexdigest()[:16]


def table_path(name: str, sources: tuple, inputs: tuple) -> str:
    digest = hashlib.sha1(f"{code_digest(tuple(sources))}\0{inputs!r}".encode()).hexdigest()[:24]
    return os.path.join(tables_dir(), f"{name}-{digest}.npy")


def cached(name: str, sources: tuple, inputs: tuple, compute) -> np.ndarray:
    """compute()'s array for these `inputs`, read from the cache when the file of this code and
    these inputs exists, else computed and written there.  sources: the paths of the source files
    whose code computes it."""
    try:
        path = table_path(name, sources, inputs)
    except OSError:                              # no writable cache directory, or a source unreadable
        return compute()
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError):
        pass
    table = compute()
    try:
        fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), suffix=".tmp")
        with os.fdopen(fd, "wb") as fh:
            np.save(fh, table, allow_pickle=False)
        os.replace(tmp, path)
    except OSError:
        pass
    return table
