"""The envelope of long traces over time, gathered block by block as the rows arrive.

A long run (a 10-minute fatigue test: six million rows) drawn through a decimated copy of its
rows aliases its waveform into a solid block. What shows drift or growth over the run is, per
time bin, the lowest, mean and highest value of each trace, taken from every row;
:class:`BinnedEnvelope` gathers them in memory fixed by the number of bins, together with the
last rows of the run at full rate (where the waveform itself can be seen).
"""
from __future__ import annotations

import numpy as np

__all__ = ["BinnedEnvelope"]


class BinnedEnvelope:
    """Per time bin the lowest, mean and highest value of some columns, from every row, and
    the last ``tail_rows`` rows of those columns as they are. Pass :meth:`update` as
    ``observe`` to :func:`hydroline.simulate` (or call it with each block of rows of a
    measured trace). Memory: four numbers per bin and column, and the tail, whatever the
    number of rows.

    A row at time ``t`` belongs to bin ``k`` when ``edges[k] <= t < edges[k + 1]``
    (``edges`` evenly spaced from ``t_start`` to ``t_end``); rows before ``t_start`` count in
    the first bin, rows at or after ``t_end`` in the last.

    Parameters
    ----------
    columns : list[str]
        Columns of the rows to follow, [SI]
    t_start : float
        Start of the first bin, [s]
    t_end : float
        End of the last bin, [s] (greater than ``t_start``)
    bins : int
        Number of bins, [-]
    tail_rows : int
        Rows at the end of the run kept as they are, [-] (0: none)
    differences : dict
        Derived columns followed as well: name -> ``(a, b)``, the column
        ``a - b`` (e.g. the tracking error, reference minus position), [SI];
        None: none
    """

    def __init__(self, columns, t_start: float, t_end: float, bins: int = 1500,
                 tail_rows: int = 0, differences: dict | None = None):
        if not t_end > t_start:
            raise ValueError(f"BinnedEnvelope: t_end ({t_end!r} s) must be greater than "
                             f"t_start ({t_start!r} s)")
        if int(bins) < 1:
            raise ValueError(f"BinnedEnvelope: bins must be >= 1, got {bins!r}")
        self.columns = list(columns)
        self.differences = dict(differences or {})
        self.names = self.columns + list(self.differences)
        self.edges = np.linspace(float(t_start), float(t_end), int(bins) + 1)
        n = len(self.names)
        self.lowest = np.full((int(bins), n), np.inf)
        self.highest = np.full((int(bins), n), -np.inf)
        self.total = np.zeros((int(bins), n))
        self.count = np.zeros(int(bins), dtype=np.int64)
        self.tail_rows = max(int(tail_rows), 0)
        self.tail_parts = []      # (t, values) blocks, together at least tail_rows rows
        self.index = None

    def update(self, t, table, columns) -> None:
        """Take in one block of rows (ascending times, after the previous block's).

        Parameters
        ----------
        t : numpy.ndarray
            Times of the block, ascending, [s]
        table : numpy.ndarray
            Its rows, one column per name in ``columns``, [SI]
        columns : list[str]
            The table's column names (those followed among them)
        """
        if not len(t):
            return
        if self.index is None:
            where = {c: i for i, c in enumerate(columns)}
            self.index = [where[c] for c in self.columns]
            self.pairs = [(where[a], where[b]) for a, b in self.differences.values()]
        t = np.asarray(t, dtype=float)
        table = np.asarray(table)
        values = table[:, self.index]
        if self.pairs:
            values = np.column_stack([values] + [table[:, a] - table[:, b]
                                                 for a, b in self.pairs])
        k = np.clip(np.searchsorted(self.edges, t, side="right") - 1, 0, len(self.count) - 1)
        starts = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
        at = k[starts]            # (ascending: each bin once in a block)
        self.lowest[at] = np.minimum(self.lowest[at], np.minimum.reduceat(values, starts, axis=0))
        self.highest[at] = np.maximum(self.highest[at],
                                      np.maximum.reduceat(values, starts, axis=0))
        self.total[at] += np.add.reduceat(values, starts, axis=0)
        self.count[at] += np.diff(np.r_[starts, len(t)])
        if self.tail_rows:
            if len(t) >= self.tail_rows:
                self.tail_parts = [(t[-self.tail_rows:].copy(), values[-self.tail_rows:].copy())]
            else:
                self.tail_parts.append((t.copy(), values.copy()))
                held = sum(len(p[0]) for p in self.tail_parts)
                while held - len(self.tail_parts[0][0]) >= self.tail_rows:
                    held -= len(self.tail_parts.pop(0)[0])

    def bands(self):
        """The envelope of each column, over the bins that hold rows.

        Returns
        -------
        tuple
            ``(t, lowest, mean, highest)``: the middle of each bin that holds a row, [s],
            and three dicts name -> per bin the lowest, mean and highest value, [SI].
        """
        full = self.count > 0
        t = 0.5 * (self.edges[:-1] + self.edges[1:])[full]
        mean = self.total[full] / self.count[full, None]
        return (t, *({name: part[:, j] for j, name in enumerate(self.names)}
                     for part in (self.lowest[full], mean, self.highest[full])))

    def tail(self):
        """The last rows taken in (at most ``tail_rows``) as they are.

        Returns
        -------
        tuple
            ``(t, values)``: times, [s], and a dict name -> values at those times, [SI].
        """
        if not self.tail_parts:
            return np.empty(0), {name: np.empty(0) for name in self.names}
        t = np.concatenate([p[0] for p in self.tail_parts])[-self.tail_rows:]
        rows = np.vstack([p[1] for p in self.tail_parts])[-self.tail_rows:]
        return t, {name: rows[:, j] for j, name in enumerate(self.names)}
