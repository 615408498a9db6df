"""hydroline's on-disk cache: compiled model libraries and small computed tables.

Directory: ``$HYDROLINE_CACHE_DIR``, else ``$XDG_CACHE_HOME/hydroline``, else
``~/.cache/hydroline``. Everything in it can be deleted at any time; it is rebuilt on demand.
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

__all__ = ["cache_dir", "load_table", "store_table", "source_tag"]


def cache_dir() -> Path:
    """Directory of the cache (created on demand by its writers)."""
    env = os.environ.get("HYDROLINE_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "hydroline"


def source_tag(*paths) -> str:
    """A short hash of source files: part of a cache key, so that a change of the code that
    computes a table makes its old entries unused."""
    h = hashlib.sha256()
    for p in paths:
        h.update(Path(p).read_bytes())
    return h.hexdigest()[:16]


def _table_path(kind: str, key: str) -> Path:
    return cache_dir() / kind / (hashlib.sha256(key.encode()).hexdigest()[:32] + ".json")


def load_table(kind: str, key: str):
    """The JSON value stored under ``key`` (a string naming every input), or None when absent
    or unreadable (a damaged entry is treated as a miss).

    Parameters
    ----------
    kind : str   Sub-directory of the cache naming the table, e.g. ``"correction_factors"``
    key : str    Everything the value depends on (inputs, :func:`source_tag` of the code)

    Returns
    -------
    object or None  The stored JSON value (lists, dicts, numbers, strings)
    """
    try:
        with open(_table_path(kind, key)) as f:
            entry = json.load(f)
        return entry["value"] if entry.get("key") == key else None
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def store_table(kind: str, key: str, value) -> None:
    """Store a JSON-serialisable value under ``key`` (atomic rename; errors ignored: the cache
    only saves time).

    Parameters
    ----------
    kind : str      Sub-directory of the cache naming the table, e.g. ``"correction_factors"``
    key : str       Everything the value depends on (inputs, :func:`source_tag` of the code)
    value : object  JSON-serialisable value (lists, dicts, numbers, strings)
    """
    path = _table_path(kind, key)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "w") as f:
            json.dump({"key": key, "value": value}, f)
        os.replace(tmp, path)
    except (OSError, TypeError, ValueError):
        try:
            os.unlink(tmp)
        except (OSError, UnboundLocalError):
            pass
