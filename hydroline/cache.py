"""hydroline's on-disk cache: compiled model libraries and small computed tables.

Directory: ``$HYDROLINE_CACHE_DIR``, else ``$XDG_CACHE_HOME/hydroline``, else
``~/.cache/hydroline``. Everything in it can be deleted at any time; it is rebuilt on demand.

The tables are bounded: each kind keeps about :data:`MAX_ENTRIES` files, the least recently
used removed first (:func:`prune_tables`, run by one :func:`store_table` in
:data:`PRUNE_EVERY` at random, so that many short processes prune as often as one long one;
a read refreshes an entry's time at most once an hour).
"""
from __future__ import annotations

import hashlib
import json
import os
import random
import tempfile
import time
from pathlib import Path

__all__ = ["cache_dir", "load_table", "store_table", "source_tag", "prune_tables",
           "least_recently_used", "mark_used", "MAX_ENTRIES"]

#: Most entries kept per table kind (a correction-factor entry is ~0.5 kB, a model record
#: ~10 kB), [-]
MAX_ENTRIES = 2000
#: One write in this many prunes its kind (at random; a pruning of 2000 entries costs ~15 ms),
#: [-]
PRUNE_EVERY = 100
#: A read refreshes an entry's modification time when it is older than this, [s]
_TOUCH_AFTER = 3600.0


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
    path = _table_path(kind, key)
    try:
        with open(path) as f:
            entry = json.load(f)
            mtime = os.fstat(f.fileno()).st_mtime
        if entry.get("key") != key:
            return None
        mark_used(path, mtime)      # recently used: kept by prune_tables
        return entry["value"]
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
        with os.fdopen(fd, "w") as f:   # (dumps: the C encoder; dump streams in Python)
            f.write(json.dumps({"key": key, "value": value}))
        os.replace(tmp, path)
    except (OSError, TypeError, ValueError):
        try:
            os.unlink(tmp)
        except (OSError, UnboundLocalError):
            pass
        return
    if random.random() * PRUNE_EVERY < 1.0:
        prune_tables(kind)


def prune_tables(kind: str, max_entries: int | None = None) -> int:
    """Remove the least recently used entries of a table kind beyond ``max_entries`` (down to
    90 % of it, so that pruning is not needed at every write), and temporary files of
    interrupted writes older than an hour. Errors are ignored (another process may prune
    the same directory at the same time).

    Parameters
    ----------
    kind : str          Sub-directory of the cache naming the table
    max_entries : int   Entries kept at most, [-] (:data:`MAX_ENTRIES` when None)

    Returns
    -------
    int  Files removed, [-]
    """
    max_entries = MAX_ENTRIES if max_entries is None else int(max_entries)
    entries, stale = [], []
    now = time.time()
    try:
        with os.scandir(cache_dir() / kind) as it:
            for e in it:
                try:
                    mtime = e.stat().st_mtime
                except OSError:
                    continue
                if e.name.endswith(".json"):
                    entries.append((mtime, e.path))
                elif e.name.endswith(".tmp") and now - mtime > 3600:
                    stale.append(e.path)
    except OSError:
        return 0
    drop = stale + least_recently_used(entries, max_entries)
    removed = 0
    for path in drop:
        try:
            os.unlink(path)
            removed += 1
        except OSError:
            pass
    return removed


def least_recently_used(entries, max_entries: int, at_least: int = 0) -> list:
    """Of a cache's entries, those to remove: none while there are at most ``max_entries``,
    else the least recently used down to 90 % of it (so that pruning is not needed at every
    write), keeping ``at_least`` of the newest.

    Parameters
    ----------
    entries : list      (modification time [s since the epoch], path) of each entry
    max_entries : int   Entries kept at most, [-]
    at_least : int      Newest entries always kept, [-]

    Returns
    -------
    list  paths, least recently used first
    """
    if len(entries) <= max_entries:
        return []
    entries = sorted(entries)
    return [path for _, path in entries[:len(entries) - max(int(0.9 * max_entries), at_least)]]


def mark_used(path, mtime: float | None = None) -> None:
    """Give a cache file a fresh modification time (its last use, which the pruning goes by),
    at most once in :data:`_TOUCH_AFTER`; errors are ignored.

    Parameters
    ----------
    path : str or Path   The file
    mtime : float        Its modification time when known, [s since the epoch] (else read)
    """
    try:
        if mtime is None:
            mtime = os.stat(path).st_mtime
        if time.time() - mtime > _TOUCH_AFTER:
            os.utime(path)
    except OSError:
        pass
