"""hydroline's on-disk cache: compiled model libraries and small computed tables.

Directory: ``$HYDROLINE_CACHE_DIR``, else ``$XDG_CACHE_HOME/hydroline``, else
``~/.cache/hydroline``. Everything in it can be deleted at any time; it is rebuilt on demand.

The tables are bounded: each kind keeps about :data:`MAX_ENTRIES` files, the least recently
used removed first (:func:`prune_tables`, run by one :func:`store_table` in
:data:`PRUNE_EVERY` at random, so that many short processes prune as often as one long one;
a read refreshes an entry's time at most once an hour).

Every entry is verified when it is read: a table's file holds the key it was made for and a
SHA-256 of that key with its value (:func:`table_checksum`); a compiled library's build record
holds its size, SHA-256 and key (:mod:`hydroline.compiled`). An entry that fails (numbers
altered, another key's file, a damaged or truncated file) is discarded with one
:class:`CacheWarning` naming the file, and computed again: a wrong entry is never used, and
what follows from it is never blamed on the rig. An entry of the format before the checksums
(no ``sha256`` field) is a quiet miss: computed again and overwritten.

Shipped tables: the package holds the entries the default rig's first commands need
(:data:`SHIPPED_TABLES`, written by ``tools/ship_tables.py``: its lines' realisations), in the
cache's own format; :func:`load_table` reads one where the cache has none, so a first run
after installing skips that work (and SciPy's Bessel functions). Their keys name the source
of the code that computed them: after a change of that code they are simply not found.
"""
from __future__ import annotations

import hashlib
import json
import os
import random
import tempfile
import time
import warnings
from pathlib import Path

__all__ = ["cache_dir", "load_table", "store_table", "source_tag", "prune_tables",
           "least_recently_used", "mark_used", "MAX_ENTRIES", "CacheWarning", "table_checksum",
           "discard_table", "discard_entry", "BACKGROUND_BUILD_ENV", "builds_in_background",
           "SHIPPED_TABLES"]

#: Most entries kept per table kind (a correction-factor entry is ~0.5 kB, a model record
#: ~10 kB), [-]
MAX_ENTRIES = 2000
#: One write in this many prunes its kind (at random; a pruning of 2000 entries costs ~15 ms),
#: [-]
PRUNE_EVERY = 100
#: Directory of the tables shipped with the package (one sub-directory per kind, files named
#: as in the cache), read where the cache has no entry
SHIPPED_TABLES = Path(__file__).with_name("shipped_tables")
#: A read refreshes an entry's modification time when it is older than this, [s]
_TOUCH_AFTER = 3600.0


def cache_dir() -> Path:
    """Directory of the cache (created on demand by its writers).

    Returns
    -------
    pathlib.Path
        ``$HYDROLINE_CACHE_DIR``, else ``$XDG_CACHE_HOME/hydroline``, else
        ``~/.cache/hydroline``.
    """
    env = os.environ.get("HYDROLINE_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "hydroline"


#: Environment variable: ``1`` lets a run whose compiled library is not built yet go on
#: without it (CVODES) while it is built in a background process
#: (:func:`hydroline.compiled.native_model`); ``0`` or unset compiles it first. The command
#: line sets it to ``1`` for its runs unless it is set (a first ``hydroline simulate`` would
#: otherwise wait for the compiler); a program gets the compiled core from its first run on
#: unless it sets it.
BACKGROUND_BUILD_ENV = "HYDROLINE_BACKGROUND_BUILD"


def builds_in_background() -> bool:
    """Whether a compiled library not built yet is built in the background
    (:data:`BACKGROUND_BUILD_ENV`).

    Returns
    -------
    bool
        True where ``$HYDROLINE_BACKGROUND_BUILD`` is set to anything but ``0``.
    """
    return os.environ.get(BACKGROUND_BUILD_ENV, "").strip() not in ("", "0")


def source_tag(*paths) -> str:
    """A short hash of source files.

    Part of a cache key, so that a change of the code that computes a table makes its old
    entries unused.

    Parameters
    ----------
    *paths : str or Path
        The source files.

    Returns
    -------
    str
        16 hexadecimal digits of the SHA-256 of the files' contents.
    """
    h = hashlib.sha256()
    for p in paths:
        h.update(Path(p).read_bytes())
    return h.hexdigest()[:16]


class CacheWarning(UserWarning):
    """A cache entry failed its check (altered, another key's, damaged) and is computed again.

    Parameters
    ----------
    *args : str
        The message: one line naming the file and what is wrong with it.
    **kwargs : dict
        None taken (as ``UserWarning``).
    """


def _table_path(kind: str, key: str, root: Path | None = None) -> Path:
    root = cache_dir() if root is None else root
    return root / kind / (hashlib.sha256(key.encode()).hexdigest()[:32] + ".json")


def table_checksum(key: str, value) -> str:
    """SHA-256 (hex) of a table entry's key and value as its file holds them: the key, a zero
    byte, and the value's JSON text as :func:`json.dumps` writes it (the text a reader
    hashes, without parsing it first).

    Parameters
    ----------
    key : str
        Everything the value depends on
    value : object
        JSON value (lists, dicts, numbers, strings)

    Returns
    -------
    str
        64 hexadecimal digits
    """
    return _checksum(key, json.dumps(value).encode())


def _checksum(key: str, text: bytes) -> str:
    h = hashlib.sha256(key.encode())
    h.update(b"\0")
    h.update(text)
    return h.hexdigest()


#: A table file's text: ``{"key": <key>, "sha256": "<64 hex>", "value": <value>}``
_HEAD, _MIDDLE = '{{"key": {}, "sha256": "', '", "value": '


def load_table(kind: str, key: str):
    """The JSON value stored under ``key`` (a string naming every input), or None when absent,
    unreadable or not the value stored for that key.

    The entry is verified: the key it holds must be ``key`` and the checksum it holds must
    be that of the key and the value's text (:func:`table_checksum`). One that fails (numbers
    altered, a file copied from another key, damaged JSON) is discarded with one
    :class:`CacheWarning` naming the file (:func:`discard_entry`), so the caller computes the
    value again; an entry without a checksum (the format before them) is a quiet miss.
    Where the cache has no file for ``key``, the package's shipped entry is read
    (:data:`SHIPPED_TABLES`, verified alike; one that fails is a quiet miss, left there) and
    stored in the cache.

    Parameters
    ----------
    kind : str
        Sub-directory of the cache naming the table, e.g. ``"correction_factors"``
    key : str
        Everything the value depends on (inputs, :func:`source_tag` of the code)

    Returns
    -------
    object or None
        The stored JSON value (lists, dicts, numbers, strings)
    """
    path = _table_path(kind, key)
    try:
        with open(path, "rb") as f:
            raw = f.read()
            mtime = os.fstat(f.fileno()).st_mtime
    except OSError:                 # absent (or unreadable: the cache only saves time)
        value = _shipped_table(kind, key)
        if value is not None:       # kept in the cache as if computed (and verified alike)
            store_table(kind, key, value)
        return value
    value = _verified_value(raw, key)
    if value is not _FAILED:
        mark_used(path, mtime)      # recently used: kept by prune_tables
        return value
    why = _table_fault(raw, key)
    if why:
        discard_entry(path, why=why)
    return None


#: :func:`_verified_value`'s answer for a file that fails its check
_FAILED = object()


def _verified_value(raw: bytes, key: str):
    """The value of a table file's text where it holds ``key`` and its checksum; else
    :data:`_FAILED`."""
    head = _HEAD.format(json.dumps(key)).encode()
    start = len(head) + 64 + len(_MIDDLE)
    if (raw.startswith(head) and raw[start - len(_MIDDLE):start] == _MIDDLE.encode()
            and raw.endswith(b"}")
            and _checksum(key, raw[start:-1]).encode() == raw[len(head):len(head) + 64]):
        try:
            return json.loads(raw[start:-1])
        except (ValueError, RecursionError):
            pass
    return _FAILED


def _shipped_table(kind: str, key: str):
    """The value of the shipped entry (:data:`SHIPPED_TABLES`) for ``key``, verified as a
    cached one; None where there is none or it fails (left as it is: a package's file)."""
    try:
        raw = _table_path(kind, key, SHIPPED_TABLES).read_bytes()
    except OSError:
        return None
    value = _verified_value(raw, key)
    return None if value is _FAILED else value


def _table_fault(raw: bytes, key: str) -> str:
    """Why a table file failed its check ("" for the format before checksums)."""
    try:
        entry = json.loads(raw)
        if "sha256" not in entry and "value" in entry:
            return ""
        return ("it was made for another key" if entry["key"] != key else
                "its content does not match its checksum")
    except (ValueError, KeyError, TypeError, RecursionError):
        return "it is not a readable entry"


def discard_table(kind: str, key: str, why: str) -> None:
    """Discard the entry stored under ``key`` that its reader found wrong (its value does not
    fit what it was stored for), with one :class:`CacheWarning` naming the file.

    Parameters
    ----------
    kind : str
        Sub-directory of the cache naming the table, e.g. ``"models"``
    key : str
        The key it is stored under
    why : str
        What is wrong with it (part of the warning)
    """
    discard_entry(_table_path(kind, key), why=why)


def discard_entry(*paths, why: str) -> None:
    """Remove a cache entry's files (errors ignored) and say so in one :class:`CacheWarning`
    naming the first file; whoever needs the entry computes it again.

    Parameters
    ----------
    *paths : Path
        The entry's files (a table's file; a library and its build record)
    why : str
        What is wrong with it (part of the warning)
    """
    for p in paths:
        try:
            os.unlink(p)
        except OSError:
            pass
    warnings.warn(f"cache entry {paths[0]} failed its check ({why}): discarded and rebuilt",
                  CacheWarning, stacklevel=2)


def store_table(kind: str, key: str, value) -> None:
    """Store a JSON-serialisable value under ``key`` with the key and a checksum of both
    (:func:`table_checksum`; atomic rename; errors ignored: the cache only saves time).

    Parameters
    ----------
    kind : str
        Sub-directory of the cache naming the table, e.g. ``"correction_factors"``
    key : str
        Everything the value depends on (inputs, :func:`source_tag` of the code)
    value : object
        JSON-serialisable value (lists, dicts, numbers, strings)
    """
    path = _table_path(kind, key)
    try:
        text = json.dumps(value)        # (dumps: the C encoder; dump streams in Python)
        head = _HEAD.format(json.dumps(key))
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
        with os.fdopen(fd, "w") as f:
            f.write(f"{head}{_checksum(key, text.encode())}{_MIDDLE}{text}}}")
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
    kind : str
        Sub-directory of the cache naming the table
    max_entries : int
        Entries kept at most, [-] (:data:`MAX_ENTRIES` when None)

    Returns
    -------
    int
        Files removed, [-]
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
    entries : list
        (modification time [s since the epoch], path) of each entry
    max_entries : int
        Entries kept at most, [-]
    at_least : int
        Newest entries always kept, [-]

    Returns
    -------
    list
        Paths of the entries to remove, least recently used first.
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
    path : str or Path
        The file
    mtime : float
        Its modification time when known, [s since the epoch] (else read)
    """
    try:
        if mtime is None:
            mtime = os.stat(path).st_mtime
        if time.time() - mtime > _TOUCH_AFTER:
            os.utime(path)
    except OSError:
        pass
