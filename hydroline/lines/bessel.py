"""Bessel functions and polygamma sums the line models need, in NumPy alone.

A line's realisation (:mod:`hydroline.lines.residue`, :mod:`hydroline.lines.corrections`)
needs ``I0, I1, I2`` of a complex argument (M6), ``J0, J1`` and the zeros of ``J0, J2`` on
the real axis (the viscous poles) and the polygamma functions of order 1 and 3 (the dropped
modes' angle sums). :mod:`scipy.special` has them all, but importing it costs ~0.15-0.3 s
(its array-API layer), which was most of a whole ``hydroline simulate`` process whose rig
changed only a number (a bulk modulus or a length: the line is realised again). These are
accurate to a few units in the last place of the largest term (checked against SciPy in
``tests/test_bessel.py``).

Methods (Abramowitz & Stegun; NIST DLMF chapter 10):

* ``|z| <= 2``: the power series ``I_v(z) = (z/2)^v sum (z^2/4)^k / (k! (k + v)!)`` (every
  term at most 1 in modulus: no cancellation worth a digit);
* ``2 < |z| < 20``: Miller's backward recurrence ``I_{k-1} = I_{k+1} + (2k/z) I_k`` from
  order ``MILLER_START``, normalised by ``e^z = I_0 + 2 sum_{k>=1} I_k`` (I_k is the minimal
  solution: the recurrence is stable backwards, and the sum has no cancellation for
  ``Re z >= 0``);
* ``|z| >= 20``: the asymptotic expansion with both exponentials (DLMF 10.40.5),
  ``I_v(z) ~ e^z/sqrt(2 pi z) sum (-1)^k a_k(v)/z^k + i e^{i v pi} e^{-z}/sqrt(2 pi z)
  sum a_k(v)/z^k`` for ``Im z >= 0`` (the conjugate for ``Im z < 0``), valid up to and on
  the imaginary axis; ``ASYMPTOTIC_TERMS`` terms leave < 1e-17 at ``|z| = 20``.
"""
from __future__ import annotations

import functools
import math

import numpy as np

__all__ = ["scaled_bessel_i012", "bessel_j01", "bessel_j_zeros", "polygamma"]

#: Below this modulus the power series, [-].
SERIES_LIMIT = 2.0

#: From this modulus the asymptotic expansion, [-].
ASYMPTOTIC_LIMIT = 20.0

#: Terms of the asymptotic expansion (the smallest term of the v = 2 series at ``|z| = 20`` is
#: below 1e-17 by then), [-].
ASYMPTOTIC_TERMS = 26

#: Order Miller's backward recurrence starts from at most; ``1.25 |z| + 30`` below that
#: (``I_55(20)/I_0(20) ~ 1e-26``, ``J_55(20)/J_0(20) ~ 5e-18``), [-].
MILLER_START = 70

#: Terms of the power series for ``|z| <= 2`` (``1/(17!)^2 < 1e-29``), [-].
SERIES_TERMS = 17


@functools.lru_cache(maxsize=1)
def _asymptotic_coefficients() -> np.ndarray:
    """Rows ``(-1)^k a_k(v)`` and ``a_k(v)`` (DLMF 10.17.1) for v = 0, 1, 2, columns
    k = 0 .. ASYMPTOTIC_TERMS - 1: shape (6, ASYMPTOTIC_TERMS)."""
    rows = []
    for v in range(3):
        mu = 4.0 * v**2
        a = [1.0]
        for k in range(1, ASYMPTOTIC_TERMS):
            a.append(a[-1] * (mu - (2 * k - 1) ** 2) / (k * 8.0))
        rows.append(a)
    a = np.array(rows)
    return np.vstack([a * (-1.0) ** np.arange(ASYMPTOTIC_TERMS), a])


def _series(z):
    """I0, I1, I2 of ``|z| <= 2`` by their power series (unscaled), rows of one array."""
    q = z * z / 4.0
    v = np.arange(3)[:, None]
    term = np.ones((3, z.size), dtype=complex)
    total = term.copy()
    for k in range(1, SERIES_TERMS):
        term = term * q / (k * (k + v))
        total = total + term
    return total * (z / 2.0) ** v / np.array([[1.0], [1.0], [2.0]])


def _miller(z):
    """I0, I1, I2 of ``2 < |z| < 20`` times ``e^{-Re z}`` by backward recurrence, rows of
    one array."""
    two_over_z = 2.0 / z
    f_next, f = np.zeros_like(z), np.full_like(z, 1e-30)
    total = np.zeros_like(z)
    start = min(MILLER_START, int(np.abs(z).max() * 1.25) + 30)
    kept = []
    for k in range(start, 0, -1):              # f = f_k, f_next = f_{k+1}
        total += f
        if k <= 2:
            kept.append(f)
        f_next, f = f, f_next + (k * two_over_z) * f
    # f is now f_0; e^z = f_0 + 2 sum_{k>=1} f_k (in the recurrence's units)
    scale = np.exp(1j * z.imag) / (f + 2.0 * total)
    return np.array([f, kept[1], kept[0]]) * scale


def _asymptotic(z, orders):
    """I_v of ``|z| >= 20`` times ``e^{-Re z}`` for v in ``orders`` (DLMF 10.40.5), rows of one
    array. The ``e^{-z}`` series is left out where ``Re z >= 21`` everywhere: it is below
    ``e^{-42} = 6e-19`` of the other there."""
    w = 1.0 / z
    root = np.sqrt(2.0 * np.pi * z)
    near = np.exp(1j * z.imag) / root                      # e^{z - Re z}/sqrt(2 pi z)
    far_needed = z.real.min() < 21.0
    rows = list(orders) + ([3 + v for v in orders] if far_needed else [])
    a = _asymptotic_coefficients()[rows]
    # terms needed at the smallest |z|: |a_k|/|z|^k below 1e-18 from there on
    reach = np.abs(a).max(axis=0) / np.abs(z).min() ** np.arange(ASYMPTOTIC_TERMS)
    terms = int(np.argmax(reach < 1e-18)) + 1 if np.any(reach < 1e-18) else ASYMPTOTIC_TERMS
    acc = np.zeros((len(rows), z.size), dtype=complex)
    for k in range(terms - 1, -1, -1):                      # Horner in 1/z
        acc = acc * w + a[:, k:k + 1]
    m = len(orders)
    if not far_needed:
        return near * acc
    sigma = np.where(z.imag >= 0.0, 1.0, -1.0)
    far = np.exp(-2.0 * z.real - 1j * z.imag) / root       # e^{-z - Re z}/sqrt(2 pi z)
    sign = np.array([[(-1.0) ** v] for v in orders])
    return near * acc[:m] + (sigma * 1j * far) * sign * acc[m:]


def scaled_bessel_i012(z, orders=(0, 1, 2)):
    """``I0(z), I1(z), I2(z)`` times ``e^{-|Re z|}`` for complex z with ``Re z >= 0``.

    SciPy's ``ive(v, z)`` for v = 0, 1, 2, without importing :mod:`scipy.special`
    (module docstring). The scaling cancels in the ratios the line models use and keeps
    every value finite.

    Parameters
    ----------
    z : complex or array_like
        Argument with ``Re z >= 0``, e.g. ``kappa = r sqrt(s/nu)`` (principal root), [-].
    orders : tuple of int
        Which of the orders 0, 1, 2, in the order wanted (fewer cost less), [-].

    Returns
    -------
    tuple of complex ndarrays
        ``ive(v, z)`` for v in ``orders``, each of the shape of ``z``, [-].

    Examples
    --------
    >>> i0, i1, i2 = scaled_bessel_i012(1.0)
    >>> round(float(i0.real) * math.e, 12)     # I0(1) = 1.266065877752
    1.266065877752
    """
    z = np.asarray(z, dtype=complex)
    shape = z.shape
    z = z.ravel()
    size = np.abs(z)
    small, large = size <= SERIES_LIMIT, size >= ASYMPTOTIC_LIMIT
    orders = [int(v) for v in orders]
    if large.all():
        out = _asymptotic(z, orders)
    else:
        out = np.empty((len(orders), z.size), dtype=complex)
        middle = ~(small | large)
        if small.any():
            zs = z[small]
            out[:, small] = _series(zs)[orders] * np.exp(-zs.real)
        if middle.any():
            out[:, middle] = _miller(z[middle])[orders]
        if large.any():
            out[:, large] = _asymptotic(z[large], orders)
    return tuple(o.reshape(shape) for o in out)


def _j_series(x):
    """J0, J1 of ``x <= 2`` by their power series (terms at most 1: no cancellation)."""
    q = -x * x / 4.0
    out = []
    for v in range(2):
        term = np.ones_like(x)
        total = term.copy()
        for k in range(1, SERIES_TERMS):
            term = term * q / (k * (k + v))
            total = total + term
        out.append(total * (x / 2.0) ** v)
    return out


def _j_miller(x):
    """J0, J1 of ``2 < x < 20`` by the backward recurrence ``J_{k-1} = (2k/x) J_k - J_{k+1}``,
    normalised by ``1 = J0 + 2 sum J_{2k}``."""
    two_over_x = 2.0 / x
    start = 2 * ((int(x.max() * 1.25) + 30) // 2)              # even
    f_next, f = np.zeros_like(x), np.full_like(x, 1e-30)
    even = np.zeros_like(x)
    f1 = None
    for k in range(start, 0, -1):              # f = f_k, f_next = f_{k+1}
        if k % 2 == 0:
            even += f
        elif k == 1:
            f1 = f
        f_next, f = f, (k * two_over_x) * f - f_next
    norm = f + 2.0 * even
    return f / norm, f1 / norm


@functools.lru_cache(maxsize=1)
def _hankel_coefficients() -> np.ndarray:
    """Rows P0, Q0, P1, Q1 of the Hankel expansion (DLMF 10.17.3) as polynomials in
    ``1/x^2``: ``P_v = sum (-1)^k a_2k(v) x^-2k``, ``Q_v x = sum (-1)^k a_2k+1(v) x^-2k``."""
    rows = []
    for v in range(2):
        mu = 4.0 * v**2
        a = [1.0]
        for k in range(1, 2 * ASYMPTOTIC_TERMS):
            a.append(a[-1] * (mu - (2 * k - 1) ** 2) / (k * 8.0))
        sign = (-1.0) ** np.arange(ASYMPTOTIC_TERMS)
        rows += [sign * np.array(a[0::2]), sign * np.array(a[1::2])]
    return np.array(rows)


def _j_hankel(x):
    """J0, J1 of ``x >= 20``: ``sqrt(2/(pi x)) (P cos chi - Q sin chi)``,
    ``chi = x - (v/2 + 1/4) pi`` (DLMF 10.17.3)."""
    c = _hankel_coefficients()
    w = 1.0 / (x * x)
    reach = np.abs(c).max(axis=0) / x.min() ** (2.0 * np.arange(ASYMPTOTIC_TERMS))
    terms = int(np.argmax(reach < 1e-18)) + 1 if np.any(reach < 1e-18) else ASYMPTOTIC_TERMS
    acc = np.zeros((4, x.size))
    for k in range(terms - 1, -1, -1):
        acc = acc * w + c[:, k:k + 1]
    amp = np.sqrt(2.0 / (np.pi * x))
    out = []
    for v in range(2):
        chi = x - (0.5 * v + 0.25) * np.pi
        out.append(amp * (acc[2 * v] * np.cos(chi) - acc[2 * v + 1] / x * np.sin(chi)))
    return out


def bessel_j01(x):
    """``J0(x), J1(x)`` of real x >= 0 (SciPy's ``j0``, ``j1``).

    Power series below 2, Miller's backward recurrence below 20, Hankel's expansion above.

    Parameters
    ----------
    x : float or array_like
        Argument, >= 0, [-].

    Returns
    -------
    tuple of two float ndarrays
        ``J0(x), J1(x)``, of the shape of ``x``; absolute error a few 1e-16, [-].

    Examples
    --------
    >>> j0, j1 = bessel_j01(1.0)
    >>> round(float(j0), 12), round(float(j1), 12)
    (0.765197686558, 0.440050585745)
    """
    x = np.asarray(x, dtype=float)
    shape = x.shape
    x = x.ravel()
    j0, j1 = np.empty_like(x), np.empty_like(x)
    small, large = x <= SERIES_LIMIT, x >= ASYMPTOTIC_LIMIT
    middle = ~(small | large)
    for part, method in ((small, _j_series), (middle, _j_miller), (large, _j_hankel)):
        if part.any():
            j0[part], j1[part] = method(x[part])
    return j0.reshape(shape), j1.reshape(shape)


def _bessel_j(order: int, x):
    """J_order(x) and its derivative, order 0 or 2."""
    j0, j1 = bessel_j01(x)
    if order == 0:
        return j0, -j1
    j2 = 2.0 * j1 / x - j0
    return j2, j1 - 2.0 * j2 / x


@functools.lru_cache(maxsize=16)
def _zeros(order: int, count: int) -> np.ndarray:
    m = np.arange(1, count + 1, dtype=float)
    beta = (m + order / 2.0 - 0.25) * np.pi                 # McMahon (DLMF 10.21.19)
    mu = 4.0 * order**2
    x = beta - (mu - 1.0) / (8.0 * beta) - 4.0 * (mu - 1.0) * (7.0 * mu - 31.0) / (
        3.0 * (8.0 * beta) ** 3)
    for _ in range(50):
        f, df = _bessel_j(order, x)
        step = f / df
        x = x - step
        if np.all(np.abs(step) <= 1e-15 * x):
            break
    f, df = _bessel_j(order, x)                              # one more: to the last ulp
    return x - f / df


def bessel_j_zeros(order: int, count: int) -> np.ndarray:
    """The first ``count`` positive zeros of ``J_order``, order 0 or 2 (SciPy's
    ``jn_zeros``): Newton's method from McMahon's expansion.

    Parameters
    ----------
    order : int
        0 or 2, [-].
    count : int
        Number of zeros, [-].

    Returns
    -------
    ndarray
        The zeros, ascending, [-].

    Examples
    --------
    >>> [round(float(v), 10) for v in bessel_j_zeros(0, 2)]
    [2.4048255577, 5.5200781103]
    """
    if order not in (0, 2):
        raise ValueError(f"order must be 0 or 2, got {order!r}")
    return _zeros(int(order), int(count)).copy()


#: Bernoulli numbers B_2, B_4, ..., B_16
_BERNOULLI = (1 / 6, -1 / 30, 1 / 42, -1 / 30, 5 / 66, -691 / 2730, 7 / 6, -3617 / 510)


def polygamma(order: int, x):
    """The polygamma function of order 1 or 3 for real x > 0 (SciPy's ``polygamma``).

    ``psi^(m)(x) = (-1)^(m+1) m! sum_k 1/(x + k)^(m+1)``: the terms below 20 summed, the rest
    by the asymptotic expansion in Bernoulli numbers.

    Parameters
    ----------
    order : int
        1 (trigamma) or 3, [-].
    x : float or array_like
        Argument, > 0, [-].

    Returns
    -------
    float or ndarray
        ``psi^(order)(x)``, [-].

    Examples
    --------
    >>> round(float(polygamma(1, 1.0)), 14) == round(math.pi**2 / 6, 14)
    True
    """
    if order not in (1, 3):
        raise ValueError(f"order must be 1 or 3, got {order!r}")
    m = order
    x = np.asarray(x, dtype=float)
    shift = np.maximum(np.ceil(20.0 - x), 0.0)
    top = int(shift.max()) if shift.size else 0
    head = np.zeros_like(x)
    for k in range(top):
        head = head + np.where(k < shift, 1.0 / (x + k) ** (m + 1), 0.0)
    y = x + shift
    tail = math.factorial(m - 1) / y**m + math.factorial(m) / (2.0 * y ** (m + 1))
    for k, b in enumerate(_BERNOULLI, start=1):
        tail = tail + b * math.factorial(2 * k + m - 1) / (math.factorial(2 * k) * y ** (2 * k + m))
    value = math.factorial(m) * head + tail                 # (-1)^(m+1) = 1 for m = 1, 3
    return value if value.ndim else float(value)
