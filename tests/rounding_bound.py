"""A bound on the rounding difference between two evaluations of a network's right-hand side
(the compiled C library against the per-component Python), derived from the evaluation itself.

Each rounding in an evaluation is a relative perturbation of at most u = 2^-53 of an
intermediate result. To first order, the difference of two evaluations that round differently
(another operation order, fused multiply-adds, another libm) is therefore bounded by a small
multiple of u times the sum of the magnitudes of the terms an output is made of, not times the
output itself, which may be a near-cancellation of large terms (a chamber's dp/dt at rest).
The magnitudes of the terms are taken from the componentwise condition of the evaluation,
|df/dx|·|x| + |df/dp|·|p| + |f| (exact for sums of monomials in the states and parameters, and
within a factor of the powers involved for sqrt, tanh and quotients), with the derivatives from
CasADi's graph of the components' equations, not from the C code under test.
"""
import numpy as np

#: Unit roundoff of IEEE double precision, [-]
UNIT_ROUNDOFF = np.finfo(float).eps / 2
#: Roundings along one output's longest chain of operations, with margin: a conservative
#: count (the deepest line and valve terms take ~20 operations), [-]
ROUNDINGS = 64


def term_magnitudes(net, t, x, p=None):
    """|df/dx|·|x| + |df/dp|·|p| + |f| for each derivative of the network at (t, x), [state
    units/s].

    Parameters
    ----------
    net : hydroline.engine.Network
        The assembled network.
    t : float
        Time, [s].
    x : ndarray
        States, [SI].
    p : ndarray, optional
        Runtime parameters, [SI]; the network's values when None.
    """
    import casadi as ca

    cm = net.compile()
    p = np.asarray(net.parameter_values if p is None else p, dtype=float)
    x = np.asarray(x, dtype=float)
    jx = cm.jacobian(t, x, p)
    jp = np.asarray(ca.densify(ca.Function("jacobian_p", [cm.t, cm.x, cm.p],
                                           [ca.jacobian(cm.dx, cm.p)])(t, x, p)))
    f = cm.rhs(t, x, p)
    return np.abs(jx) @ np.abs(x) + np.abs(jp) @ np.abs(p) + np.abs(f)


def rounding_bound(net, t, x, p=None):
    """The largest difference two correct double-precision evaluations of the network's
    derivatives at (t, x) may show, per state, [state units/s] (see the module's text).

    Parameters
    ----------
    net : hydroline.engine.Network
        The assembled network.
    t : float
        Time, [s].
    x : ndarray
        States, [SI].
    p : ndarray, optional
        Runtime parameters, [SI]; the network's values when None.
    """
    return ROUNDINGS * UNIT_ROUNDOFF * term_magnitudes(net, t, x, p)
