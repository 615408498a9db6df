"""Numbers computed from a line's parameters (correction factors, exact-pole realisations),
kept in this process and in the on-disk cache (:mod:`hydroline.cache`): a later build of the
same line skips the root finding, and a later process reads them in about a millisecond."""
from __future__ import annotations

import threading
from collections import OrderedDict

from ..cache import load_table, store_table

__all__ = ["LineMemo", "kept_in_memory"]


class _DiskUse(threading.local):
    """Per thread: False inside :class:`kept_in_memory`, where the on-disk cache is neither
    read nor written. Per thread, because a sweep on a Dask cluster of threads runs variants
    in several threads at once: one process-wide flag, saved and restored by overlapping
    ``with`` blocks, was left False after the sweep, and every later line of the process was
    solved again and never stored."""

    store = True


_DISK = _DiskUse()


class kept_in_memory:
    """Context manager: line numbers computed inside it (in this thread) are kept in this
    process's tables only, neither looked up in nor written to the on-disk cache
    (:mod:`hydroline.cache`). A sweep's worker meets thousands of lines (one per hose length)
    that no later run asks for again: a file per line filled the cache directory (13 000 files
    after a few sweeps), and a look-up that misses costs about as much as a solve."""

    def __enter__(self):
        self._saved, _DISK.store = _DISK.store, False
        return self

    def __exit__(self, *exc):
        _DISK.store = self._saved
        return False


class LineMemo:
    """One kind of line numbers: the last ``kept`` values of this process, most recent last,
    and the on-disk table ``kind``.

    Parameters
    ----------
    kind : str
        The cache's table kind, e.g. ``"correction_factors"``.
    kept : int
        Values kept in this process, [-].
    """

    def __init__(self, kind: str, kept: int = 512):
        self.kind, self.kept = kind, kept
        self.memory: OrderedDict = OrderedDict()

    def get(self, key: str, compute, encode, decode):
        """The value of ``key``: from this process, else from disk (``decode(stored)``, None
        when the stored value does not fit), else ``compute()``, stored as ``encode(value)``.

        Parameters
        ----------
        key : str
            Everything the value depends on (the numbers and the source of the code).
        compute : callable
            ``compute() -> value``.
        encode : callable
            ``encode(value) -> JSON-able``.
        decode : callable
            ``decode(stored) -> value or None``.

        Returns
        -------
        object
            The value; the caller copies what it may change.
        """
        known = self.memory.get(key)
        if known is not None:
            self.memory.move_to_end(key)
            return known
        value = None
        if _DISK.store:
            stored = load_table(self.kind, key)
            if stored is not None:
                try:
                    value = decode(stored)
                except (TypeError, ValueError, KeyError, IndexError):
                    value = None
        if value is None:
            value = compute()
            if _DISK.store:
                store_table(self.kind, key, encode(value))
        self.memory[key] = value
        if len(self.memory) > self.kept:
            self.memory.popitem(last=False)
        return value
