"""Modal line with the exact poles and exact residues of the dissipative model (M5)-(M6).

``ModalLine(line, n, form, method="residue")`` builds its matrices with
:func:`residue_realisation`. The derivation, from (M5)-(M6) to the matrices below, is in
``docs/residue_line.md``; in short, every entry ``H(s)`` of a form's transfer matrix
(docs/model.md table 2.1) is meromorphic in s and is written as

    H(s) = sum_{k<=n} [ R_k/(s - p_k) + conj ]          retained modes, exact
         + column term (PP: 1/(Zc Gamma); QQ: 1/(s C))   k = 0 term
         + V(s)                                          real-axis "viscous" poles
         + T(s)                                          dropped modes k > n

* **Poles** ``p_k``: the first n roots in the upper half plane of ``cosh Gamma(s) = 0`` (PQ,
  QP; ``Gamma = j (k - 1/2) pi``) or ``sinh Gamma(s) = 0`` (PP, QQ; ``Gamma = j k pi``), found
  by :func:`hydroline.lines.corrections.dissipative_root` -- the roots (M15) uses.
* **Residues** ``R_k``: numerator over the derivative of the denominator, e.g. for PQ
  ``R_k = [[1, -Zc sinh G], [sinh G/Zc, 1]] / (sinh G * G')`` at ``s = p_k``, with
  ``G' = dGamma/ds`` from the analytic derivative of ``I0/I2`` (:func:`propagation_derivative`).
  ``R_k`` has rank one (its determinant is proportional to ``cosh^2 Gamma = 0`` for PQ/QP,
  ``sinh^2 Gamma = 0`` for PP/QQ), so each complex pair is realised with two real states.
* **k = 0 term**: PP, the laminar fluid column ``1/(Zc Gamma) = I2(kappa)/(s I I0(kappa))``,
  whose exact partial fractions are parallel R-L branches ``L_m = I j_{0,m}^2/4``,
  ``R_m = L_m nu j_{0,m}^2/r^2`` (:func:`column_branches`): the first is kept exactly, the
  others are lumped by octaves of m (2, 3-4, 5-8, 9-16, 17-inf), each lumped branch with
  its members' DC conductance ``sum 1/R_m`` and inverse inertance ``sum 1/L_m``; the
  whole column has the DC conductance ``1/R``, the first moment ``(4/3) I/R^2`` and (to
  0.07 %) the plug-flow inertance ``I`` at high frequency: 6 states, within 0.61 % of
  ``1/(Zc Gamma)`` at every frequency. QQ, ``Zc/Gamma = 1/(s C)`` exactly, one
  integrator (the stored volume).
* **Remainder** ``V + T`` (strictly proper, no feed-through, so no algebraic loops):

  - ``V``, the real-axis poles of the Bessel model: ``Gamma^2`` has poles at the zeros of
    I2 (``s = -nu j_{2,m}^2/r^2``, the first 26.37 nu/r^2) and every mode's characteristic
    equation has one real root beside each of them. They are computed exactly
    (:func:`viscous_poles`), those slower than the first dropped mode are kept, and for every
    entry they are lumped into one real pole whose DC gain and first moment equal theirs
    (one state per entry);
  - ``T``, the dropped modes (and the faster real poles). For the ``tanh`` and ``coth``
    entries T is the inertance of the dropped modes, which decides the top resonance
    peaks; a real-pole block cannot represent it and a feed-through D would make algebraic
    loops in the network. Above the band the exact entries oscillate about the
    reflection-free line (``Zc``, ``1/Zc``; 0 for sech, csch) with the dropped resonances,
    which a modal line cannot resolve; T must not invent one there.

    PQ, QP (:func:`_remainder_blocks`): the dropped modes in ``TAIL_GROUPS`` groups
    (:func:`tail_groups`, modes n+1 .. 1.5(n+1), .. 2.25(n+1), .. 3.4(n+1), rest), one
    damped pair ``(b1 s + b0)/(s^2 + 2 zeta Omega s + Omega^2)`` per group and output, with
    ``Omega`` from the group's lossless first and third moments and ``zeta`` ~ the group's
    relative width (0.16 ... 0.8; every pair decays within L/c). The numerators are a
    least-squares fit of the exact remainder in the band and of the reflection-free mean
    above it, with the DC gain and first moment of every entry exact (equality
    constraints) and ``|H| <= TAIL_BOUND * envelope`` above the band (re-weighting).
    PP, QQ (:func:`_passive_remainder_blocks`): the same groups, one pair per group and
    *port channel* (``H00 + H01`` and ``H00 - H01``, the eigenvalues of the port admittance
    (PP) or impedance (QQ): common and differential mode, :func:`_port_channels`), the
    same objective and equalities, plus passivity: ``Re >= 0`` of both channels of the
    whole model on a frequency grid (in the band ``>= PASSIVE_MARGIN`` times the exact
    line's real part), refined where a dense check finds less, and the common mode's
    second moment at most half the exact one (PP, near DC); the envelope bound as tangent
    half-planes (cutting planes). A quadratic programme in 16 numerators, solved exactly
    (:func:`_inequality_lsq`). Should it ever fail (not seen on ~100 lines, Dn 3e-5 ...
    0.05), the old single light pseudo-mode per output (:func:`_single_tail_blocks`,
    passive, but 2-9 times the envelope above the band) is used instead.

  The DC gain of every entry is therefore exact: PQ/QP the laminar steady state (M12),
  PP ``1/R``, QQ ``1/(s C)`` plus the offsets ``R/3`` (coth) and ``-R/6`` (csch).

States, in order (names as :class:`hydroline.components.HoseSection` expects, the part
after the dot gives the unit):

* QQ only: ``column.volume`` -- net volume stored, [m^3] (both pressures are volume/C);
* PP only: ``column.flow1`` ... ``column.flow6`` -- flows of the column branches, [m^3/s];
* per mode k = 1..n: PQ/QP ``mode{k}.pressure``, ``mode{k}.flow`` -- the mode's
  contributions to the pressure and to the flow output, [Pa], [m^3/s]; PP
  ``mode{k}.volume``, ``mode{k}.flow`` -- the modal volume and flow (contribution to the
  first output; the second gets ``(-1)^k`` times it), [m^3], [m^3/s]; QQ
  ``mode{k}.pressure_integral``, ``mode{k}.pressure``, [Pa s], [Pa];
* ``viscous_{end}{j}.{q}`` -- the lumped real-axis poles' contribution of input j (1, 2)
  to the output at ``end`` ("upstream"/"downstream") of quantity q ("pressure"/"flow"),
  e.g. PQ ``viscous_downstream2.pressure``: part of P_d driven by Q_d;
* PQ/QP: ``tail{g}_{end}.{q}1``, ``tail{g}_{end}.{q}2`` -- group g's contribution to that
  output and its quadrature component (same unit); PP/QQ: ``tail{g}_{mode}.{q}1``,
  ``...2``, mode "common" or "differential" (port channel driven by ``u1 + u2`` or
  ``u1 - u2``; the outputs get half of it, with the channel's signs), q "flow" (PP) or
  "pressure" (QQ); fallback: ``tail_{end}.{q}1``, ``...2``.

Inputs and outputs are in the order of the form's table (:data:`FORM_PORTS`).
"""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from ..cache import source_tag
from .bessel import bessel_j01, bessel_j_zeros, polygamma, scaled_bessel_i012
from .corrections import check_modes, dissipative_root, dissipative_roots, modal_angles
from .memo import LineMemo
from .line import FORM_PORTS, Line, check_form

__all__ = ["residue_realisation", "propagation_derivative", "modal_poles", "modal_residues",
           "viscous_poles", "retardation_poles", "exact_moments", "column_branches", "tail_groups",
           "viscous_clusters", "realisation_with_notes"]

#: PP and QQ forms, fallback only (:func:`_single_tail_blocks`, used if the passive fit
#: fails): damping ratio of the single pseudo-mode per output that stands for the dropped
#: modes, [-]. Light: its in-band part must stay reactive.
TAIL_DAMPING = 0.05

#: PP and QQ: the envelope bound enters the fit as tangent half-planes
#: ``Re(H e^{-j arg H}) <= TAIL_CUT * TAIL_BOUND * envelope`` at the points above the bound
#: (cutting planes, added per round), [-].
TAIL_CUT = 0.99

#: PP and QQ: in the band (from a quarter of a mode spacing), the real part of each port
#: channel of the model must be at least this fraction of the exact line's (a margin
#: that keeps it positive between the grid points, where the exact one is small for
#: low-loss lines), [-].
PASSIVE_MARGIN = 0.5

#: PQ and QP forms: the dropped modes k > n are lumped in groups ``[a_g, a_{g+1})`` with
#: ``a_g = (n + 1) TAIL_GROUP_RATIO^g`` (the last group runs to infinity), one pseudo-mode per
#: group and output, [-]. 4 groups of ratio 1.5: in the band, peaks 1..n-1 within 0.9 %
#: (n = 6, 9 lines, all forms); above it, nothing beyond the exact envelope (the test's
#: definition) on 10 of the 11 lines tried without any bound enforcement, 1.3 times on the
#: lossiest (Dn = 0.033, n = 10).
TAIL_GROUPS = 4
TAIL_GROUP_RATIO = 1.5

#: Damping ratio of a group's pseudo-mode, as a fraction of the group's relative width
#: ``zeta = TAIL_ZETA_SCALE * width/(2 Omega)`` (its half-power band covers about the modes it
#: stands for), at most ``TAIL_ZETA_MAX`` (the infinite group), [-]. The pseudo-modes then
#: have zeta 0.16 ... 0.8 and decay within 0.3 L/c (n = 6), 20 times faster than mode n.
TAIL_ZETA_SCALE = 0.8
TAIL_ZETA_MAX = 0.8

#: Weight, relative to the in-band fit, of the reflection-free mean ``Zc`` (tanh, coth -> 1,
#: sech, csch -> 0) that the model follows above the band up to the last pseudo-mode, [-].
TAIL_MEAN_WEIGHT = 0.1

#: Bound on the model above the band, times the exact response's envelope (running maximum
#: of ``|H_exact|`` over all higher frequencies); enforced by re-weighting on a grid of
#: TAIL_POINTS_PER_SPACING points per mode spacing (1.08: the tests, on a finer grid, see
#: <= 1.075 with their bound 1.1), [-].
TAIL_BOUND = 1.08

#: Frequency points of the in-band fit and of the reflection-free mean above it, [-].
TAIL_FIT_POINTS = 300

#: Points per mode spacing (pi/tau) of the envelope grid above the band, [-].
TAIL_POINTS_PER_SPACING = 16

#: Bound-enforcement rounds (each quadruples the weight of the points still above the bound), [-].
TAIL_ITERATIONS = 20

#: Real roots computed per viscous cluster (one per mode), [-]; their residues fall off as
#: theta^-2 ... theta^-4, so 30 leave < 1e-3 of a cluster's weight out.
VISCOUS_ROOTS_PER_CLUSTER = 30

#: Largest number of viscous clusters (zeros of I2) resolved; faster ones go to the tail, [-].
MAX_VISCOUS_CLUSTERS = 40

#: Branches of the PP fluid column kept with their exact poles; the rest are lumped by
#: octaves of the branch index (:func:`column_branches`), [-].
COLUMN_EXACT_BRANCHES = 1

#: Number of lumped octave groups of column branches (the last one runs to infinity), [-].
#: 5 groups (6 branches): max error of the column admittance against ``1/(Zc Gamma)``
#: 0.61 % at any frequency. One lumped branch with DC and first moment exact (the earlier
#: design) has the high-frequency inertance I/0.88 and is 12 % off there.
COLUMN_OCTAVES = 5


def propagation_derivative(line: Line, s, bessel=None):
    """Gamma(s), Zc(s) of the dissipative model (M6) and the derivative dGamma/ds.

    With ``B = I0(kappa)/I2(kappa)``, ``kappa = r sqrt(s/nu)``, ``Gamma = s tau sqrt(B)``:
    ``dGamma/ds = tau sqrt(B) (1 + kappa B'(kappa)/(4 B))``,
    ``B' = (I1/I2)(1 - B) + 2 B/kappa`` (from I0' = I1, I2' = I1 - 2 I2/kappa).

    Parameters
    ----------
    line : Line
        The line
    s : array_like complex
        Laplace variable off the origin, [1/s]
    bessel : tuple or None
        ``I0, I1, I2`` of ``kappa`` times ``e^{-|Re kappa|}``, each of the shape of ``s``,
        where the caller has them (the viscous roots: from J0, J1 on the real axis);
        computed when None

    Returns
    -------
    Gamma : ndarray
        Propagation operator, complex, [-]
    Zc : ndarray
        Characteristic impedance, complex, [Pa s/m^3]
    dGamma_ds : ndarray
        dGamma/ds, complex, [s]; principal square roots as in :meth:`Line.propagation`

    Notes
    -----
    A viscoelastic wall (M44): ``Gamma sqrt(W)``, ``Zc/sqrt(W)`` and
    ``dGamma/ds sqrt(W) + Gamma W'/(2 sqrt(W))``.
    """
    s = np.asarray(s, dtype=complex)
    nu, r, tau = line.fluid.kinematic_viscosity, line.radius, line.wave_time
    kappa = r * np.sqrt(s / nu)
    i0, i1, i2 = scaled_bessel_i012(kappa) if bessel is None else bessel   # scaling cancels
    B = i0 / i2
    sq = np.sqrt(B)
    dB = (i1 / i2) * (1.0 - B) + 2.0 * B / kappa
    G, Zc, dG = s * tau * sq, line.impedance * sq, tau * sq * (1.0 + kappa * dB / (4.0 * B))
    if line.viscoelastic:        # (M44): Gamma sqrt(W), Zc/sqrt(W), same branch for both
        w = np.sqrt(line.wall_factor(s))
        dG = dG * w + G * line.wall_factor_derivative(s) / (2.0 * w)
        G, Zc = G * w, Zc / w
    return G, Zc, dG


def modal_poles(line: Line, n_modes: int, form: str = "PQ") -> np.ndarray:
    """Poles of modes 1..n in the upper half plane, [1/s].

    Roots of ``Gamma(s) = j theta_k`` (M6), ``theta_k = (k - 1/2) pi`` (PQ, QP: cosh Gamma = 0)
    or ``k pi`` (PP, QQ: sinh Gamma = 0), continued from mode to mode as in (M15).

    Parameters
    ----------
    line : Line
        The line, SI
    n_modes : int
        Modes, [-]
    form : str
        Causal form: "PQ", "QP", "PP" or "QQ"

    Returns
    -------
    ndarray
        Complex poles, one per mode, [1/s].
    """
    thetas = modal_angles(n_modes, form)
    together = dissipative_roots(line, thetas)   # every mode at once: one Bessel call a step
    if together is not None and np.all(np.diff(together.imag) > 0):
        return together
    roots = []
    guess = None
    for k, theta in enumerate(thetas):
        if roots:
            prev, ratio = roots[-1], theta / thetas[k - 1]
            guess = complex(prev.real * np.sqrt(ratio), prev.imag * ratio)
        roots.append(dissipative_root(line, theta, guess))
    return np.array(roots)


def modal_residues(line: Line, poles, form: str = "PQ", bessel=None) -> np.ndarray:
    """Exact residues of every entry of a form's transfer matrix at roots of its denominator.

    PQ/QP entries are ``N(s)/cosh Gamma`` and PP/QQ entries ``N(s)/sinh Gamma``; at a simple
    root the residue is ``N/(sinh Gamma Gamma')`` or ``N/(cosh Gamma Gamma')``. Valid for the
    modal poles and for the real (viscous) roots alike.

    Parameters
    ----------
    line : Line
        The line
    poles : array_like
        Roots of cosh Gamma (PQ/QP) or sinh Gamma (PP/QQ), [1/s]
    form : str
        "PQ", "QP", "PP" or "QQ"
    bessel : tuple or None
        ``I0, I1, I2`` at the poles where known (:func:`propagation_derivative`)

    Returns
    -------
    ndarray
        Complex, shape ``poles.shape + (2, 2)``, [output unit * input unit^-1 / s]
    """
    form = check_form(form)
    p = np.asarray(poles, dtype=complex)
    G, Zc, dG = propagation_derivative(line, p, bessel)
    ch, sh = np.cosh(G), np.sinh(G)
    one = np.ones_like(G)
    if form == "PQ":
        den, num = sh * dG, [[one, -Zc * sh], [sh / Zc, one]]
    elif form == "QP":
        den, num = sh * dG, [[Zc * sh, one], [one, -sh / Zc]]
    elif form == "PP":
        den, num = ch * dG, [[ch / Zc, -one / Zc], [one / Zc, -ch / Zc]]
    else:
        den, num = ch * dG, [[Zc * ch, -Zc], [Zc, -Zc * ch]]
    R = np.empty(p.shape + (2, 2), dtype=complex)
    for i in range(2):
        for j in range(2):
            R[..., i, j] = num[i][j] / den
    return R


def _bessel_zeros(order: int, count: int) -> np.ndarray:
    """The first ``count`` positive zeros of J_order (:func:`bessel_j_zeros`, remembered:
    every residue-line build asks for the same ones), [-]."""
    return bessel_j_zeros(int(order), int(count))


#: Chebyshev points per viscous bracket: J0, J1 on a bracket of width <= 0.39 interpolated to
#: below 1e-20 (the evaluation's rounding, a few 1e-16, is what is left), [-].
BRACKET_NODES = 12


def _bracket_bessel(count: int):
    """The first ``count`` viscous brackets ``[j_{2,m}, next zero of J0]`` (the same for every
    line) and Chebyshev interpolants of J0, J1 on each: ``(lo, hi, mid, half, coef)``, lo, hi
    of shape (count,), mid, half (count, 1), coef (2, count, 1, BRACKET_NODES). A Newton step
    of :func:`viscous_poles` then costs one Clenshaw sum instead of a Bessel evaluation."""
    lo, hi, mid, half, coef = _bracket_interpolants(max(count, MAX_VISCOUS_CLUSTERS))
    return lo[:count], hi[:count], mid[:count], half[:count], coef[:, :count]


@functools.lru_cache(maxsize=4)
def _bracket_interpolants(count: int):
    """:func:`_bracket_bessel` of ``count`` brackets, computed."""
    j2 = _bessel_zeros(2, count)
    j0 = _bessel_zeros(0, count + 2)
    lo, hi = j2, j0[np.searchsorted(j0, j2)]
    mid, half = 0.5 * (hi + lo), 0.5 * (hi - lo)
    k = np.arange(BRACKET_NODES)
    angle = np.pi * (k + 0.5) / BRACKET_NODES
    values = bessel_j01(mid[:, None] + half[:, None] * np.cos(angle)[None, :])  # (2, count, N)
    basis = np.cos(np.outer(k, angle)) * (2.0 / BRACKET_NODES)                 # (j, node)
    coef = np.einsum("vmk,jk->vmj", np.array(values), basis)
    coef[..., 0] *= 0.5
    return lo, hi, mid[:, None], half[:, None], coef[:, :, None, :]


def _chebyshev(coef, t):
    """Clenshaw's sum of Chebyshev series ``coef[..., j]`` at ``t`` in [-1, 1] (broadcast)."""
    b1 = b2 = 0.0
    for j in range(coef.shape[-1] - 1, 0, -1):
        b1, b2 = 2.0 * t * b1 - b2 + coef[..., j], b1
    return t * b1 - b2 + coef[..., 0]


def viscous_poles(line: Line, form: str = "PQ", rate_limit: float | None = None,
                  n_roots: int = VISCOUS_ROOTS_PER_CLUSTER,
                  max_clusters: int = MAX_VISCOUS_CLUSTERS) -> np.ndarray:
    """Real poles of the dissipative model beside the zeros of I2, [1/s].

    On the negative real axis ``kappa = j x``, ``x = r sqrt(-s/nu)``, and
    ``Gamma^2 = -theta^2`` becomes ``x^4 J0(x) Dn^2 = theta^2 J2(x)``: one root in every
    interval from a zero ``j_{2,m}`` of J2 to the next zero of J0, for every mode theta.
    Solved by Newton's method inside the brackets for the modes 1..n_roots of the form and
    the clusters m whose rate ``nu j_{2,m}^2/r^2`` is at most ``rate_limit`` (at least the
    first cluster).

    Parameters
    ----------
    line : Line
        The line, SI
    form : str
        Causal form: "PQ", "QP", "PP" or "QQ"
    rate_limit : float
        Largest cluster rate kept, [1/s] (None: the first cluster only)
    n_roots : int
        Roots per cluster (modes of the form), [-]
    max_clusters : int
        Clusters at most, [-]

    Returns
    -------
    ndarray
        (clusters, n_roots) real poles s < 0, [1/s]
    """
    return _viscous_roots(line, form, rate_limit, n_roots, max_clusters)[0]


def _viscous_roots(line: Line, form: str, rate_limit, n_roots: int, max_clusters: int):
    """:func:`viscous_poles` [1/s] and ``I0, I1, I2`` there (``kappa = j x``: ``J0(x)``,
    ``j J1(x)``, ``-J2(x)``), for :func:`modal_residues`."""
    form = check_form(form)
    Dn = line.dissipation_number
    nu, r = line.fluid.kinematic_viscosity, line.radius
    j2 = _bessel_zeros(2, max_clusters)
    if rate_limit is not None:
        keep = nu * j2**2 / r**2 <= rate_limit
        keep[0] = True
        j2 = j2[keep]
    lo_m, hi_m, mid, half, coef = _bracket_bessel(len(j2))
    lo = np.repeat(lo_m[:, None], n_roots, axis=1)
    hi = np.repeat(hi_m[:, None], n_roots, axis=1)
    q = (modal_angles(n_roots, form)[None, :] / Dn) ** 2

    def g(x, q):                  # and dg/dx; J2 = 2 J1/x - J0, J2' = J1 - 2 J2/x
        J0, J1 = _chebyshev(coef, (x - mid) / half)
        J2 = 2.0 * J1 / x - J0
        x3 = x**3
        return x3 * x * J0 - q * J2, 4.0 * x3 * J0 - x3 * x * J1 - q * (J1 - 2.0 * J2 / x)

    # Newton's method on every bracket at once, kept inside the bracket (a step that leaves
    # it bisects), from the secant of the ends: ~5 evaluations of g to a step below 4e-16
    # relative; the bracket shrinks on the way
    g_ends = g(np.concatenate([lo, hi], axis=1), np.tile(q, 2))[0]
    g_lo, g_hi = g_ends[:, :n_roots], g_ends[:, n_roots:]
    x = lo - g_lo * (hi - lo) / (g_hi - g_lo)
    x = np.where((x > lo) & (x < hi), x, 0.5 * (lo + hi))
    sign_lo = np.sign(g_lo)
    for _ in range(100):
        g_x, slope = g(x, q)
        up = np.sign(g_x) == sign_lo              # the root lies in (x, hi): lo moves
        lo, hi = np.where(up, x, lo), np.where(up, hi, x)
        step = g_x / slope
        done = (np.abs(step) <= 4e-16 * x) | (g_x == 0.0) | (hi - lo <= 4e-16 * hi)
        if np.all(done):
            break
        new = x - step
        new = np.where((new > lo) & (new < hi), new, 0.5 * (lo + hi))
        x = np.where(done, x, new)
    J0, J1 = _chebyshev(coef, (x - mid) / half)
    return -nu * x**2 / r**2, (J0 + 0j, 1j * J1, J0 - 2.0 * J1 / x + 0j)


def exact_moments(line: Line, form: str = "PQ"):
    """DC gain H(0) and first moment H'(0) of the exact dissipative transfer matrix.

    From ``Gamma^2 = g1 s + g2 s^2 + ...`` with ``g1 = 8 Dn tau``, ``g2 = 4 tau^2/3``
    (``I0/I2 = 8/kappa^2 + 4/3 + ...``) and ``Zc = Z0 Gamma/(s tau)``:
    ``sech = 1 - g/2``, ``G tanh G = g - g^2/3``, ``tanh G/G = 1 - g/3``,
    ``G coth G = 1 + g/3 - g^2/45``, ``G csch G = 1 - g/6 + 7 g^2/360``. For QQ the pole
    ``1/(s C)`` of every entry (sign as in the table) is removed first.

    Parameters
    ----------
    line : Line
        The line, SI
    form : str
        Causal form: "PQ", "QP", "PP" or "QQ"

    Returns
    -------
    H0 : ndarray
        Real (2, 2), in form order, [SI of the form]
    H1 : ndarray
        Real (2, 2), in form order, [H0 unit * s]
    """
    form = check_form(form)
    tau, Z0, Dn = line.wave_time, line.impedance, line.dissipation_number
    g1, g2 = 8.0 * Dn * tau, 4.0 / 3.0 * tau**2
    if line.viscoelastic:
        return _viscoelastic_moments(line, form, g1, g2)
    if form in ("PQ", "QP"):
        sech = np.array([1.0, -g1 / 2.0])
        ztanh = np.array([Z0 * g1 / tau, Z0 * (g2 - g1**2 / 3.0) / tau])
        tanhz = np.array([0.0, tau / Z0])
        M = ([[sech, -ztanh], [tanhz, sech]] if form == "PQ" else
             [[ztanh, sech], [sech, -tanhz]])
    elif form == "PP":
        base = np.array([tau / (Z0 * g1), -tau * g2 / (Z0 * g1**2)])
        coth = base + np.array([0.0, tau / (3.0 * Z0)])
        csch = base - np.array([0.0, tau / (6.0 * Z0)])
        M = [[coth, -csch], [csch, -coth]]
    else:
        coth = Z0 / tau * np.array([g1 / 3.0, g2 / 3.0 - g1**2 / 45.0])
        csch = Z0 / tau * np.array([-g1 / 6.0, -g2 / 6.0 + 7.0 * g1**2 / 360.0])
        M = [[coth, -csch], [csch, -coth]]
    M = np.array(M)
    return M[..., 0], M[..., 1]


def _viscoelastic_moments(line: Line, form: str, g1: float, g2: float):
    """:func:`exact_moments` of a line with a viscoelastic wall (M44): ``Gamma^2`` times
    ``W = W0 + W1 s + ...`` (``g1 W0``, ``g2 W0 + g1 W1``) and ``Zc = Z0 Gamma/(s tau W)``."""
    tau, Z0 = line.wave_time, line.impedance
    W0 = float(line.wall_factor(0.0).real)
    W1 = float(line.wall_factor_derivative(0.0).real)
    g1, g2 = g1 * W0, g2 * W0 + g1 * W1
    if form in ("PQ", "QP"):
        sech = np.array([1.0, -g1 / 2.0])
        ztanh = Z0 / (tau * W0) * np.array([g1, g2 - g1**2 / 3.0 - g1 * W1 / W0])
        tanhz = np.array([0.0, tau * W0 / Z0])
        M = ([[sech, -ztanh], [tanhz, sech]] if form == "PQ" else
             [[ztanh, sech], [sech, -tanhz]])
    elif form == "PP":
        base = tau / Z0 * np.array([W0 / g1, W1 / g1 - W0 * g2 / g1**2])
        coth = base + np.array([0.0, tau * W0 / (3.0 * Z0)])
        csch = base - np.array([0.0, tau * W0 / (6.0 * Z0)])
        M = [[coth, -csch], [csch, -coth]]
    else:
        raise ValueError("a viscoelastic wall (M44) is modelled in the PQ, QP and PP forms, "
                         "not QQ")
    M = np.array(M)
    return M[..., 0], M[..., 1]


def retardation_poles(line: Line, form: str = "PQ", rate_limit: float | None = None,
                      n_roots: int = VISCOUS_ROOTS_PER_CLUSTER):
    """Poles near the negative real axis of a line with a viscoelastic wall (M44), beside the
    zeros of I2 and beside the retardation rates ``1/tau_k``, [1/s].

    ``Gamma^2 = (s tau)^2 B(s) W(s)`` is real on the negative real axis with poles at the
    viscous rates ``nu j_{2,m}^2/r^2`` and at ``1/tau_k``; beside each, on the side where it
    tends to ``-infinity``, every mode's ``F = Gamma^2 + theta^2`` has a root. Past a
    retardation rate W < 0 up to its zero ``(1 + beta_e J_k)/tau_k``, so a viscous rate in
    that window turns its roots toward the wall's: the interval between them has two roots
    per mode, real if ``max F > 0`` there, else a complex pair near the axis (the low modes
    when the two rates are close, e.g. 20 ms beside the viscous rate 50.3 1/s of a 13 mm
    hose; found by Newton from the maximum of F, ``s = -x_m +- j sqrt(2 F_max/F'')``).
    Between two consecutive singular rates F is sampled on a grid geometric toward both ends
    (offsets 1e-15 ... 1/2 of the gap) and every sign change is bisected, for the modes
    1..n_roots of the form. A real root goes with its nearest singular rate (in log); the
    roots of an interval that both its ends claim go, real or complex, with its wall rate,
    so that the large residues of opposite sign of such a pair are lumped together.

    Parameters
    ----------
    line : Line
        The line, with its wall elements
    form : str
        Causal form: "PQ", "QP" or "PP"
    rate_limit : float
        Largest viscous cluster rate kept, [1/s] (None: the first only)
    n_roots : int
        Modes of the form, [-]

    Returns
    -------
    viscous : ndarray
        Poles beside the viscous rates, complex, [1/s] (both members of every
        complex pair)
    wall : list of ndarray
        Poles beside each wall element's retardation rate, one complex array per
        element, [1/s]
    """
    form = check_form(form)
    nu, r = line.fluid.kinematic_viscosity, line.radius
    vis = nu * _bessel_zeros(2, MAX_VISCOUS_CLUSTERS) ** 2 / r**2
    if rate_limit is not None:
        vis = vis[: max(1, int(np.sum(vis <= rate_limit)))]
    else:
        vis = vis[:1]
    wall = np.array([1.0 / t for t in line.retardation_times])
    sing = np.sort(np.concatenate((vis, wall)))
    edges = np.concatenate(([0.0], sing, [sing[-1] * 1.5]))
    q = modal_angles(n_roots, form) ** 2
    u = 10.0 ** -np.arange(15.0, 0.0, -0.5)
    u = np.unique(np.concatenate((u, [0.5], 1.0 - u)))

    def F(rate):                  # Gamma^2 + theta^2 for rates (..., 1) and all theta
        with np.errstate(invalid="ignore", divide="ignore"):
            g = propagation_derivative(line, -rate + 0j)[0] ** 2
        return g.real + q

    found, facing, owner = [], [], {float(w): e for e, w in enumerate(wall)}
    with np.errstate(invalid="ignore", divide="ignore"):
        for lo_edge, hi_edge in zip(edges[:-1], edges[1:]):
            grid = lo_edge + (hi_edge - lo_edge) * u
            x, k = _real_roots_between(line, grid, F(grid[:, None]), q)
            found.append((x, k))
            # ends that claim a root of every mode: a singular rate where Gamma^2 -> -inf
            # (probed 1e-9 of the gap inside: closer, round-off may cross the singularity)
            probe = F(lo_edge + (hi_edge - lo_edge) * np.array([[1e-9], [1.0 - 1e-9]]))[:, 0]
            if edges[-1] > hi_edge and lo_edge > 0 and np.all(probe < 0.0):
                facing.append((lo_edge, hi_edge, np.bincount(k, minlength=len(q))))
                walls = [e for e in (lo_edge, hi_edge) if float(e) in owner]
                if walls:        # a viscous rate in a wall's window: its roots are the wall's
                    for e in (lo_edge, hi_edge):
                        owner.setdefault(float(e), owner[float(walls[0])])
        x = np.concatenate([f[0] for f in found])
        k = np.concatenate([f[1] for f in found])
        roots = list(-x)
        # every singular rate claims one root per mode: a deficit is a complex pair, in a
        # facing interval where this mode lacks its two real roots
        deficit = len(sing) - np.bincount(k, minlength=len(q))
        for lo_edge, hi_edge, count in facing:
            lack = [m for m in range(len(q)) if count[m] < 2 and deficit[m] >= 2]
            for m, p in zip(lack, _complex_pairs_between(line, lo_edge, hi_edge, q[lack])):
                if p is not None:
                    roots += [p, np.conj(p)]
                    deficit[m] -= 2
    if np.any(deficit >= 2):
        import warnings
        warnings.warn(f"viscoelastic wall (M44) of a {line.length:.4g} m line: complex wall "
                      f"poles of {int(np.sum(deficit >= 2))} modes not found (a retardation rate "
                      "inside the modal band or beta_e J > ~0.3); its residue line is less "
                      "accurate (see docs/model.md, M44)", RuntimeWarning, stacklevel=4)
    roots = np.array(roots, dtype=complex)
    near = sing[np.argmin(np.abs(np.log(-roots.real[:, None]) - np.log(sing[None, :])), axis=1)]
    group = np.array([owner.get(float(r), -1) for r in near])
    return roots[group < 0], [roots[group == e] for e in range(len(wall))]


def _real_roots_between(line, grid, Fg, q):
    """Real roots of Gamma^2 + theta^2 (every theta of ``q``) on a grid of rates between two
    singular rates, where it takes the values ``Fg`` (points, modes): rates [1/s] and their
    mode indices."""
    change = np.nonzero(np.sign(Fg[:-1]) != np.sign(Fg[1:]))
    if not change[0].size:
        return np.zeros(0), np.zeros(0, dtype=int)
    i, k = change
    lo, hi = grid[i], grid[i + 1]
    f_lo = Fg[i, k]
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        f_mid = propagation_derivative(line, -mid + 0j)[0] ** 2
        f_mid = f_mid.real + q[k]
        left = np.sign(f_mid) == np.sign(f_lo)
        lo, f_lo = np.where(left, mid, lo), np.where(left, f_mid, f_lo)
        hi = np.where(left, hi, mid)
        if np.all(hi - lo <= 1e-15 * hi):
            break
    x = 0.5 * (lo + hi)
    # a pole of F (sign change across infinity) is no root: |F| must be small there
    scale = np.abs(Fg[i, k]) + np.abs(Fg[i + 1, k])
    ok = np.abs(propagation_derivative(line, -x + 0j)[0] ** 2 + q[k]) < 1e-6 * scale
    return x[ok], k[ok]


def _complex_pairs_between(line, lo_edge, hi_edge, q, iterations=60):
    """Complex roots (upper member) of ``F = Gamma^2 + theta^2`` for the modes ``q = theta^2``
    whose real roots are missing between two singular rates a < b that both claim one, [1/s].

    F has simple poles at ``-a`` and ``-b``; ``G = (s + a)(s + b) F`` has none there, so its
    quadratic through ``s = -m``, ``-m +- j h`` (m the middle, h the half width) gives the
    start, and Newton on G (``G' = (2 s + a + b) F + (s + a)(s + b) 2 Gamma Gamma'``)
    polishes it. The root's real part may lie outside the interval (within one width).
    """
    a, b = lo_edge, hi_edge
    mid, h = 0.5 * (a + b), 0.5 * (b - a)

    def G_and_slope(s, qk):
        Ga, _, dGa = propagation_derivative(line, np.atleast_1d(np.asarray(s, dtype=complex)))
        F = Ga**2 + qk
        P = (s + a) * (s + b)
        return P * F, (2.0 * s + a + b) * F + P * 2.0 * Ga * dGa

    nodes = np.array([-mid, -mid + 1j * h, -mid - 1j * h])
    out = []
    for qk in q:
        g = G_and_slope(nodes, qk)[0]
        # quadratic through the nodes in z = (s + mid)/h: g = c0 + c1 z + c2 z^2, z = 0, j, -j
        c0 = g[0]
        c2 = -(g[1] + g[2] - 2.0 * c0) / 2.0
        c1 = (g[1] - g[2]) / 2j
        z = np.roots([c2, c1, c0]) if abs(c2) > 0 else np.array([-c0 / c1])
        z = z[np.argmax(z.imag)]
        s = complex(-mid + h * z)
        if s.imag <= 0:
            s = complex(s.real, h)
        for _ in range(iterations):
            g, dg = G_and_slope(s, qk)
            step = complex(g[0] / dg[0])
            s = s - step
            if abs(step) <= 1e-13 * abs(s):
                break
        Gs = propagation_derivative(line, np.array([s]))[0][0]
        ok = (abs(Gs**2 + qk) <= 1e-8 * qk and s.imag > 1e-12 * abs(s)
              and 2.0 * a - b < -s.real < 2.0 * b - a)
        out.append(complex(s) if ok else None)
    return out


def column_branches(line: Line, n_exact: int = COLUMN_EXACT_BRANCHES,
                    n_octaves: int = COLUMN_OCTAVES):
    """Parallel R-L branches of the PP fluid column ``1/(Zc Gamma) = I2/(s I I0)`` (M6).

    Mittag-Leffler: ``2 I1(kappa)/(kappa I0(kappa)) = sum_m 4/(z + j_m^2)``, ``z = kappa^2``,
    ``j_m`` the zeros of J0, and ``I2/I0 = 1 - 2 I1/(kappa I0)`` give
    ``1/(Zc Gamma) = sum_m 1/(L_m s + R_m)``, ``L_m = I j_m^2/4``, ``R_m = L_m nu j_m^2/r^2``,
    with ``sum 1/R_m = 1/R`` (laminar DC, M12), ``sum 1/L_m = 1/I`` (plug flow at high
    frequency) and ``sum L_m/R_m^2 = (4/3) I/R^2`` (first moment), from the Rayleigh sums
    ``sum_m j_m^-2 = 1/4``, ``j_m^-4 = 1/32``, ``j_m^-6 = 1/192``.

    Branches ``m <= n_exact`` are returned as they are; then the octaves
    ``m in (n_exact 2^(g-1), n_exact 2^g]``, g = 1 .. n_octaves - 1, and all further m are
    lumped into one branch each with ``1/R = sum 1/R_m`` and ``1/L = sum 1/L_m`` (passive,
    its pole inside its members' range; the infinite group is what the others leave of
    ``1/R`` and ``1/I``). Lumping lowers the first moment (Cauchy-Schwarz), by ~4e-5 of
    it; the first lumped group's inertance is raised to restore it exactly, which moves the
    high-frequency ``1/I`` by 0.07 %. The first moment must be exact: the PP entries'
    ``H'(0) ~ I/R^2`` is ``(I omega/R)^2`` (up to 1e5 for wide short lines) times the
    admittance at the frequencies that matter, so any deficit left to the tail pseudo-mode
    would appear there multiplied by that factor. Max error against ``1/(Zc Gamma)``,
    defaults: 0.61 % at any frequency.

    Parameters
    ----------
    line : Line
        The line (bore, fluid), SI
    n_exact : int
        Branches kept one by one, [-]
    n_octaves : int
        Octave groups after them (the last takes every further branch), [-]

    Returns
    -------
    list of tuple
        ``(inertance [kg/m^4], resistance [Pa s/m^3])`` pairs, the exact branches first
    """
    I, R = line.inertance, line.resistance
    nu, r = line.fluid.kinematic_viscosity, line.radius
    edges = [n_exact * 2**g for g in range(n_octaves)]
    j = _bessel_zeros(0, edges[-1])
    groups = [j[m:m + 1] for m in range(n_exact)]
    groups += [j[a:b] for a, b in zip(edges[:-1], edges[1:])]
    out = [[I / (4.0 * np.sum(g**-2.0)), I * nu / (4.0 * r**2 * np.sum(g**-4.0))]
           for g in groups]
    # m > edges[-1]: what the others leave of 1/I and 1/R
    out.append([1.0 / (1.0 / I - sum(1.0 / Lb for Lb, _ in out)),
                1.0 / (1.0 / R - sum(1.0 / Rb for _, Rb in out))])
    deficit = 4.0 / 3.0 * I / R**2 - sum(Lb / Rb**2 for Lb, Rb in out)
    out[n_exact][0] += deficit * out[n_exact][1] ** 2
    return [tuple(b) for b in out]


# ---- realisation --------------------------------------------------------------------------
def _mode_pq(p, R):
    """Two real states whose values are the mode's contributions to both outputs (C = I).

    ``R = u v^T``; ``z' = p z + v^T u_in``, contribution ``2 Re(u z) = T [Re z, Im z]`` with
    ``T = 2 [Re u, -Im u]`` (invertible since Re Zc != 0); in ``x = T [Re z, Im z]``:
    ``A = T [[a, -b], [b, a]] T^-1``, ``B = T [Re v; Im v]``, ``C = I``.
    """
    j = int(np.argmax(np.abs(R).sum(axis=0)))
    i = int(np.argmax(np.abs(R[:, j])))
    u, v = R[:, j], R[i, :] / R[i, j]
    T = 2.0 * np.column_stack([u.real, -u.imag])
    Lam = np.array([[p.real, -p.imag], [p.imag, p.real]])
    return T @ Lam @ np.linalg.inv(T), T @ np.vstack([v.real, v.imag]), np.eye(2)


def _mode_pp(p, R):
    """Two real states [xi, y] for ``R = c [1, sg]^T [1, -sg]`` (PP and QQ).

    ``y = g(s) (u1 - sg u2)`` with ``g = c/(s - p) + conj = (b1 s + b0)/(s^2 + a1 s + a0)``,
    realised as ``xi' = y - mu xi``, ``y' = -k xi - a y + b1 w`` with ``mu = b0/b1``,
    ``a = a1 - mu``, ``k = a0 - a mu``; the outputs are ``y`` and ``sg y``.
    """
    c = R[0, 0]
    sg = 1.0 if (R[1, 0] * np.conj(c)).real >= 0 else -1.0
    b1, b0 = 2.0 * c.real, -2.0 * (c * np.conj(p)).real
    a1, a0 = -2.0 * p.real, abs(p) ** 2
    if not b1 > 1e-9 * abs(c):   # Re(c) > 0 for every line with Dn well below 1
        raise ValueError(f"mode at s = {p:.4g} 1/s has a residue with Re <= 0; the line is too "
                         "dissipative for the residue modal line")
    mu = b0 / b1
    a = a1 - mu
    A = np.array([[-mu, 1.0], [-(a0 - a * mu), -a]])
    B = np.array([[0.0, 0.0], [b1, -sg * b1]])
    return A, B, np.array([[0.0, 1.0], [0.0, sg]])


def _tail_omega(n_modes: int, form: str) -> float:
    """Omega tau of one mode with the first and third moments of the lossless tail.

    ``sum_{i>n} 2 s tau/((s tau)^2 + theta_i^2) = 2 S2 s tau - 2 S4 (s tau)^3 + ...`` with
    ``S_k = sum_{i>n} theta_i^-k`` (polygamma sums); ``K s/(s^2 + Omega^2)`` matches both
    for ``(Omega tau)^2 = S2/S4``.
    """
    a = n_modes + (0.5 if form in ("PQ", "QP") else 1.0)
    S2 = polygamma(1, a) / np.pi**2
    S4 = polygamma(3, a) / (6.0 * np.pi**4)
    return float(np.sqrt(S2 / S4))


def _lumped_rate(V0, V1, rates, weights):
    """Rate of one real pole with DC gain V0 and first moment V1, inside the cluster range."""
    lo, hi = rates.min(), rates.max()
    lam = -V0 / V1 if V1 != 0 else np.nan
    if np.isfinite(lam) and lo * (1 - 1e-9) <= lam <= hi * (1 + 1e-9):
        return lam
    w = np.abs(weights)                       # mixed signs: |weight|-averaged rate
    return float(np.sum(w / rates) / np.sum(w / rates**2)) if w.sum() > 0 else lo


def _blocks_transfer(blocks, s):
    """Transfer matrix of block-diagonal (A, B, C) blocks of size 1 or 2 at the points s.

    ``sum_blocks C (sI - A)^-1 B`` with ``(sI - A)^-1 = [[s - d, b], [c, s - a]] / det`` for
    ``A = [[a, b], [c, d]]``: every block at once, each term of the inverse weighting the
    outer product of a column of C with a row of B.
    """
    s = np.asarray(s, dtype=complex)
    sm = s[..., None]
    H = np.zeros(s.shape + (4,), dtype=complex)
    one = [(A, B, C) for A, B, C, _ in blocks if A.shape[0] == 1]
    two = [(A, B, C) for A, B, C, _ in blocks if A.shape[0] != 1]
    if one:
        a = np.array([A[0, 0] for A, _, _ in one])
        CB = np.array([np.outer(C[:, 0], B[0]) for _, B, C in one]).reshape(len(one), 4)
        H += (1.0 / (sm - a)) @ CB
    if two:
        A = np.array([blk[0] for blk in two])
        B = np.array([blk[1] for blk in two])
        C = np.array([blk[2] for blk in two])
        a, b, c, d = A[:, 0, 0], A[:, 0, 1], A[:, 1, 0], A[:, 1, 1]
        det = (sm - a) * (sm - d) - b * c

        def outer(k, l):                                 # column k of C times row l of B
            return np.einsum("mi,mj->mij", C[:, :, k], B[:, l, :]).reshape(len(two), 4)

        H += ((sm - d) / det) @ outer(0, 0) + (b / det) @ outer(0, 1)
        H += (c / det) @ outer(1, 0) + ((sm - a) / det) @ outer(1, 1)
    return H.reshape(s.shape + (2, 2))


def _reflection_free(line: Line, s, form: str):
    """Mean of the exact response above the modal band: the line without reflections, (M6).

    ``tanh, coth -> 1``, ``sech, csch -> 0``: PQ ``[[0, -Zc], [1/Zc, 0]]`` etc.
    """
    _, Zc = line.propagation(s)
    z = np.zeros_like(Zc)
    m = {"PQ": [[z, -Zc], [1 / Zc, z]], "QP": [[Zc, z], [z, -1 / Zc]],
         "PP": [[1 / Zc, z], [z, -1 / Zc]], "QQ": [[Zc, z], [z, -Zc]]}[form]
    return np.moveaxis(np.array(m), (0, 1), (-2, -1))


def _angle_sums(a, b, form: str):
    """``S2 = sum theta_k^-2`` and ``S4 = sum theta_k^-4`` over modes ``a <= k < b`` (b may be
    inf), ``theta_k`` as in :func:`modal_angles` (polygamma sums), [-]."""
    off = 0.5 if form in ("PQ", "QP") else 1.0

    def from_k(k):
        if not np.isfinite(k):
            return np.zeros(2)
        x = k - 1.0 + off
        return np.array([polygamma(1, x) / np.pi**2,
                         polygamma(3, x) / (6.0 * np.pi**4)])

    return from_k(a) - from_k(b)


def tail_groups(n_modes: int, form: str = "PQ"):
    """Pseudo-modes of the dropped modes k > n: ``(Omega tau, zeta)`` per group, [-].

    Group g lumps the modes ``a_g <= k < a_{g+1}``, ``a_g ~ (n + 1) TAIL_GROUP_RATIO^g``, the
    last one all the rest. ``(Omega tau)^2 = S2/S4`` over the group matches its lossless first
    and third moments (``sum 2 x/(x^2 + theta_k^2) = 2 S2 x - 2 S4 x^3 + ...``);
    ``zeta = TAIL_ZETA_SCALE * width/(2 Omega)`` with the group's width ``(a_{g+1} - a_g) pi``
    (``2 Omega`` for the last), at most ``TAIL_ZETA_MAX``. Used by the PQ and QP forms.

    Parameters
    ----------
    n_modes : int
        Number of retained modes n >= 1, [-]
    form : str
        Causal form "PQ", "QP", "PP" or "QQ" (sets theta_k), [-]

    Returns
    -------
    list of tuple
        ``(Omega tau [-], zeta [-])``, one per group, in rising frequency
    """
    return list(_tail_groups(check_modes(n_modes), check_form(form)))


@functools.lru_cache(maxsize=64)
def _tail_groups(n: int, form: str) -> tuple:
    """:func:`tail_groups`, remembered: a function of (n, form) alone, asked for by every
    line realised (~0.6 ms each, the polygamma sums)."""
    edges = [n + 1]
    for g in range(1, TAIL_GROUPS):
        edges.append(max(edges[-1] + 1, int(round((n + 1) * TAIL_GROUP_RATIO**g))))
    edges.append(np.inf)
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        S2, S4 = _angle_sums(a, b, form)
        Om = float(np.sqrt(S2 / S4))
        width = (b - a) * np.pi if np.isfinite(b) else 2.0 * Om
        out.append((Om, min(TAIL_ZETA_SCALE * width / (2.0 * Om), TAIL_ZETA_MAX)))
    return tuple(out)


def _equality_lsq(Q, q, G, h):
    """min ``z'Q z - 2 q'z`` subject to ``G z = h`` exactly (KKT system)."""
    K = np.block([[Q, G.T], [G, np.zeros((len(h), len(h)))]])
    return np.linalg.solve(K, np.concatenate([q, h]))[:len(q)]


def _inequality_lsq(Q, q, G, h, A, b):
    """min ``z'Q z - 2 q'z`` subject to ``G z = h`` and ``A z >= b`` (Q positive definite).

    Lawson and Hanson's route (Solving Least Squares Problems, ch. 23): the equalities are
    eliminated on the null space of G, the quadratic is whitened by its Cholesky factor,
    and the remaining least-distance problem ``min |u|, A' u >= b'`` is solved as the
    non-negative least-squares problem ``min |[A'^T; b'^T] x - e|, x >= 0``
    (:func:`scipy.optimize.nnls`), ``u = -r[:-1]/r[-1]`` from its residual r. Exact up to
    round-off; returns None when the constraints are infeasible.
    """
    from scipy.linalg import null_space, solve_triangular
    from scipy.optimize import nnls

    zp = np.linalg.lstsq(G, h, rcond=None)[0]
    N = null_space(G)
    M = N.T @ Q @ N
    Rc = np.linalg.cholesky(M).T                              # M = Rc' Rc
    c = solve_triangular(Rc, N.T @ (q - Q @ zp), trans="T")  # v = Rc^-1 (u + c)
    Gm = solve_triangular(Rc, (A @ N).T, trans="T").T         # A N Rc^-1
    hm = b - A @ zp - Gm @ c
    norm = np.linalg.norm(Gm, axis=1)
    norm[norm == 0] = 1.0
    Gm, hm = Gm / norm[:, None], hm / norm
    E = np.vstack([Gm.T, hm])
    f = np.zeros(E.shape[0])
    f[-1] = 1.0
    x, _ = nnls(E, f, maxiter=50 * E.shape[1])
    r = E @ x - f
    if abs(r[-1]) < 1e-12:
        return None
    u = -r[:-1] / r[-1]
    return zp + N @ solve_triangular(Rc, u + c)


def _remainder_blocks(line: Line, n: int, form: str, blocks, rem0, rem1, ends, notes=None,
                      shared=None):
    """Pseudo-modes that stand for the dropped modes k > n (module docstring, "Remainder").

    Per output, one damped pair ``(b1 s + b0)/(s^2 + 2 zeta Omega s + Omega^2)`` per group of
    :func:`tail_groups`, shared by both inputs. The numerators of every entry minimise
    ``|H_model - H_exact|^2`` over the retained band (0 to half a spacing above mode n) plus
    ``TAIL_MEAN_WEIGHT^2 |H_model - H_mean|^2`` above it (``H_mean`` the reflection-free line,
    :func:`_reflection_free`, up to the last pseudo-mode), subject to the exact DC gain
    ``rem0`` and first moment ``rem1`` of the entry (equality constraints). Where the result
    exceeds ``TAIL_BOUND`` times the exact envelope above the band, those frequencies are
    pulled onto 0.97 of the bound with growing weight (``TAIL_ITERATIONS`` rounds).
    ``notes`` (a dict, where given) gets ``"tail_peak"``: the first fit's largest
    ``|H|/bound`` above the band (above 1: the bound was enforced), [-]; the exact responses
    on the fit's grids are kept in (and taken from) the dict ``shared`` where given.

    Returns
    -------
    list of (A, B, C, names) blocks, [1/s] and the output's unit per input unit
    """
    tau = line.wave_time
    peak = 0.0
    groups = tail_groups(n, form)
    m = len(groups)
    Om = np.array([g[0] for g in groups])                 # in units of 1/tau
    ze = np.array([g[1] for g in groups])
    theta_band = modal_angles(n + 1, form)[-1] - 0.5 * np.pi

    def basis(x):                 # columns [sigma/D_i, 1/D_i] at sigma = j x = s tau
        sig = 1j * x[:, None]
        D = sig**2 + 2.0 * ze * Om * sig + Om**2
        return np.hstack([sig / D, 1.0 / D])

    def blocks_at(s, key):        # the blocks so far (the modes' part kept in shared)
        if shared is None:
            return _blocks_transfer(blocks, s)
        k = len(shared["modes"][0])
        return _kept(shared, key, lambda: _blocks_transfer(blocks[:k], s)) + \
            _blocks_transfer(blocks[k:], s)

    def remaining(x, target, key):     # target minus the blocks so far
        s = 1j * x / tau
        return target(s) - blocks_at(s, key)

    x_in = np.linspace(theta_band / TAIL_FIT_POINTS, theta_band, TAIL_FIT_POINTS)
    x_up = theta_band * np.geomspace(1.0, Om[-1] / theta_band, TAIL_FIT_POINTS)[1:]
    E_in = remaining(x_in, lambda s: _kept(shared, "tail_in", lambda: line.transfer(s, form)),
                     "modes_in")
    E_up = remaining(x_up, lambda s: _kept(shared, "tail_up",
                                           lambda: _reflection_free(line, s, form)), "modes_up")
    F_in, F_up = basis(x_in), TAIL_MEAN_WEIGHT * basis(x_up)
    # envelope grid: running maximum of |H_exact| from above, to twice the last pseudo-mode
    top = 2.0 * Om[-1]
    x_c = np.arange(theta_band, top + 2.0 * np.pi, np.pi / TAIL_POINTS_PER_SPACING)
    env = _kept(shared, "tail_envelope", lambda: np.maximum.accumulate(
        np.abs(line.transfer(1j * x_c[::-1] / tau, form)), axis=0)[::-1])
    keep = x_c <= top
    x_c, bound = x_c[keep], TAIL_BOUND * env[keep]
    base_c = blocks_at(1j * x_c / tau, "modes_envelope")
    F_c = basis(x_c)
    # DC: sum b0_i/Om_i^2 = rem0; first moment in sigma: sum b1_i/Om_i^2 - 2 zeta_i b0_i/Om_i^3
    G = np.vstack([np.concatenate([np.zeros(m), Om**-2.0]),
                   np.concatenate([Om**-2.0, -2.0 * ze * Om**-3.0])])

    def normal(M, y):
        return (M.real.T @ M.real + M.imag.T @ M.imag,
                M.real.T @ y.real + M.imag.T @ y.imag)

    # numerators of output o: beta_j = L[j] @ z, z = [beta_0, beta_1] (j = input)
    k2 = 2 * m
    L = [np.hstack([np.eye(k2), np.zeros((k2, k2))]), np.hstack([np.zeros((k2, k2)), np.eye(k2)])]
    L = [L, L]

    beta = np.zeros((2, 2, k2))
    for o in range(2):
        Qz, qz, Gz, hz, rows = 0.0, 0.0, [], [], []
        for j in range(2):
            Lj = L[o][j]
            scale = max(np.abs(E_in[:, o, j]).max(), 1e-300)
            Q1, q1 = normal(F_in, E_in[:, o, j])
            Q2, q2 = normal(F_up, TAIL_MEAN_WEIGHT * E_up[:, o, j])
            Qz = Qz + Lj.T @ (Q1 + Q2) @ Lj / scale**2
            qz = qz + Lj.T @ (q1 + q2) / scale**2
            Gz.append(G @ Lj)
            hz += [rem0[o, j], rem1[o, j] / tau]
            rows.append(scale)
        Gz, hz = np.vstack(Gz), np.array(hz)
        z = _equality_lsq(Qz, qz, Gz, hz)
        weight = 0.03 / TAIL_FIT_POINTS      # per point, against the in-band fit
        for it in range(TAIL_ITERATIONS):
            added = False
            for j in range(2):
                Lj = L[o][j]
                H = base_c[:, o, j] + F_c @ (Lj @ z)
                if it == 0:
                    peak = max(peak, float(np.max(np.abs(H) / bound[:, o, j])))
                over = np.flatnonzero(np.abs(H) > bound[:, o, j])
                if over.size:
                    added = True
                    target = (H[over] * (0.97 * bound[over, o, j] / np.abs(H[over]))
                              - base_c[over, o, j])
                    Qk, qk = normal(F_c[over], target)
                    Qz = Qz + weight * Lj.T @ Qk @ Lj / rows[j]**2
                    qz = qz + weight * Lj.T @ qk / rows[j]**2
            if not added:
                break
            z = _equality_lsq(Qz, qz, Gz, hz)
            weight *= 4.0
        for j in range(2):
            beta[o, j] = L[o][j] @ z
    if notes is not None:
        notes["tail_peak"] = peak

    out = []
    for o in range(2):
        end, kind = ends[o]
        Ct = np.zeros((2, 2))
        Ct[o, 0] = 1.0
        for i in range(m):
            W, a1 = Om[i] / tau, 2.0 * ze[i] * Om[i] / tau
            b1, b0 = beta[o, :, i] / tau, beta[o, :, m + i] / tau**2
            # y' = -a1 y + W q + b1 u,  q' = -W y + (b0/W) u:  y = (b1 s + b0)/(s^2 + a1 s + W^2) u
            out.append((np.array([[-a1, W], [-W, 0.0]]), np.vstack([b1, b0 / W]), Ct.copy(),
                        [f"tail{i + 1}_{end}.{kind}1", f"tail{i + 1}_{end}.{kind}2"]))
    return out


def _second_moment(blocks, skip=()):
    """``H2`` of the blocks, ``H(s) = H0 + H1 s + H2 s^2 + ...``: ``-C A^-3 B``, [unit s^2]."""
    H2 = np.zeros((2, 2))
    for A, B, C, names in blocks:
        if names not in skip:
            X = np.linalg.solve(A, np.linalg.solve(A, np.linalg.solve(A, B)))
            H2 -= C @ X
    return H2


def _port_channels(H):
    """PP/QQ entries -> the two port channels ``H00 + H01`` ("plus") and ``H00 - H01``.

    By the symmetry of (M6) (``H11 = -H00``, ``H10 = -H01``) the port admittance (PP,
    ``diag(1, -1) H``) and impedance (QQ, ``H diag(1, -1)``) have the constant eigenvectors
    [1, 1] and [1, -1]; their eigenvalues are these two channels (PP: plus = common mode
    ``tanh(G/2)/Zc``, minus = differential ``coth(G/2)/Zc``; QQ: plus = differential
    ``Zc tanh(G/2)``, minus = common ``Zc coth(G/2)``). The port is passive iff both have a
    real part >= 0 on the imaginary axis.
    """
    return np.stack([H[..., 0, 0] + H[..., 0, 1], H[..., 0, 0] - H[..., 0, 1]], axis=-1)


def _passive_remainder_blocks(line: Line, n: int, form: str, blocks, rem0, rem1, moment2=None):
    """PP/QQ: grouped pseudo-modes per port channel, fitted under a passivity constraint.

    The dropped modes are grouped as for PQ/QP (:func:`tail_groups`); every group gets one
    damped pair ``(b1 s + b0)/(s^2 + 2 zeta Omega s + Omega^2)`` per port channel (plus,
    minus: :func:`_port_channels`), driven by ``u1 + u2`` or ``u1 - u2``. The numerators
    (4 per group) solve a quadratic programme (:func:`_inequality_lsq`):

    * minimise the same least-squares objective as :func:`_remainder_blocks` (exact
      remainder in the band, reflection-free mean above it), per channel;
    * equality: DC gain ``rem0`` and first moment ``rem1`` of every entry exact;
    * passivity: ``Re(channel) >= 0`` of the whole model (modes, column, V and these pairs)
      on a frequency grid (linear in the numerators; in the band ``>= PASSIVE_MARGIN``
      times the exact real part), refined where a check on a 64-per-spacing grid finds
      less than half of that; near DC, where the common-mode admittance (PP) is
      ``-H2 omega^2``, its second moment at most half the exact one (``moment2`` [Pa^-1
      m^3 s], negative);
    * envelope: ``|H| <= TAIL_BOUND * envelope`` above the band for entries 00 and 01 (10,
      11 are their negatives), as tangent half-planes at the points that exceed it
      (``TAIL_CUT``), added in rounds (at most ``TAIL_ITERATIONS``).

    Parameters
    ----------
    line : Line
        The line
    n : int
        Retained modes, [-]
    form : str
        "PP" or "QQ"
    blocks : list
        (A, B, C, names) blocks realised so far (column, modes, V)
    rem0, rem1 : ndarray (2, 2) DC gain and first moment the remainder must supply, [output
                         unit per input unit], [same * s]
    moment2 : float, optional
        Exact second moment of the common-mode admittance (PP)

    Returns
    -------
    list of (A, B, C, names) blocks, or None if no passive fit was found (the caller then
    uses :func:`_single_tail_blocks`)
    """
    tau = line.wave_time
    groups = tail_groups(n, form)
    m = len(groups)
    Om = np.array([g[0] for g in groups])
    ze = np.array([g[1] for g in groups])
    theta_band = modal_angles(n + 1, form)[-1] - 0.5 * np.pi
    kind = "flow" if form == "PP" else "pressure"
    skip = (["column.volume"],)

    def basis(x):                 # columns [sigma/D_i, 1/D_i] at sigma = j x = s tau
        sig = 1j * np.asarray(x)[:, None]
        D = sig**2 + 2.0 * ze * Om * sig + Om**2
        return np.hstack([sig / D, 1.0 / D])

    def known(x):                 # channels of the blocks so far
        return _port_channels(_blocks_transfer(blocks, 1j * np.asarray(x) / tau))

    k2 = 2 * m                    # unknowns per channel; z = [plus (k2), minus (k2)]
    nz = 2 * k2
    x_in = np.linspace(theta_band / TAIL_FIT_POINTS, theta_band, TAIL_FIT_POINTS)
    x_up = theta_band * np.geomspace(1.0, Om[-1] / theta_band, TAIL_FIT_POINTS)[1:]
    E_in = _port_channels(line.transfer(1j * x_in / tau, form)) - known(x_in)
    E_up = _port_channels(_reflection_free(line, 1j * x_up / tau, form)) - known(x_up)
    F_in, F_up = basis(x_in), basis(x_up)
    Q = np.zeros((nz, nz))
    q = np.zeros(nz)
    scales = []
    for c in range(2):
        sl = slice(c * k2, (c + 1) * k2)
        scale = max(np.abs(E_in[:, c]).max(), np.abs(E_up[:, c]).max(), 1e-300)
        scales.append(scale)
        for F, y, w in ((F_in, E_in[:, c], 1.0), (F_up, E_up[:, c], TAIL_MEAN_WEIGHT**2)):
            Q[sl, sl] += w * (F.real.T @ F.real + F.imag.T @ F.imag) / scale**2
            q[sl] += w * (F.real.T @ y.real + F.imag.T @ y.imag) / scale**2
    S = max(scales)               # unknowns w = z/S, of order one
    Q *= S**2 / len(x_in)
    q *= S / len(x_in)
    # equalities: DC gain and first moment of each channel
    G1 = np.vstack([np.concatenate([np.zeros(m), Om**-2.0]),
                    np.concatenate([Om**-2.0, -2.0 * ze * Om**-3.0])])
    Geq = np.zeros((4, nz))
    heq = np.zeros(4)
    r0, r1 = _port_channels(rem0), _port_channels(rem1 / tau)
    for c in range(2):
        Geq[2 * c:2 * c + 2, c * k2:(c + 1) * k2] = G1
        heq[2 * c:2 * c + 2] = np.array([r0[c], r1[c]]) / S
    z0 = _equality_lsq(Q, q, Geq, heq)

    # inequalities, rows a z >= b (scaled)
    A_ub, b_ub = [], []
    if moment2 is not None:       # second moment of the common-mode channel (PP plus)
        h2_known = _port_channels(_second_moment(blocks, skip))[0]
        row = np.zeros(nz)
        # sigma^2 coefficient of (b1 sig + b0)/D: b0 (4 zeta^2 - 1)/Om^4 - 2 zeta b1/Om^3
        row[:m] = 2.0 * ze * Om**-3.0
        row[m:k2] = (1.0 - 4.0 * ze**2) * Om**-4.0
        # h2_known/tau^2 - row z <= 0.5 moment2/tau^2 (both in sigma = s tau)
        A_ub.append(row)
        b_ub.append(np.array([(h2_known - 0.5 * moment2) / tau**2 / S]))

    spacing = np.pi
    x_lo = min(1e-3, 1e-2 * line.dissipation_number) * np.pi
    top = 2.0 * Om[-1]
    x_pass = np.unique(np.concatenate([
        np.geomspace(x_lo, theta_band, 30),
        np.arange(spacing / 4, theta_band, spacing / 4),
        theta_band * np.geomspace(1.0, top / theta_band, 30)]))
    x_fine = np.unique(np.concatenate([
        np.geomspace(x_lo * 0.1, theta_band, 1000),
        np.arange(spacing / 64, top, spacing / 64)]))
    # envelope grid above the band (as _remainder_blocks)
    x_c = np.arange(theta_band, top + 2.0 * np.pi, np.pi / TAIL_POINTS_PER_SPACING)
    env = np.maximum.accumulate(np.abs(line.transfer(1j * x_c[::-1] / tau, form)), axis=0)[::-1]
    keep = x_c <= top
    x_c, bound = x_c[keep], TAIL_BOUND * env[keep][:, 0, :]       # entries 00, 01

    F_fine, K_fine = basis(x_fine), known(x_fine)
    F_c, K_c = basis(x_c), _blocks_transfer(blocks, 1j * x_c / tau)[:, 0, :]

    def exact_real(x):
        """Margin targets ``PASSIVE_MARGIN Re(exact)`` (in the band) and where Re(exact) is
        resolved (> 1e-7 |exact|, above 0.01 of the first mode; near DC the common mode's
        O(omega^2) real part is below the round-off of the blocks' sum, and there the
        second-moment constraint stands for it)."""
        x = np.asarray(x)
        ex = _port_channels(line.transfer(1j * x / tau, form))
        inside = ((x >= 0.25 * np.pi) & (x <= theta_band))[:, None]
        return (np.where(inside, PASSIVE_MARGIN * np.maximum(ex.real, 0.0), 0.0),
                (ex.real > 1e-7 * np.abs(ex)) & (x >= 0.02 * np.pi)[:, None])

    def add_passive(x):
        F, K, (X, ok) = basis(x), known(x), exact_real(x)
        for c in range(2):
            rows = np.zeros((len(x), nz))
            rows[:, c * k2:(c + 1) * k2] = F.real
            A_ub.append(rows[ok[:, c]])
            b_ub.append(((X[:, c] - K[:, c].real) / S)[ok[:, c]])

    def add_envelope(idx, entry, H):
        # entry 00 = (plus + minus)/2, 01 = (plus - minus)/2: the tangent half-plane of
        # |H| <= bound at the current phase, Re(H e^-j arg H) <= bound (cutting planes)
        sgn = 1.0 if entry == 0 else -1.0
        ph = np.exp(-1j * np.angle(H[idx]))[:, None]
        F = F_c[idx] * ph
        rows = np.zeros((len(idx), nz))
        rows[:, :k2] = -0.5 * F.real
        rows[:, k2:] = -0.5 * sgn * F.real
        sc = bound[idx, entry] / S
        A_ub.append(rows / sc[:, None])
        b_ub.append(((K_c[idx, entry] * ph[:, 0]).real / S - TAIL_CUT * sc) / sc)

    X_fine, ok_fine = exact_real(x_fine)
    add_passive(x_pass)
    z, passive = z0, None
    for _ in range(TAIL_ITERATIONS):
        Aub = np.vstack([np.atleast_2d(a) for a in A_ub])
        bub = np.concatenate([np.atleast_1d(b) for b in b_ub])
        z_new = _inequality_lsq(Q, q, Geq, heq, Aub, bub)
        if z_new is None or (Aub @ z_new - bub).min() < -1e-6:
            break                 # infeasible or inaccurate: keep the last passive one
        z = z_new
        added = False
        for c in range(2):        # dense passivity check
            re = K_fine[:, c].real + S * (F_fine.real @ z[c * k2:(c + 1) * k2])
            bad = np.flatnonzero((re < 0.5 * X_fine[:, c]) & ok_fine[:, c])
            if bad.size:
                add_passive(x_fine[bad[:: max(1, bad.size // 20)]])
                added = True
        if not added:
            passive = z
        for e, sgn in ((0, 1.0), (1, -1.0)):
            H = K_c[:, e] + 0.5 * S * (F_c @ (z[:k2] + sgn * z[k2:]))
            over = np.flatnonzero(np.abs(H) > bound[:, e])
            if over.size:
                add_envelope(over[:: max(1, over.size // 20)], e, H)
                added = True
        if not added:
            break
    if passive is None:
        return None
    z = passive

    out = []
    for c, (vin, vout) in enumerate((([1.0, 1.0], [0.5, -0.5]), ([1.0, -1.0], [0.5, 0.5]))):
        chan = ("common" if (form == "PP") == (c == 0) else "differential")
        zc = S * z[c * k2:(c + 1) * k2]
        for i in range(m):
            W, a1 = Om[i] / tau, 2.0 * ze[i] * Om[i] / tau
            b1, b0 = zc[i] / tau, zc[m + i] / tau**2
            Bt = np.vstack([b1 * np.array(vin), b0 / W * np.array(vin)])
            Ct = np.zeros((2, 2))
            Ct[:, 0] = vout
            out.append((np.array([[-a1, W], [-W, 0.0]]), Bt, Ct,
                        [f"tail{i + 1}_{chan}.{kind}1", f"tail{i + 1}_{chan}.{kind}2"]))
    return out


def _single_tail_blocks(n, form, tau, rem0, rem1, ends):
    """PP/QQ: one pseudo-mode per output, ``Omega`` from the lossless tail's first and third
    moments (:func:`_tail_omega`), ``zeta = TAIL_DAMPING``, numerators from the exact DC gain
    and first moment. Passive, but it peaks above the band at 2-9 times the exact envelope."""
    Om = _tail_omega(n, form) / tau
    a1, a0 = 2.0 * TAIL_DAMPING * Om, Om**2
    out = []
    for o in range(2):
        b0 = rem0[o] * a0
        b1 = rem1[o] * a0 + rem0[o] * a1
        Ct = np.zeros((2, 2))
        Ct[o, 0] = 1.0
        end, kind = ends[o]
        out.append((np.array([[-a1, Om], [-Om, 0.0]]), np.vstack([b1, b0 / Om]), Ct,
                    [f"tail_{end}.{kind}1", f"tail_{end}.{kind}2"]))
    return out


def residue_realisation(line: Line, n_modes: int, form: str = "PQ"):
    """State-space matrices of the modal line with exact poles and residues (M6).

    Parameters
    ----------
    line : Line
        The line (needs Dn well below 1, as for (M15))
    n_modes : int
        Number of retained modes n >= 1 (two states each)
    form : str
        Causal form "PQ", "QP", "PP" or "QQ" (docs/model.md table 2.1)

    Returns
    -------
    A, B, C, D : ndarray
        Real matrices, inputs and outputs in the form's order, [SI]; D = 0
        (strictly proper)
    state_names : list[str]
        States as in the module docstring: 2 n modal + 4 viscous + tail (4 per
        group of :func:`tail_groups`, 16), plus 6 column states (PP) or 1 (QQ)
    """
    if not isinstance(line, Line):
        raise ValueError(f"line must be a hydroline.lines.Line, got {type(line).__name__}")
    n = check_modes(n_modes)
    form = check_form(form)
    # a pure function of these numbers, kept in this process and on disk: a later build of
    # the same line (a CLI run, a fit's next evaluation) skips the root finding and fitting
    key = (f"{_SOURCE_TAG}|{form}|{n}|{line.length!r}|{line.diameter!r}|"
           f"{line.fluid.density!r}|{line.fluid.kinematic_viscosity!r}|{line.wave_time!r}")
    if line.viscoelastic:
        key += f"|{line.creep_compliances!r}|{line.retardation_times!r}"

    def decode(stored):
        A, B, C, names = (np.array(stored["A"], dtype=float), np.array(stored["B"], dtype=float),
                          np.array(stored["C"], dtype=float), list(stored["names"]))
        N = len(names)
        if A.shape != (N, N) or B.shape != (N, 2) or C.shape != (2, N):
            return None
        return A, B, C, np.zeros((2, 2)), names

    A, B, C, D, names = _REALISATIONS.get(
        key, lambda: _realise(line, n, form),
        lambda v: {"A": v[0].tolist(), "B": v[1].tolist(), "C": v[2].tolist(), "names": v[4]},
        decode)
    return A.copy(), B.copy(), C.copy(), D.copy(), list(names)


#: Exact-pole realisations of the lines met in this process and on disk
_REALISATIONS = LineMemo("residue_lines")
_SOURCE_TAG = source_tag(__file__, Path(__file__).with_name("line.py"),
                         Path(__file__).with_name("corrections.py"),
                         Path(__file__).with_name("bessel.py"))


def _lumped_pole_blocks(line: Line, poles, form: str, prefix: str, ends, rem0, rem1):
    """One real pole per entry for a cluster of poles near the negative real axis (M44):
    its DC gain and first moment those of the cluster (``sum -R/p``, ``sum -R/p^2`` over
    every pole, complex pairs with both members), subtracted from ``rem0``, ``rem1``.

    Returns
    -------
    list of (A, B, C, names) blocks of one state each, named ``{prefix}{end}{j}.{kind}``
    """
    poles = np.asarray(poles, dtype=complex)
    if not poles.size:
        return []
    R = modal_residues(line, poles, form)
    rates = -poles.real
    out = []
    for o in range(2):
        for j in range(2):
            res = R[:, o, j]
            V0, V1 = float(np.sum(-res / poles).real), float(np.sum(-res / poles**2).real)
            if V0 == 0.0:
                continue
            lam = _lumped_rate(V0, V1, rates, (-res / poles).real)
            Bw = np.zeros((1, 2))
            Bw[0, j] = lam * V0
            Cw = np.zeros((2, 1))
            Cw[o, 0] = 1.0
            end, kind = ends[o]
            out.append((np.array([[-lam]]), Bw, Cw, [f"{prefix}{end}{j + 1}.{kind}"]))
            rem0[o, j] -= V0
            rem1[o, j] -= -V0 / lam
    return out


def viscous_clusters(line: Line, n_modes: int, form: str = "PQ") -> int:
    """Viscous clusters (zeros of I2) a residue line of ``n_modes`` modes resolves: those
    whose rate ``nu j_{2,m}^2/r^2`` is at most the first dropped mode's ``theta_{n+1}/tau``,
    at least one and at most :data:`MAX_VISCOUS_CLUSTERS`, [-]. (In the line's dimensionless
    terms: ``j_{2,m}^2 Dn <= theta_{n+1}``.)

    Parameters
    ----------
    line : Line
        The line, SI
    n_modes : int
        Retained modes, [-]
    form : str
        Causal form "PQ", "QP", "PP" or "QQ"

    Returns
    -------
    int
        The number of clusters, [-].
    """
    form = check_form(form)
    theta_next = modal_angles(check_modes(n_modes) + 1, form)[-1]
    nu, r = line.fluid.kinematic_viscosity, line.radius
    keep = nu * _bessel_zeros(2, MAX_VISCOUS_CLUSTERS) ** 2 / r**2 <= theta_next / line.wave_time
    return max(1, int(np.sum(keep)))


def realisation_with_notes(line: Line, n_modes: int, form: str, clusters: int, shared=None):
    """:func:`residue_realisation` of an elastic-walled line computed (not remembered) with
    ``clusters`` viscous clusters, and notes on its choices that do not vary smoothly with
    the line's numbers (for :mod:`hydroline.lines.residue_table`).

    Parameters
    ----------
    line : Line
        The line (no viscoelastic wall), SI
    n_modes : int
        Retained modes, [-]
    form : str
        Causal form "PQ" or "QP"
    clusters : int
        Viscous clusters resolved (:func:`viscous_clusters` gives the line's own), [-]
    shared : dict or None
        Where given, what does not depend on ``clusters`` (the modes, the viscous roots of
        every cluster, the exact responses of the tail fit) is kept in it and taken from it:
        a realisation of the same line with another cluster count then costs about a fifth

    Returns
    -------
    A, B, C, D : ndarray
        As :func:`residue_realisation`, [SI]
    state_names : list[str]
        The states
    notes : dict
        ``"lumped_margin"``: the smallest relative distance, over the entries, of the
        lumped viscous pole ``-V0/V1`` inside its cluster's range of rates (negative: the
        pole fell outside and the weighted mean rate was taken), [-]; ``"tail_peak"``: the
        first tail fit's largest ``|H|/bound`` above the band (above 1: the bound was
        enforced), [-]
    """
    if line.viscoelastic or check_form(form) not in ("PQ", "QP"):
        raise ValueError("realisation_with_notes: elastic-walled lines in the PQ or QP form")
    notes = {}
    return (*_realise(line, check_modes(n_modes), form, int(clusters), notes, shared), notes)


def _kept(shared, key, compute):
    """``compute()``, kept in the dict ``shared`` under ``key`` (where given)."""
    if shared is None:
        return compute()
    if key not in shared:
        shared[key] = compute()
    return shared[key]


def _mode_blocks(line: Line, n: int, form: str):
    """The k = 0 terms and the retained modes of :func:`_realise`: their blocks (A, B, C,
    names) and their DC gain and first moment (2 x 2 each)."""
    blocks = []                                                     # (A, B, C, names)

    # k = 0 terms
    if form == "QQ":
        blocks.append((np.zeros((1, 1)), np.array([[1.0, -1.0]]),
                       np.full((2, 1), 1.0 / line.capacitance), ["column.volume"]))
    elif form == "PP":
        for m, (Lb, Rb) in enumerate(column_branches(line)):
            blocks.append((np.array([[-Rb / Lb]]), np.array([[1.0 / Lb, -1.0 / Lb]]),
                           np.ones((2, 1)), [f"column.flow{m + 1}"]))

    # retained modes
    poles = modal_poles(line, n, form)
    for k, (p, Rk) in enumerate(zip(poles, modal_residues(line, poles, form)), start=1):
        if form in ("PQ", "QP"):
            A, B, C = _mode_pq(p, Rk)
            names = [f"mode{k}.pressure", f"mode{k}.flow"]
        else:
            A, B, C = _mode_pp(p, Rk)
            kinds = ("volume", "flow") if form == "PP" else ("pressure_integral", "pressure")
            names = [f"mode{k}.{kinds[0]}", f"mode{k}.{kinds[1]}"]
        blocks.append((A, B, C, names))

    # what the exact model still needs: DC gain and first moment of every entry
    H0m, H1m = np.zeros((2, 2)), np.zeros((2, 2))
    for A, B, C, names in blocks:
        if names != ["column.volume"]:             # QQ: the 1/(sC) pole is exact
            X = np.linalg.solve(A, B)
            H0m -= C @ X
            H1m -= C @ np.linalg.solve(A, X)
    return blocks, H0m, H1m


def _all_viscous(line: Line, form: str):
    """The viscous roots of every cluster (:data:`MAX_VISCOUS_CLUSTERS`) [1/s] and the real
    parts of their residues (:func:`modal_residues`)."""
    sv, bessel = _viscous_roots(line, form, None, VISCOUS_ROOTS_PER_CLUSTER, MAX_VISCOUS_CLUSTERS)
    return sv, modal_residues(line, sv, form, bessel).real


def _realise(line: Line, n: int, form: str, clusters=None, notes=None, shared=None):
    """:func:`residue_realisation`'s matrices, computed (an elastic wall: with ``clusters``
    viscous clusters where given, notes on the choices in the dict ``notes``, what does not
    depend on the cluster count kept in the dict ``shared``)."""
    ends = [name.split("_") for name in FORM_PORTS[form][1]]   # [("downstream", "pressure"), ...]
    tau = line.wave_time
    blocks, H0m, H1m = _kept(shared, "modes", lambda: _mode_blocks(line, n, form))
    blocks = list(blocks)
    H0, H1 = exact_moments(line, form)
    rem0, rem1 = H0 - H0m, H1 - H1m

    # V: real-axis poles slower than the first dropped mode, one lumped pole per entry
    theta_next = modal_angles(n + 1, form)[-1]
    if line.viscoelastic:      # (M44): viscous and wall roots, real and complex, together
        sv, wall_roots = retardation_poles(line, form, rate_limit=theta_next / tau)
        blocks += _lumped_pole_blocks(line, sv, form, "viscous_", ends, rem0, rem1)
        # W: the roots beside each retardation rate, one lumped pole per element and entry
        for e, sr in enumerate(wall_roots):
            blocks += _lumped_pole_blocks(line, sr, form, f"wall{e + 1}_", ends, rem0, rem1)
    else:
        if clusters is None:
            sv, bessel = _viscous_roots(line, form, theta_next / tau, VISCOUS_ROOTS_PER_CLUSTER,
                                        MAX_VISCOUS_CLUSTERS)
            Rv = modal_residues(line, sv, form, bessel).real
        elif shared is None:
            sv, bessel = _viscous_roots(line, form, None, VISCOUS_ROOTS_PER_CLUSTER, clusters)
            Rv = modal_residues(line, sv, form, bessel).real
        else:    # every cluster's roots, each solved on its own bracket: the first rows
            sv, Rv = _kept(shared, "viscous", lambda: _all_viscous(line, form))
            sv, Rv = sv[:clusters], Rv[:clusters]
        rates = -sv.ravel()
        margin = np.inf
        for o in range(2):
            for j in range(2):
                res = Rv[..., o, j].ravel()
                V0, V1 = np.sum(res / rates), -np.sum(res / rates**2)
                lam = _lumped_rate(V0, V1, rates, res / rates)
                if notes is not None:
                    ratio = -V0 / V1 if V1 != 0 else -np.inf
                    margin = min(margin, ratio / rates.min() - 1.0, 1.0 - ratio / rates.max())
                Bv = np.zeros((1, 2))
                Bv[0, j] = lam * V0
                Cv = np.zeros((2, 1))
                Cv[o, 0] = 1.0
                end, kind = ends[o]
                blocks.append((np.array([[-lam]]), Bv, Cv, [f"viscous_{end}{j + 1}.{kind}"]))
                rem0[o, j] -= V0
                rem1[o, j] -= -V0 / lam
        if notes is not None:
            notes["lumped_margin"] = float(margin)

    # T: dropped modes; exact DC gain and first moment
    if form in ("PQ", "QP"):      # well-damped grouped pseudo-modes, fitted and bounded
        blocks += _remainder_blocks(line, n, form, blocks, rem0, rem1, ends, notes, shared)
    else:                         # grouped pseudo-modes per port channel, kept passive
        tail = _passive_remainder_blocks(
            line, n, form, blocks, rem0, rem1,
            -line.wave_time * 8.0 * line.dissipation_number * line.wave_time
            / (12.0 * line.impedance) if form == "PP" else None)
        blocks += tail if tail is not None else _single_tail_blocks(n, form, tau, rem0, rem1,
                                                                    ends)

    N = sum(b[0].shape[0] for b in blocks)
    A, B, C = np.zeros((N, N)), np.zeros((N, 2)), np.zeros((2, N))
    names, i = [], 0
    for Ab, Bb, Cb, nb in blocks:
        m = Ab.shape[0]
        A[i:i + m, i:i + m], B[i:i + m], C[:, i:i + m] = Ab, Bb, Cb
        names += nb
        i += m
    return A, B, C, np.zeros((2, 2)), names
