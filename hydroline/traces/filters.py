"""Sliding-window filters of a sampled signal, in NumPy alone.

The same results as ``scipy.signal.savgol_filter(..., mode="interp")`` and
``scipy.ndimage.maximum_filter1d`` / ``minimum_filter1d`` / ``uniform_filter1d`` with
``mode="nearest"`` (to rounding; the suite compares them), for the oscillation metrics of
every run: importing ``scipy.signal`` and ``scipy.ndimage`` costs more start-up than a cached
simulation.
"""
from __future__ import annotations

import numpy as np

__all__ = ["savgol_filter", "maximum_filter1d", "minimum_filter1d", "uniform_filter1d"]


def _check_mode(mode, supported):
    if mode != supported:
        raise ValueError(f"mode must be {supported!r} (the only edge treatment here), got {mode!r}")


def savgol_filter(x, window_length: int, polyorder: int, mode: str = "interp") -> np.ndarray:
    """Savitzky-Golay smoothing: at each sample, the value of the least-squares polynomial of
    degree ``polyorder`` through the ``window_length`` samples centred on it (odd window); in
    the first and last half-windows, the polynomial fitted to the first / last window (SciPy's
    ``mode="interp"``).

    Parameters
    ----------
    x : array_like
        The signal, [any unit]
    window_length : int
        Odd number of samples, polyorder < window_length <= len(x)
    polyorder : int
        Degree of the polynomial
    mode : str
        "interp" (the only edge treatment)

    Returns
    -------
    ndarray
        The smoothed signal, [unit of x]
    """
    _check_mode(mode, "interp")
    x = np.asarray(x, dtype=float)
    n, w = len(x), int(window_length)
    if w % 2 != 1 or not polyorder < w <= n:
        raise ValueError(f"window_length must be odd, > polyorder and <= len(x) = {n}; got {w}")
    half = w // 2
    centre, first, last = _savgol_weights(w, int(polyorder))
    y = np.empty(n)
    if n > 2 * half:
        y[half:n - half] = np.convolve(x, centre[::-1], mode="valid")
    y[:half] = first @ x[:w]
    y[n - half:] = last @ x[n - w:]
    return y


_SAVGOL_WEIGHTS: dict = {}


def _savgol_weights(w: int, polyorder: int):
    """Weights of :func:`savgol_filter` for a window of ``w`` samples, kept by (w, polyorder):
    the centre's (the least-squares polynomial's value at the middle sample) and the first
    and last half-windows' (the polynomial fitted to the first / last window, evaluated at
    their samples: ``polyval(polyfit(k, x[:w]), k[:half])`` as one matrix, equal to round-off)."""
    key = (w, polyorder)
    if key not in _SAVGOL_WEIGHTS:
        # by the normal equations of polynomials in a variable scaled to [-1, 1] / [0, 1]
        # (well conditioned at these degrees; an SVD per new window cost ~0.1 ms)
        half = w // 2
        powers = np.arange(polyorder + 1)
        u = np.arange(-half, half + 1, dtype=float) / max(half, 1)
        A = u[:, None] ** powers[None, :]                              # (w, polyorder + 1)
        centre = A @ np.linalg.solve(A.T @ A, np.eye(polyorder + 1)[0])  # value at u = 0
        k = np.arange(w, dtype=float) / (w - 1)
        V = k[:, None] ** powers[None, :]
        fit = np.linalg.solve(V.T @ V, V.T)                             # samples -> coefficients
        first, last = V[:half] @ fit, V[w - half:] @ fit
        if len(_SAVGOL_WEIGHTS) >= 64:
            _SAVGOL_WEIGHTS.clear()
        _SAVGOL_WEIGHTS[key] = (centre, first, last)
    return _SAVGOL_WEIGHTS[key]


def _nearest_windows(x, size):
    """x padded by its edge values so that window i covers samples i - size//2 .. i + (size-1)//2."""
    x = np.asarray(x, dtype=float)
    if int(size) < 1:
        raise ValueError(f"size must be >= 1, got {size!r}")
    left, right = size // 2, (size - 1) // 2
    return np.concatenate([np.full(left, x[0]), x, np.full(right, x[-1])])


def _running_extreme(x, size, accumulate):
    """Max (or min) over sliding windows of ``size`` samples (van Herk / Gil-Werman: block-wise
    prefix and suffix extremes, O(n) whatever the size)."""
    size = int(size)
    padded = _nearest_windows(x, size)
    n = len(x)
    if size == 1 or n == 0:
        return padded[:n].copy()
    blocks = -(-len(padded) // size)
    fill = accumulate.identity if hasattr(accumulate, "identity") else None
    ext = np.full(blocks * size, np.nan if fill is None else fill)
    ext[:len(padded)] = padded
    ext[len(padded):] = padded[-1]
    b = ext.reshape(blocks, size)
    forward = accumulate.accumulate(b, axis=1).ravel()
    backward = accumulate.accumulate(b[:, ::-1], axis=1)[:, ::-1].ravel()
    i = np.arange(n)
    return accumulate(backward[i], forward[i + size - 1])


def maximum_filter1d(x, size: int, mode: str = "nearest") -> np.ndarray:
    """Largest sample in the window of ``size`` samples about each sample (edges repeated:
    SciPy's ``mode="nearest"``), [unit of x].

    Parameters
    ----------
    x : array_like
        Evenly sampled signal, [any unit]
    size : int
        Window length, >= 1, [samples]
    mode : str
        Edge treatment; only ``"nearest"`` (edges repeated)

    Returns
    -------
    ndarray
        Filtered signal, as long as x, [unit of x]
    """
    _check_mode(mode, "nearest")
    return _running_extreme(x, size, np.maximum)


def minimum_filter1d(x, size: int, mode: str = "nearest") -> np.ndarray:
    """Smallest sample in the window of ``size`` samples about each sample (edges repeated:
    SciPy's ``mode="nearest"``), [unit of x].

    Parameters
    ----------
    x : array_like
        Evenly sampled signal, [any unit]
    size : int
        Window length, >= 1, [samples]
    mode : str
        Edge treatment; only ``"nearest"`` (edges repeated)

    Returns
    -------
    ndarray
        Filtered signal, as long as x, [unit of x]
    """
    _check_mode(mode, "nearest")
    return _running_extreme(x, size, np.minimum)


def uniform_filter1d(x, size: int, mode: str = "nearest") -> np.ndarray:
    """Mean of the window of ``size`` samples about each sample (edges repeated: SciPy's
    ``mode="nearest"``), [unit of x].

    Parameters
    ----------
    x : array_like
        Evenly sampled signal, [any unit]
    size : int
        Window length, >= 1, [samples]
    mode : str
        Edge treatment; only ``"nearest"`` (edges repeated)

    Returns
    -------
    ndarray
        Filtered signal, as long as x, [unit of x]
    """
    _check_mode(mode, "nearest")
    size = int(size)
    padded = _nearest_windows(x, size)
    c = np.concatenate([[0.0], np.cumsum(padded)])
    return (c[size:size + len(x)] - c[:len(x)]) / size
