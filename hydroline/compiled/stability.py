"""Where the compiled core's NDF orders 3-5 stop being stable on a network's oscillatory modes.

The integrator (``bdf.c``) uses the numerical differentiation formulas NDF1-5 of Shampine &
Reichelt (SIAM J. Sci. Comput. 18, 1997), in backward-difference form with the coefficients
``KAPPA`` below. Applied to ``y' = lambda y`` with step h, NDF of order q is

    sum_{m=1..q} (1/m) w^m - kappa_q gamma_q w^(q+1) = z,   w = 1 - 1/zeta,  z = h lambda,

(gamma_q = 1 + 1/2 + ... + 1/q), and it is stable where every root zeta has ``|zeta| <= 1``.
Orders 1 and 2 are A-stable; orders 3-5 are only A(alpha)-stable (alpha ~ 81, 66 and 51
degrees): a lightly damped mode (lambda near the imaginary axis, e.g. a short hose's upper
modes at 10-25 kHz and 5 % damping) makes them unstable once ``|h lambda|`` passes ~0.6-0.9.
The step-size control then holds h just below that limit at orders 3-4 (tens of thousands of
3.9 us steps for a 0.05 m hose section) where order 2 would take steps set by accuracy alone.

:func:`order_step_limits` gives, for a set of eigenvalues, the largest step each order may
take before one of them leaves its stability region (the lower edge of the unstable band
along the eigenvalue's ray, from the boundary locus of the formula); the C core keeps an
order only while its step stays below that limit (``hl_set_order_limits``) and otherwise
steps at a lower order. :func:`block_eigenvalues` finds the eigenvalues cheaply: each
component's own block of the Jacobian (a hose section's modes are its own to within a
fraction of a per cent; the coupled network's full 58 x 58 eigenproblem costs ~1 ms).
"""
from __future__ import annotations

import functools

import numpy as np

__all__ = ["KAPPA", "unstable_onset", "order_step_limits", "block_eigenvalues",
           "eigenvalues_of_blocks", "block_gather", "cut_blocks", "MARGIN"]

#: NDF coefficients kappa_q, q = 0..5 (as ``hl_kappa`` in ``bdf.c``; SciPy's BDF)
KAPPA = (0.0, -0.1850, -1.0 / 9.0, -0.0823, -0.0415, 0.0)
#: Fraction of the stability limit a step may reach (the block eigenvalues are estimates)
MARGIN = 0.95
#: Orders whose stability region is not the whole left half-plane
LIMITED_ORDERS = (3, 4, 5)


def _gamma(q: int) -> float:
    return sum(1.0 / j for j in range(1, q + 1))


def locus(q: int, n: int = 8192) -> np.ndarray:
    """The boundary locus z(theta) of NDF order q (``|zeta| = 1``), theta in (0, pi] (the curve is
    symmetric about the real axis).

    Parameters
    ----------
    q : int
        Order, 1-5
    n : int
        Points, [-]

    Returns
    -------
    ndarray
        complex z = h lambda on the boundary, [-]
    """
    theta = np.linspace(0.0, np.pi, n + 1)[1:]
    w = 1.0 - np.exp(-1j * theta)
    z = sum((1.0 / m) * w**m for m in range(1, q + 1))
    return z - KAPPA[q] * _gamma(q) * w ** (q + 1)


@functools.lru_cache(maxsize=None)
def _onset_table(q: int):
    """(angles [rad], lower edge of the unstable band [-]) of NDF order q, angles measured from
    the negative real axis (0: a real decaying mode, pi/2: an undamped oscillation)."""
    z = locus(q)
    phi = np.arctan2(z.imag, -z.real)          # in (0, pi) for the upper half
    r = np.abs(z)
    grid = np.linspace(0.0, np.pi / 2, 721)
    onset = np.full(grid.shape, np.inf)
    # where the locus crosses each ray (segments between neighbouring locus points), the
    # smallest radius; the locus leaves the origin tangent to the imaginary axis on its right
    # (phi > pi/2), so rays into the left half-plane meet it only where the bulge of the
    # unstable region reaches over
    a, b = phi[:-1], phi[1:]
    ra, rb = r[:-1], r[1:]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    seg = np.flatnonzero(hi - lo < 0.5)
    # every (segment, grid angle within it) pair, without a loop over the grid (~1 ms a table,
    # once per process: it is met at the first run's first step)
    first = np.searchsorted(grid, lo[seg], "left")
    count = np.searchsorted(grid, hi[seg], "right") - first
    seg = np.repeat(seg, count)
    k = np.repeat(first - np.cumsum(count) + count, count) + np.arange(count.sum())
    s = (grid[k] - a[seg]) / np.where(b[seg] != a[seg], b[seg] - a[seg], 1.0)
    radii = ra[seg] + s * (rb[seg] - ra[seg])
    far = radii > 1e-6
    np.minimum.at(onset, k[far], radii[far])
    return grid, onset


def unstable_onset(q: int, angle) -> np.ndarray:
    """Smallest ``|h lambda|`` at which NDF order q becomes unstable on a mode whose eigenvalue
    makes ``angle`` with the negative real axis; inf where the whole ray is stable.

    Parameters
    ----------
    q : int
        Order, 1-5
    angle : array
        Angle of h lambda from the negative real axis, [rad] (0..pi/2)

    Returns
    -------
    ndarray
        ``|h lambda|`` at the onset, [-]
    """
    grid, onset = _onset_table(q)
    # (searchsorted's indices are >= 0: only the top needs the clip)
    idx = np.minimum(np.searchsorted(grid, np.asarray(angle, dtype=float)), len(grid) - 1)
    # the next grid angle up: nearer the imaginary axis, the band starts lower (conservative)
    return onset[idx]


def order_step_limits(eigenvalues) -> tuple:
    """Largest step of each order 1-5 for which every given eigenvalue stays inside the
    order's stability region (times :data:`MARGIN`); inf where none limits it.

    Parameters
    ----------
    eigenvalues : array
        Eigenvalues of the Jacobian, [1/s]

    Returns
    -------
    tuple
        (h_1, ..., h_5), [s]
    """
    lam = np.asarray(eigenvalues, dtype=complex).ravel()
    lam = lam[np.isfinite(lam) & (lam.real < 0) & (lam.imag != 0)]
    limits = [np.inf] * 5
    if lam.size:
        angle = np.arctan2(np.abs(lam.imag), -lam.real)
        size = np.abs(lam)
        for q in LIMITED_ORDERS:
            h = unstable_onset(q, angle) / size
            limits[q - 1] = MARGIN * float(h.min())
    return tuple(limits)


_EIGEN_CACHE: dict = {}
_EIGEN_CACHE_SIZE = 256


def _eigvals_2x2(sub: np.ndarray) -> np.ndarray:
    """Eigenvalues of a 2 x 2 matrix in closed form, [1/s]."""
    a, b, c, d = sub[0, 0], sub[0, 1], sub[1, 0], sub[1, 1]
    mean, det = 0.5 * (a + d), a * d - b * c
    root = np.sqrt(complex(mean * mean - det))
    return np.array([mean + root, mean - root])


def _remember(key, w: np.ndarray) -> np.ndarray:
    """Keep a block's eigenvalues by its value (a hose section's block is the same in every
    run of its numbers), the oldest dropped past :data:`_EIGEN_CACHE_SIZE`; returns ``w``."""
    if len(_EIGEN_CACHE) >= _EIGEN_CACHE_SIZE:
        _EIGEN_CACHE.pop(next(iter(_EIGEN_CACHE)))
    _EIGEN_CACHE[key] = w
    return w


def block_eigenvalues(jacobian, blocks) -> np.ndarray:
    """Eigenvalues of the diagonal blocks of a Jacobian (each component's own states).

    Parameters
    ----------
    jacobian : ndarray
        Dense Jacobian, [1/s] (scaled or not: similar blocks)
    blocks : list
        Slices or index arrays of the states of each block

    Returns
    -------
    ndarray
        complex, [1/s]
    """
    return eigenvalues_of_blocks(
        [jacobian[b, b] if isinstance(b, slice) else jacobian[np.ix_(b, b)] for b in blocks])


def eigenvalues_of_blocks(subs) -> np.ndarray:
    """Eigenvalues of square matrices, one after another (:func:`block_eigenvalues` of blocks
    already cut out): 2 x 2 ones in closed form, larger ones not met before (remembered by
    value) of one size in one LAPACK call (a sweep's variant has two new 32 x 32 hose blocks); blocks smaller than
    2 x 2 or not finite are left out.

    Parameters
    ----------
    subs : list
        Square blocks of a Jacobian, [1/s]

    Returns
    -------
    ndarray
        complex, [1/s]
    """
    out = [None] * len(subs)
    new = {}         # size -> [(index, key, block)] not in the memory
    for i, sub in enumerate(subs):
        if sub.shape[0] < 2 or not np.isfinite(sub).all():
            continue
        sub = np.ascontiguousarray(sub)
        if sub.shape[0] == 2:
            out[i] = _eigvals_2x2(sub)
            continue
        key = (sub.shape[0], sub.tobytes())
        w = _EIGEN_CACHE.get(key)
        if w is None:
            new.setdefault(sub.shape[0], []).append((i, key, sub))
        else:
            out[i] = w
    for group in new.values():
        ws = np.linalg.eigvals(np.stack([sub for _, _, sub in group])) if len(group) > 1 \
            else [np.linalg.eigvals(group[0][2])]
        for (i, key, _), w in zip(group, ws):
            out[i] = _remember(key, w)
    out = [w for w in out if w is not None]
    return np.concatenate(out) if out else np.zeros(0, dtype=complex)


def block_gather(colind, rows, blocks) -> tuple:
    """Where the diagonal blocks of a compressed-column matrix lie among its nonzeros: made
    once per network, so that a run cuts its blocks out of the nonzeros in one gather,
    without a dense matrix (:meth:`hydroline.compiled.NativeModel.order_limits`).

    Parameters
    ----------
    colind : array
        Column starts of the nonzeros (n + 1 of them), [-]
    rows : array
        Row of each nonzero, [-]
    blocks : list
        Slices of the states of each block

    Returns
    -------
    tuple
        ``(take, place, sizes)``: the nonzeros ``take`` go to the flat positions ``place``
        of one buffer holding the blocks one after another (each ``m x m``, row by row,
        zero where the matrix has no nonzero); ``sizes`` the blocks' m, [-]
    """
    colind = np.asarray(colind, dtype=np.intp)
    rows = np.asarray(rows, dtype=np.intp)
    cols = np.repeat(np.arange(colind.size - 1), np.diff(colind))
    take, place, sizes = [], [], []
    offset = 0
    for b in blocks:
        a, m = b.start, b.stop - b.start
        k = np.flatnonzero((cols >= a) & (cols < b.stop) & (rows >= a) & (rows < b.stop))
        take.append(k)
        place.append(offset + (rows[k] - a) * m + (cols[k] - a))
        sizes.append(m)
        offset += m * m
    empty = np.zeros(0, dtype=np.intp)
    return (np.concatenate(take) if take else empty, np.concatenate(place) if place else empty,
            tuple(sizes))


def cut_blocks(nonzeros, gather) -> list:
    """The diagonal blocks of a compressed-column matrix cut out of its nonzeros, by the
    positions :func:`block_gather` found (one gather into one buffer).

    Parameters
    ----------
    nonzeros : ndarray
        The matrix's nonzeros, in its compressed-column order, [1/s]
    gather : tuple
        ``(take, place, sizes)`` of :func:`block_gather` for this matrix's pattern

    Returns
    -------
    list
        The blocks, each ``m x m`` (views of one buffer), [1/s].
    """
    take, place, sizes = gather
    flat = np.zeros(sum(m * m for m in sizes))
    flat[place] = nonzeros[take]
    blocks, at = [], 0
    for m in sizes:
        blocks.append(flat[at:at + m * m].reshape(m, m))
        at += m * m
    return blocks
