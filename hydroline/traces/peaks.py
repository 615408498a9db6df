"""Peaks of a sampled signal by prominence or spacing, in NumPy alone.

The same peaks as :func:`scipy.signal.find_peaks` for the two criteria hydroline uses
(``prominence`` and ``distance``; the suite compares the two), without importing
``scipy.signal``, which loads ``scipy.stats`` and costs about a second of start-up in a
command that only wants the oscillation metrics of one run.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["find_peaks", "local_maxima", "peak_prominence"]


def local_maxima(x) -> np.ndarray:
    """Indices of the local maxima of ``x``: samples higher than both neighbours, or flat
    tops (a run of equal samples higher than the samples on either side), given by their
    middle sample (the lower of the two middle ones for an even run). The first and last
    samples are never maxima.

    Parameters
    ----------
    x : array_like
        Evenly sampled signal, [any unit]

    Returns
    -------
    ndarray
        Indices of the maxima, increasing, [samples]
    """
    x = np.asarray(x, dtype=float)
    n = len(x)
    if n < 3:
        return np.zeros(0, dtype=np.intp)
    d = x[1:] - x[:-1]       # (np.diff's operation, without its overhead)
    if d.all():     # no flat stretch (the usual case): a top is one sample, up then down
        return np.flatnonzero((d[:-1] > 0) & (d[1:] < 0)) + 1
    rising = np.flatnonzero(d > 0)        # x[i] < x[i + 1]: a top may start at i + 1
    nonflat = np.flatnonzero(d != 0)      # next change after each position
    if nonflat.size == 0:
        return np.zeros(0, dtype=np.intp)
    starts = rising + 1
    # first change at or after each start: where the top ends
    k = np.searchsorted(nonflat, starts)
    ok = k < nonflat.size
    starts, k = starts[ok], k[ok]
    ends = nonflat[k]                      # d[ends] != 0: x[ends] != x[ends + 1]
    falling = d[ends] < 0
    left, right = starts[falling], ends[falling]
    return ((left + right) // 2).astype(np.intp)


def peak_prominence(x, peak: int) -> float:
    """Topographic prominence of one peak of ``x`` (no window; as
    :func:`scipy.signal.peak_prominences`): its height above the higher of the lowest points
    on either side before the signal rises above the peak again.

    Parameters
    ----------
    x : ndarray
        The signal, float, [any unit]
    peak : int
        Index of a local maximum of ``x``, [samples]

    Returns
    -------
    float
        Prominence, >= 0, [unit of x]
    """
    h = x[peak]
    higher_left = np.flatnonzero(x[:peak] > h)
    i0 = higher_left[-1] + 1 if higher_left.size else 0
    higher_right = np.flatnonzero(x[peak + 1:] > h)
    i1 = peak + 1 + higher_right[0] if higher_right.size else len(x)
    return float(h - max(x[i0:peak + 1].min(), x[peak:i1].min()))


def _prominences(x, peaks):
    """Topographic prominence of each peak (:func:`peak_prominence`)."""
    out = np.empty(len(peaks))
    for m, p in enumerate(peaks):
        out[m] = peak_prominence(x, p)
    return out


def find_peaks(x, prominence: float | None = None, distance: float | None = None):
    """Local maxima of ``x`` kept by minimum ``prominence`` and/or minimum spacing.

    Parameters
    ----------
    x : array_like
        The signal, [any unit]
    prominence : float
        Least prominence kept, [unit of x] (None: no condition)
    distance : float
        Least spacing of kept peaks, [samples]; where peaks are closer the
        higher one stays (None: no condition)

    Returns
    -------
    peaks : ndarray of int
        Indices of the peaks, ascending, [-]
    properties : dict
        With ``"prominences"`` when a prominence was asked for (as
        :func:`scipy.signal.find_peaks`).
    """
    x = np.asarray(x, dtype=float)
    peaks = local_maxima(x)
    props = {}
    if distance is not None and peaks.size > 1:
        spacing = math.ceil(distance)
        keep = np.ones(peaks.size, dtype=bool)
        order = np.argsort(x[peaks])
        for j in order[::-1]:
            if not keep[j]:
                continue
            k = j - 1
            while k >= 0 and peaks[j] - peaks[k] < spacing:
                keep[k] = False
                k -= 1
            k = j + 1
            while k < peaks.size and peaks[k] - peaks[j] < spacing:
                keep[k] = False
                k += 1
        peaks = peaks[keep]
    if prominence is not None:
        # a peak's prominence is at most its height above the signal's minimum: test only
        # those that can pass (the many small ripples of a padded spectrum cannot)
        floor = x.min() if x.size else 0.0
        peaks = peaks[x[peaks] - floor >= prominence]
        prom = _prominences(x, peaks)
        keep = prom >= prominence
        peaks, props["prominences"] = peaks[keep], prom[keep]
    return peaks, props
