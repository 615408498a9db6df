"""Math used in component equations, for both numbers (NumPy) and CasADi symbols.

Components write each equation once with these functions. Evaluated with floats they give
floats (the reference NumPy path); evaluated with CasADi SX symbols they build the graph the
network compiles into one function with exact Jacobians.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["sqrt", "exp", "tanh", "fabs", "fmax", "fmin", "sign", "if_else", "matvec",
           "smooth_sqrt", "is_symbolic", "log", "power", "vertcat"]

_SYM = (ca.SX, ca.MX, ca.DM)


def is_symbolic(*args) -> bool:
    """True when any argument is a CasADi expression."""
    return any(isinstance(a, _SYM) for a in args)


def _pick(*args):
    return ca if is_symbolic(*args) else np


def sqrt(x):
    return _pick(x).sqrt(x)


def exp(x):
    return _pick(x).exp(x)


def log(x):
    return _pick(x).log(x)


def tanh(x):
    return _pick(x).tanh(x)


def fabs(x):
    return ca.fabs(x) if is_symbolic(x) else np.abs(x)


def sign(x):
    return ca.sign(x) if is_symbolic(x) else np.sign(x)


def power(x, a):
    return x**a


def fmax(a, b):
    return ca.fmax(a, b) if is_symbolic(a, b) else np.maximum(a, b)


def fmin(a, b):
    return ca.fmin(a, b) if is_symbolic(a, b) else np.minimum(a, b)


def if_else(cond, a, b):
    """``a`` where ``cond`` else ``b`` (both branches are evaluated)."""
    if is_symbolic(cond, a, b):
        return ca.if_else(cond, a, b)
    return np.where(cond, a, b)


def matvec(M, x):
    """Constant matrix times a vector of numbers or symbols."""
    if is_symbolic(x):
        return ca.mtimes(ca.DM(M), x)
    return np.asarray(M) @ np.asarray(x, dtype=float)


def vertcat(items):
    """Stack scalars into a column (CasADi) or a 1-D array (NumPy)."""
    if is_symbolic(*items):
        return ca.vertcat(*items)
    return np.array([float(v) for v in items])


def smooth_sqrt(dp, transition):
    """``sgn(dp) sqrt|dp|`` with a laminar (linear) region for ``|dp| << transition``.

    ``dp / (dp^2 + transition^2)^(1/4)``: equals ``sgn(dp) sqrt|dp|`` to 1 % for
    ``|dp| > 7 transition`` and is linear, ``dp/sqrt(transition)``, near zero, so the
    orifice equation (M20) has a finite slope at zero pressure drop. [sqrt(Pa)]
    """
    return dp / sqrt(sqrt(dp * dp + transition * transition))
