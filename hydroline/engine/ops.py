"""Math used in component equations, for both numbers (NumPy) and CasADi symbols.

Components write each equation once with these functions. Evaluated with floats they give
floats (the reference NumPy path); evaluated with CasADi SX symbols they build the graph the
network compiles into one function with exact Jacobians. CasADi is not imported here: a
process that only evaluates numbers (a run of a model loaded from the cache) never loads it.
"""
from __future__ import annotations

import sys

import numpy as np

__all__ = ["sqrt", "exp", "tanh", "fabs", "fmax", "fmin", "sign", "if_else", "matvec",
           "smooth_sqrt", "softplus", "is_symbolic", "log", "power", "vertcat", "pairwise_sum"]

_SYM = ()   # CasADi's expression types, once CasADi is loaded


def _symbol_types() -> tuple:
    global _SYM
    ca = sys.modules.get("casadi")
    if ca is not None and hasattr(ca, "DM"):   # (not while casadi itself is being imported)
        _SYM = (ca.SX, ca.MX, ca.DM)
    return _SYM


def _casadi():
    """The CasADi module (loaded already by whoever made the symbols)."""
    import casadi

    return casadi


def is_symbolic(*args) -> bool:
    """True when any argument is a CasADi expression.

    Parameters
    ----------
    *args : object
        Values to inspect: numbers, arrays or CasADi ``SX``/``MX``/``DM``.

    Returns
    -------
    bool
        Whether the CasADi branch of the operations below is taken.

    Examples
    --------
    >>> import casadi as ca
    >>> is_symbolic(1.0, 2.0), is_symbolic(1.0, ca.SX.sym("p"))
    (False, True)
    """
    sym = _SYM or _symbol_types()   # no CasADi expression exists before CasADi is loaded
    return bool(sym) and any(isinstance(a, sym) for a in args)


def _pick(*args):
    return _casadi() if is_symbolic(*args) else np


def sqrt(x):
    """Square root, ``x >= 0``.

    Parameters
    ----------
    x : float, array_like or CasADi expression
        Argument, in its own unit [any].

    Returns
    -------
    float, ndarray or CasADi expression
        ``sqrt(x)``, [sqrt of the unit of x].
    """
    return _pick(x).sqrt(x)


def exp(x):
    """Exponential.

    Parameters
    ----------
    x : float, array_like or CasADi expression
        Dimensionless argument, [-].

    Returns
    -------
    float, ndarray or CasADi expression
        ``exp(x)``, [-].
    """
    return _pick(x).exp(x)


def log(x):
    """Natural logarithm, ``x > 0``.

    Parameters
    ----------
    x : float, array_like or CasADi expression
        Dimensionless argument, [-].

    Returns
    -------
    float, ndarray or CasADi expression
        ``ln(x)``, [-].
    """
    return _pick(x).log(x)


def tanh(x):
    """Hyperbolic tangent (used to regularise sgn, e.g. in the friction of (M24)).

    Parameters
    ----------
    x : float, array_like or CasADi expression
        Dimensionless argument, [-].

    Returns
    -------
    float, ndarray or CasADi expression
        ``tanh(x)`` in (-1, 1), [-].
    """
    return _pick(x).tanh(x)


def fabs(x):
    """Absolute value.

    Parameters
    ----------
    x : float, array_like or CasADi expression
        Argument, [any].

    Returns
    -------
    float, ndarray or CasADi expression
        ``|x|``, [unit of x].
    """
    return _casadi().fabs(x) if is_symbolic(x) else np.abs(x)


def sign(x):
    """Sign: -1, 0 or +1.

    Parameters
    ----------
    x : float, array_like or CasADi expression
        Argument, [any].

    Returns
    -------
    float, ndarray or CasADi expression
        ``sgn(x)``, [-].
    """
    return _casadi().sign(x) if is_symbolic(x) else np.sign(x)


def power(x, a):
    """Power ``x**a``.

    Parameters
    ----------
    x : float, array_like or CasADi expression
        Base, [any].
    a : float or CasADi expression
        Exponent, [-].

    Returns
    -------
    float, ndarray or CasADi expression
        ``x**a``, [unit of x to the power a].
    """
    return x**a


def fmax(a, b):
    """Elementwise maximum.

    Parameters
    ----------
    a, b : float, array_like or CasADi expression
        Values of the same unit, [any].

    Returns
    -------
    float, ndarray or CasADi expression
        ``max(a, b)``, [unit of a].
    """
    return _casadi().fmax(a, b) if is_symbolic(a, b) else np.maximum(a, b)


def fmin(a, b):
    """Elementwise minimum.

    Parameters
    ----------
    a, b : float, array_like or CasADi expression
        Values of the same unit, [any].

    Returns
    -------
    float, ndarray or CasADi expression
        ``min(a, b)``, [unit of a].
    """
    return _casadi().fmin(a, b) if is_symbolic(a, b) else np.minimum(a, b)


def if_else(cond, a, b):
    """``a`` where ``cond`` else ``b`` (both branches are evaluated).

    Parameters
    ----------
    cond : bool, array_like of bool or CasADi expression
        Condition, [-].
    a, b : float, array_like or CasADi expression
        Values where the condition holds / does not hold, same unit, [any].

    Returns
    -------
    float, ndarray or CasADi expression
        The selected values, [unit of a].
    """
    if is_symbolic(cond, a, b):
        return _casadi().if_else(cond, a, b)
    return np.where(cond, a, b)


def matvec(M, x):
    """Constant matrix times a vector of numbers or symbols.

    Parameters
    ----------
    M : array_like
        Constant matrix, shape (m, n), [SI, output unit per input unit].
    x : array_like or CasADi expression
        Vector of length n, [SI].

    Returns
    -------
    ndarray or CasADi expression
        ``M x``, length m, [SI].
    """
    if is_symbolic(x):
        ca = _casadi()
        return ca.mtimes(ca.DM(M), x)
    return np.asarray(M) @ np.asarray(x, dtype=float)


def pairwise_sum(terms):
    """The sum of the terms added pairwise, ``((a + b) + (c + d)) + ...``: a symbolic sum of n
    terms is then about log2(n) additions deep instead of a chain of n, so that the compiled
    code's additions do not each wait for the one before (a hose section's output gathers
    every one of its states: 80 at 30 modes per section).

    Parameters
    ----------
    terms : sequence of float or CasADi expressions
        The terms, [SI, one unit].

    Returns
    -------
    float or CasADi expression
        Their sum (0.0 when there are none), [SI].
    """
    terms = list(terms)
    if not terms:
        return 0.0
    while len(terms) > 1:
        terms = [terms[i] + terms[i + 1] if i + 1 < len(terms) else terms[i]
                 for i in range(0, len(terms), 2)]
    return terms[0]


def vertcat(items):
    """Stack scalars into a column (CasADi) or a 1-D array (NumPy).

    Parameters
    ----------
    items : sequence of float or CasADi expressions
        The scalars, in order, [SI, each item's own unit].

    Returns
    -------
    ndarray or CasADi expression
        Column of the items, [SI, unit of each item].
    """
    if is_symbolic(*items):
        return _casadi().vertcat(*items)
    return np.array([float(v) for v in items])


def smooth_sqrt(dp, transition):
    """``sgn(dp) sqrt|dp|`` with a laminar (linear) region for ``|dp| << transition``.

    ``dp / (dp^2 + transition^2)^(1/4)``: equals ``sgn(dp) sqrt|dp|`` to 1 % for
    ``|dp| > 7 transition`` and is linear, ``dp/sqrt(transition)``, near zero, so the
    orifice equation (M20) has a finite slope at zero pressure drop.

    Parameters
    ----------
    dp : float, array_like or CasADi expression
        Pressure drop across the orifice, [Pa].
    transition : float or CasADi expression
        Pressure drop below which the flow turns laminar, > 0, [Pa].

    Returns
    -------
    float, ndarray or CasADi expression
        Regularised signed square root, [sqrt(Pa)].

    Examples
    --------
    Far above the transition it is the turbulent square root; at zero drop its slope is
    ``1/sqrt(transition)``:

    >>> round(float(smooth_sqrt(1e6, 1e4)), 2)    # sqrt(1e6) (1 - 1e-4/4) = 999.975
    999.98
    >>> round(float(smooth_sqrt(1.0, 1e4)), 9)    # 1/sqrt(1e4) = 0.01
    0.01
    """
    return dp / sqrt(sqrt(dp * dp + transition * transition))


def softplus(y, width):
    """Smooth positive part ``max(y, 0) + w ln(1 + exp(-|y|/w))``: equals ``max(y, 0)`` to
    ``w exp(-|y|/w)`` a few ``w`` away from zero, with no kink there (a valve that opens at a
    cracking pressure, a check valve's forward branch).

    Parameters
    ----------
    y : float, array_like or CasADi expression
        Argument, in its own unit [any].
    width : float or CasADi expression
        Width ``w`` of the smooth region, > 0, [unit of y].

    Returns
    -------
    float, ndarray or CasADi expression
        The smooth positive part, [unit of y].

    Examples
    --------
    >>> round(float(softplus(5.0, 0.1)), 9), round(float(softplus(-5.0, 0.1)), 9)
    (5.0, 0.0)
    >>> round(float(softplus(0.0, 0.1)), 6)    # w ln 2
    0.069315
    """
    return fmax(y, 0.0) + width * log(1.0 + exp(-fabs(y) / width))

