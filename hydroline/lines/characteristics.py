"""Reference time-domain line: method of characteristics with unsteady laminar friction.

This is an independent time-domain model of one hydraulic line (model reference §2), meant as a
reference for the modal state-space lines.  It uses no modal code and nothing from the
Laplace-domain models: only the line's geometry and fluid properties.

Equations (per unit length, flow q = A v positive from end u at x = 0 to end d at x = L)::

    dp/dt + (rho c^2 / A) dq/dx = 0
    (rho / A) dq/dt + dp/dx + (rho / A) F[q] = 0

with the laminar, frequency-dependent wall friction of Zielke (W. Zielke, "Frequency-dependent
friction in transient pipe flow", ASME J. Basic Eng. 90 (1968) 109-115)::

    F[q](t) = (8 nu / r^2) q(t) + (4 nu / r^2) int_0^t W(nu (t - u) / r^2) dq/du(u) du      (Z1)

(8 nu/r^2 = 32 nu/d^2 is the Hagen-Poiseuille term; 4 nu/r^2 = 16 nu/d^2).  Zielke's weighting
function is exactly a sum of exponentials over the zeros j_{2,k} of the Bessel function J2,
``W(tau) = sum_k exp(-j_{2,k}^2 tau)``; it is the time-domain form of the dissipative model (M6):
the Laplace transform of (Z1) is ``F(s) = s (I0(kappa)/I2(kappa) - 1)``, so that
``Gamma^2 = (s L/c)^2 I0/I2`` as in (M6).  For small tau the series converges slowly and
``W ~ 1/(2 sqrt(pi tau)) - 5/4 + ...`` (:func:`zielke_weighting` uses the exact asymptotic
expansion there, whose first six coefficients are Zielke's 0.282095, -1.25, 1.057855, 0.9375,
0.396696, -0.351563).

Weighting-function approximations (``weighting=``):

* ``"zielke"`` (default): an approximation of the exact W built by this module, accurate to
  about 1e-5 (relative) for 1e-14 <= tau <= 0.5 and exact beyond (see
  :func:`weighting_terms`): the first 15 eigen-terms ``exp(-j_{2,k}^2 tau)`` of Zielke's series,
  blended smoothly (C-infinity partition of unity over k = 5 ... 15) into a tail of exponentials
  with rates in geometric progression, 4 per decade up to about 3e16 (the geometric-rate idea of
  Kagawa et al., "High speed and accurate computing method of frequency-dependent friction in
  laminar pipe flow for characteristics method", Trans. JSME B 49 (1983) 2638-2644; see also
  Schohl, ASME J. Fluids Eng. 115 (1993) 420-424), whose weights are fitted here by
  non-negative least squares to the relative error of W on 1e-16 <= tau <= 0.05.  No published
  table is copied: the coefficients are computed once, deterministically, by
  :func:`weighting_terms`, and checked against the exact W in the tests.
* ``"trikha"``: the three-term approximation of A. K. Trikha, "An efficient method for
  simulating frequency-dependent friction in transient liquid flow", ASME J. Fluids Eng. 97
  (1975) 97-105: ``m = (40.0, 8.1, 1.0)``, ``n = (8000, 200, 26.4)``.  Cheap, inaccurate for
  tau < ~1e-4 (high frequencies); kept for comparison.

Each exponential term is convolved recursively (Trikha 1975), with the flow taken piecewise
linear in time over a step, which integrates each exponential exactly::

    y_k(t + dt) = exp(-a_k dt) y_k(t) + m_k (1 - exp(-a_k dt))/(a_k dt) (q(t + dt) - q(t)),
    a_k = n_k nu / r^2.

Terms that decay within one time step (a_k dt > 50) carry no memory and are merged into one.

Discretisation: n_reaches equal reaches, time step dt = (L/n_reaches)/c (Courant number 1, so a
lossless line is reproduced exactly), compatibility equations along dx/dt = +-c::

    C+:  dp + Z0 dq + Z0 F dt = 0,     C-:  dp - Z0 dq - Z0 F dt = 0,     Z0 = rho c / A

with the friction integrated along each characteristic by the trapezoidal rule by default (its
value at the foot, from the known state, and at the head, linear in the unknown flow through the
recursion above, so the scheme stays explicit).  At t = 0 the inputs jump to their t = 0
values from the initial steady state.  Boundaries: pressure imposed at x = 0 (with C-), flow
imposed at x = L (with C+).

Column separation (``line.fluid.cavity_pressure`` set; none otherwise): the discrete vapour
cavity model (DVCM: Wylie & Streeter, *Fluid Transients in Systems*, 1993, sec. 8.2;
Bergant, Simpson & Tijsseling, "Water hammer with column separation: a historical review",
J. Fluids Struct. 22 (2006) 135-171) with the cavity law of the chambers (M42) in place of
its constant cavity pressure (M45). Every node but the upstream one (pressure imposed) may
hold a cavity of volume ``V_ref phi(p)`` (``V_ref`` the node's share of the bore volume,
``A dx``, half at x = L); the node then has two flows, ``q-`` from the reach on its left
(``p + Z q- = C+``) and ``q+`` into the reach on its right (``p - Z q+ = C-``; at x = L
the imposed flow), each reach end keeping its own friction memory, and its oil balance over
a step, implicit (``psi = 1``), ``V_ref phi(p) = V_old + dt (q+ - q-)``, decreasing in p, is
solved by Newton from below (convex: monotone). A node without cavity whose liquid pressure
stays above p_cav is the scheme above, and a cavity closes when the step's inflow fills it.

A rising line (``elevation_rise`` of :meth:`CharacteristicsLine.simulate`: x = L lies that
high above x = 0, the axis straight): gravity adds ``rho g sin(theta)`` to the momentum
equation, which the piezometric pressure ``p + rho g z(x)`` absorbs exactly, so the scheme
runs on it unchanged; the cavity law and the outputs read the pressure itself,
``p = p_pz - rho g z(x)`` (the line at rest holds its hydrostatic profile, and a cavity
opens first at the top).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import optimize, special

from ..fluid import cavity_compliance, cavity_volume_fraction
from .line import Line

__all__ = ["CharacteristicsLine", "CharacteristicsResult", "zielke_weighting", "weighting_terms",
           "TRIKHA_WEIGHTS"]

#: Trikha (1975) three-term approximation of Zielke's weighting function: (m_i, n_i).
TRIKHA_WEIGHTS = (np.array([40.0, 8.1, 1.0]), np.array([8000.0, 200.0, 26.4]))

#: Exact asymptotic expansion W ~ sum_n b_n tau^(n/2 - 1)/Gamma(n/2) for small tau (from the
#: large-argument expansions of I1 and I2); Zielke (1968) quotes the first six, rounded.
_W_ASYMPTOTIC = (1 / 2, -5 / 4, 15 / 16, 15 / 16, 135 / 256, -45 / 64, -7425 / 2048, -675 / 64)
_N_ZEROS = 200
_TAU_SWITCH = 1e-3        # asymptotic series below, eigen-series (200 terms) above


@lru_cache(maxsize=1)
def _j2_squared() -> np.ndarray:
    return special.jn_zeros(2, _N_ZEROS) ** 2


def zielke_weighting(tau) -> np.ndarray:
    """Zielke's (1968) weighting function W(tau) for laminar unsteady friction, exact.

    ``W(tau) = sum_k exp(-j_{2,k}^2 tau)`` (j_{2,k}: zeros of J2), evaluated with 200 terms for
    tau >= 1e-3 and with the small-time asymptotic expansion (8 terms, error < 1e-10) below.

    Parameters
    ----------
    tau : array_like
        Dimensionless time ``nu t / r^2 = 4 nu t / d^2``, > 0 [-].

    Returns
    -------
    ndarray
        W(tau), the shape of ``tau`` [-].

    Examples
    --------
    At large tau only the first term is left, ``exp(-j_{2,1}^2 tau)`` with
    ``j_{2,1} = 5.1356223``; at small tau Zielke's expansion starts
    ``0.282095/sqrt(tau) - 1.25``:

    >>> import numpy as np
    >>> round(float(zielke_weighting(0.5)) / np.exp(-5.1356223**2 * 0.5), 6)
    1.0
    >>> round(float(zielke_weighting(1e-6)), 3), round(0.282095 / np.sqrt(1e-6) - 1.25, 3)
    (280.846, 280.845)
    """
    tau = np.asarray(tau, dtype=float)
    if np.any(~(tau > 0)):
        raise ValueError("tau must be > 0 [-]")
    flat = tau.reshape(-1)
    out = np.empty_like(flat)
    small = flat < _TAU_SWITCH
    ts = flat[small]
    out[small] = sum(b * ts ** (n / 2 - 1) / math.gamma(n / 2)
                     for n, b in enumerate(_W_ASYMPTOTIC, start=1))
    tl = flat[~small]
    out[~small] = np.exp(-np.outer(tl, _j2_squared())).sum(axis=1)
    return out.reshape(tau.shape)


def _smooth_step(x):
    """C-infinity step: 1 for x <= 0, 0 for x >= 1."""
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    a = np.where(x > 0, np.exp(-1.0 / np.maximum(x, 1e-300)), 0.0)
    b = np.where(x < 1, np.exp(-1.0 / np.maximum(1.0 - x, 1e-300)), 0.0)
    return b / (a + b)


@lru_cache(maxsize=4)
def _fit_zielke(k_blend=(5, 15), per_decade=4, tau_min=1e-14, tau_fit_max=0.05):
    k1, k2 = k_blend
    xk = _j2_squared()[:k2]
    chi = _smooth_step((np.arange(1, k2 + 1) - k1) / (k2 - k1))
    n_tail = int(np.ceil(np.log10(300.0 / tau_min / xk[k1 - 1]) * per_decade)) + 1
    rates = xk[k1 - 1] * 10.0 ** (np.arange(n_tail) / per_decade)
    tau = np.logspace(np.log10(tau_min) - 2, np.log10(tau_fit_max), 3000)
    w = zielke_weighting(tau)
    target = w - np.exp(-np.outer(tau, xk)) @ chi
    A = np.exp(-np.outer(tau, rates)) / w[:, None]
    m_tail = optimize.nnls(A, target / w, maxiter=100000)[0]
    m = np.concatenate([chi, m_tail])
    n = np.concatenate([xk, rates])
    keep = m > 0
    return m[keep], n[keep]


def weighting_terms(weighting: str = "zielke"):
    """Coefficients of the exponential-sum weighting function ``W(tau) ~ sum m_i exp(-n_i tau)``.

    Parameters
    ----------
    weighting : str
        "zielke" (this module's accurate approximation of the exact W, see the module
        docstring) or "trikha" (Trikha 1975: m = 40.0, 8.1, 1.0; n = 8000, 200, 26.4).

    Returns
    -------
    (m, n) : tuple of ndarray
        Weights m_i [-] and dimensionless rates n_i [-] (rate in time: ``n_i nu / r^2`` [1/s]).
    """
    if weighting == "zielke":
        m, n = _fit_zielke()
    elif weighting == "trikha":
        m, n = TRIKHA_WEIGHTS
    else:
        raise ValueError(f"weighting must be 'zielke' or 'trikha'; got {weighting!r}")
    return m.copy(), n.copy()


@dataclass(frozen=True)
class CharacteristicsResult:
    """Time histories at the two ends of a line, SI units.

    Attributes
    ----------
    t : ndarray
        Times t_n = n dt, [s].
    upstream_pressure : ndarray
        p at x = 0 (imposed), [Pa].
    downstream_pressure : ndarray
        p at x = L (PQ-form output), [Pa].
    upstream_flow : ndarray
        q at x = 0, positive into the line (PQ-form output), [m^3/s].
    downstream_flow : ndarray
        q at x = L, positive out of the line (imposed), [m^3/s].
    cavity_volume : ndarray or None
        Total volume of the discrete cavities along the line (M45), [m^3]; None without a
        cavity model (``line.fluid.cavity_pressure`` None).
    downstream_cavity_volume : ndarray or None
        The cavity at x = L, [m^3]; None without a cavity model.
    """

    t: np.ndarray
    upstream_pressure: np.ndarray
    downstream_pressure: np.ndarray
    upstream_flow: np.ndarray
    downstream_flow: np.ndarray
    cavity_volume: np.ndarray | None = None
    downstream_cavity_volume: np.ndarray | None = None


def _as_signal(value, name: str, unit: str):
    """Return f(t_array) -> ndarray for a constant or a callable input."""
    if callable(value):
        def f(t):
            try:
                v = np.asarray(value(t), dtype=float)
                if v.shape != t.shape:
                    v = np.broadcast_to(v, t.shape).copy() if v.ndim == 0 else None
            except (TypeError, ValueError):
                v = None
            if v is None:
                v = np.array([float(value(ti)) for ti in t])
            if not np.all(np.isfinite(v)):
                raise ValueError(f"{name} must return finite values [{unit}]")
            return v
        return f
    try:
        c = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number [{unit}] or a function of time t [s]; "
                         f"got {value!r}") from None
    if not np.isfinite(c):
        raise ValueError(f"{name} must be finite [{unit}], got {value!r}")
    return lambda t: np.full(t.shape, c)


class CharacteristicsLine:
    """A line solved by the method of characteristics with unsteady laminar friction.

    Parameters
    ----------
    line : Line
        Geometry, fluid and effective bulk modulus (its wave speed c and impedance Z0 are used).
    n_reaches : int
        Number of equal reaches N >= 1 [-]; the time step is ``dt = L/(N c)`` [s].
    friction : str
        "unsteady" (default: Zielke's frequency-dependent laminar friction, the time-domain
        form of the dissipative model (M6)), "steady" (Hagen-Poiseuille 32 nu v/d^2 only) or
        "none" (lossless).
    weighting : str
        Exponential approximation of Zielke's weighting function, "zielke" (accurate, default)
        or "trikha" (Trikha 1975), see :func:`weighting_terms`.

    Attributes
    ----------
    dt : float
        Time step, [s].
    dx : float
        Reach length, [m].

    Notes
    -----
    Accuracy (measured against :func:`hydroline.lines.inverse_laplace.exact_step_response`
    with the dissipative model (M6); unit pressure step, blocked end, ten wave periods, times
    more than 0.1 L/c away from the wave fronts): for a 3.048 m x 12.7 mm hose (oil
    nu = 3.2e-5 m^2/s, c = 1072 m/s) max error 0.084 / 0.043 / 0.023 / 0.012 and rms
    0.018 / 0.0094 / 0.0048 / 0.0025 of the step for 16 / 32 / 64 / 128 reaches; for a
    10 m x 6 mm line max 0.071 / 0.037 / 0.020 / 0.011.  The convergence is first order; the
    error sits just behind the wave fronts, where the friction of a step has its
    1/sqrt(time) singularity, and shows there as a decaying odd-even (2 dt) ripple.  Steady
    friction alone is wrong by more than 50 % of the step for such hoses.
    """

    def __init__(self, line: Line, n_reaches: int = 64, friction: str = "unsteady",
                 weighting: str = "zielke"):
        if not isinstance(line, Line):
            raise ValueError(f"line must be a hydroline Line, got {type(line).__name__}")
        if isinstance(n_reaches, bool) or not isinstance(n_reaches, (int, np.integer)) \
                or n_reaches < 1:
            raise ValueError(f"n_reaches must be an integer >= 1 [-], got {n_reaches!r}")
        if friction not in ("unsteady", "steady", "none"):
            raise ValueError(f"friction must be 'unsteady', 'steady' or 'none'; got {friction!r}")
        self.line = line
        self.n_reaches = int(n_reaches)
        self.friction = friction
        self.weighting = weighting
        self.dx = line.length / self.n_reaches
        self.dt = self.dx / line.wave_speed
        nu, r = line.fluid.kinematic_viscosity, line.radius
        self._steady = 8.0 * nu / r**2 if friction != "none" else 0.0          # [1/s]
        self._unsteady = 4.0 * nu / r**2 if friction == "unsteady" else 0.0    # [1/s]
        m, n = weighting_terms(weighting)       # validates weighting
        if friction == "unsteady":
            x = n * nu * self.dt / r**2           # a_k dt
            phi = -np.expm1(-x) / x
            slow = x <= 50.0
            decay = np.exp(-x[slow])
            mphi = m[slow] * phi[slow]
            fast = np.sum(m[~slow] * phi[~slow])
            if fast > 0:                          # merged memory-less terms
                decay = np.append(decay, 0.0)
                mphi = np.append(mphi, fast)
        else:
            decay, mphi = np.zeros(0), np.zeros(0)
        self._decay = decay
        self._mphi = mphi

    @property
    def n_terms(self) -> int:
        """Number of recursive convolution states per node [-]."""
        return self._decay.size

    def simulate(self, t_end: float, upstream_pressure=1.0, downstream_flow=0.0,
                 initial_pressure: float = 0.0, initial_flow: float = 0.0,
                 theta: float = 0.5, elevation_rise: float = 0.0,
                 gravity: float = 9.81) -> CharacteristicsResult:
        """Simulate the line with a pressure imposed upstream and a flow imposed downstream.

        Parameters
        ----------
        t_end : float
            End time, > 0 [s]; the result holds t_n = n dt for n = 0 ... ceil(t_end/dt).
        upstream_pressure : float or callable
            Pressure p_u(t) at x = 0 [Pa]: a constant (a step at t = 0 from the initial
            state) or a function of time [s] (called with an array of times, or per time).
        downstream_flow : float or callable
            Flow q_d(t) out of the line at x = L [m^3/s]; 0 = blocked end.
        initial_pressure : float
            Upstream pressure of the initial steady state (t < 0) [Pa].
        initial_flow : float
            Flow of the initial steady state [m^3/s]; the initial pressure then falls linearly
            along the line by the laminar resistance (M12), with no unsteady-friction memory.
        theta : float
            Weight of the head (new time level) in the friction integral along a
            characteristic, 0 (explicit, friction at the foot only) ... 1; 0.5 = trapezoidal
            (default) [-].
        elevation_rise : float
            Height of the downstream end (x = L) above the upstream end, the line straight
            between them (negative: it falls) [m]. The pressures in and out are the ends'
            own; the line at rest holds ``initial_pressure - rho g z(x)``.
        gravity : float
            Acceleration of gravity, [m/s^2].

        Returns
        -------
        CharacteristicsResult
        """
        try:
            t_end = float(t_end)
        except (TypeError, ValueError):
            raise ValueError(f"t_end must be a positive time [s], got {t_end!r}") from None
        if not (t_end > 0 and np.isfinite(t_end)):
            raise ValueError(f"t_end must be a positive finite time [s], got {t_end!r}")
        if not 0 <= theta <= 1:
            raise ValueError(f"theta must lie in [0, 1] [-], got {theta!r}")
        for name, v, unit in (("initial_pressure", initial_pressure, "Pa"),
                              ("initial_flow", initial_flow, "m^3/s"),
                              ("elevation_rise", elevation_rise, "m"),
                              ("gravity", gravity, "m/s^2")):
            if not np.isfinite(float(v)):
                raise ValueError(f"{name} must be finite [{unit}], got {v!r}")
        pu_fun = _as_signal(upstream_pressure, "upstream_pressure", "Pa")
        qd_fun = _as_signal(downstream_flow, "downstream_flow", "m^3/s")

        N, dt = self.n_reaches, self.dt
        n_steps = int(np.ceil(t_end / dt - 1e-9))
        if n_steps > 10_000_000:
            raise ValueError(f"t_end/dt = {t_end / dt:.3g} steps is too many; use fewer reaches "
                             f"or a shorter t_end [s]")
        t = np.arange(n_steps + 1) * dt
        pu = pu_fun(t)
        qd = qd_fun(t)

        Z0 = self.line.impedance
        Rs, cu = self._steady, self._unsteady
        decay, mphi = self._decay, self._mphi
        G = Rs + cu * mphi.sum()                       # d F_head / d q_head [1/s]
        zeff = Z0 * (1.0 + dt * theta * G)
        a_foot = Z0 * dt * (1.0 - theta)
        a_head = Z0 * dt * theta

        # initial steady state (M12): uniform flow, linear laminar pressure drop; p is the
        # piezometric pressure (referred to x = 0's height), `lift` what it exceeds p by
        x = np.linspace(0.0, 1.0, N + 1)
        q = np.full(N + 1, float(initial_flow))
        p = float(initial_pressure) - self.line.resistance * float(initial_flow) * x
        lift = self.line.fluid.density * float(gravity) * float(elevation_rise) * x
        Y = np.zeros((N + 1, decay.size))

        out_pd = np.empty(n_steps + 1)
        out_qu = np.empty(n_steps + 1)
        out_pu = np.empty(n_steps + 1)
        out_qd = np.empty(n_steps + 1)

        def advance(p, q, Y, p_up, q_down):
            F = Rs * q + cu * Y.sum(axis=1)             # friction at the feet (time n)
            H = cu * (Y @ decay - mphi.sum() * q)        # head friction = G q_new + H
            cp = np.empty(N + 1)
            cm = np.empty(N + 1)
            cp[1:] = p[:-1] + Z0 * q[:-1] - a_foot * F[:-1] - a_head * H[1:]
            cm[:-1] = p[1:] - Z0 * q[1:] + a_foot * F[1:] + a_head * H[:-1]
            pn = np.empty(N + 1)
            qn = np.empty(N + 1)
            pn[1:-1] = 0.5 * (cp[1:-1] + cm[1:-1])
            qn[1:-1] = (cp[1:-1] - cm[1:-1]) / (2.0 * zeff)
            pn[0] = p_up
            qn[0] = (p_up - cm[0]) / zeff
            qn[-1] = q_down
            pn[-1] = cp[-1] - zeff * q_down
            Yn = Y * decay + np.outer(qn - q, mphi)
            return pn, qn, Yn

        fluid = self.line.fluid
        if fluid.cavity_pressure is not None:
            return self._simulate_with_cavities(t, pu, qd, p, q, Y, zeff, a_foot, a_head, lift)

        # t = 0: the inputs take their t = 0 values (a step from the initial state); the steady
        # initial state is a fixed point of the scheme, so one step from it moves only the
        # boundary nodes, as it must.
        p, q, Y = advance(p, q, Y, pu[0], qd[0])
        out_pu[0], out_pd[0], out_qu[0], out_qd[0] = p[0], p[-1], q[0], q[-1]
        for k in range(1, n_steps + 1):
            p, q, Y = advance(p, q, Y, pu[k], qd[k])
            out_pu[k], out_pd[k], out_qu[k], out_qd[k] = p[0], p[-1], q[0], q[-1]
        if lift[-1] != 0.0:
            out_pd -= lift[-1]
        return CharacteristicsResult(t, out_pu, out_pd, out_qu, out_qd)

    def _simulate_with_cavities(self, t, pu, qd, p, q, Y, zeff, a_foot, a_head, lift):
        """The scheme of :meth:`simulate` with a discrete cavity at every node but x = 0
        (DVCM with the cavity law M42, see the module docstring); ``p`` piezometric, the
        node's own pressure ``p - lift``."""
        fluid, N, dt, Z0 = self.line.fluid, self.n_reaches, self.dt, self.line.impedance
        Rs, cu, decay, mphi = self._steady, self._unsteady, self._decay, self._mphi
        pc, delta = fluid.cavity_pressure, fluid.cavity_pressure_drop
        v_ref = np.full(N + 1, self.line.area * self.dx)
        v_ref[-1] *= 0.5
        k_dt_z = np.full(N + 1, 2.0 * dt / zeff)        # d(dt (q+ - q-))/dp at a node
        k_dt_z[-1] = dt / zeff
        # each node's two reach ends: flow and friction memory on its left (-) and right (+)
        qm, qp, Ym, Yp = q.copy(), q.copy(), Y.copy(), Y.copy()
        vc = np.zeros(N + 1)
        out = {k: np.empty(t.size) for k in ("pu", "pd", "qu", "qd", "vc", "vd")}

        def node_pressure(p_liq, v_old, i):
            """Root of ``V_ref phi(p) - V_old - k dt/Z (p - p_liq)`` (decreasing, convex):
            Newton from a start below it, where the function is positive."""
            vr, kz = v_ref[i], k_dt_z[i]
            x = np.minimum(p_liq, pc) - delta * (v_old / vr + 1.0)
            for _ in range(60):
                g = vr * cavity_volume_fraction(x, pc, delta) - v_old - kz * (x - p_liq)
                step = g / (cavity_compliance(vr, x, fluid) + kz)
                x = x + step
                if np.all(np.abs(step) <= 1e-12 * (np.abs(x) + delta)):
                    break
            return x

        for n in range(t.size):
            Fp = Rs * qp + cu * Yp.sum(axis=1)          # friction at the feet (time n)
            Fm = Rs * qm + cu * Ym.sum(axis=1)
            Hm = cu * (Ym @ decay - mphi.sum() * qm)    # head friction = G q_new + H
            Hp = cu * (Yp @ decay - mphi.sum() * qp)
            cp = np.empty(N + 1)
            cm = np.empty(N + 1)
            cp[1:] = p[:-1] + Z0 * qp[:-1] - a_foot * Fp[:-1] - a_head * Hm[1:]
            cm[:-1] = p[1:] - Z0 * qm[1:] + a_foot * Fm[1:] + a_head * Hp[:-1]
            p_liq = np.empty(N + 1)
            p_liq[0] = pu[n]
            p_liq[1:-1] = 0.5 * (cp[1:-1] + cm[1:-1])
            p_liq[-1] = cp[-1] - zeff * qd[n]
            pn = p_liq.copy()
            open_ = (vc > 0) | (p_liq - lift < pc)
            open_[0] = False
            i = np.flatnonzero(open_)
            if i.size:               # the cavity law in the node's own pressure
                pn[i] = node_pressure(p_liq[i] - lift[i], vc[i], i) + lift[i]
            vn = np.zeros(N + 1)
            vn[i] = v_ref[i] * cavity_volume_fraction(pn[i] - lift[i], pc, delta)
            qmn, qpn = np.empty(N + 1), np.empty(N + 1)
            qpn[0] = (pu[n] - cm[0]) / zeff
            qmn[0] = qpn[0]
            qmn[1:] = (cp[1:] - pn[1:]) / zeff
            qpn[1:-1] = (pn[1:-1] - cm[1:-1]) / zeff
            qpn[-1] = qd[n]
            Ym = Ym * decay + np.outer(qmn - qm, mphi)
            Yp = Yp * decay + np.outer(qpn - qp, mphi)
            p, qm, qp, vc = pn, qmn, qpn, vn
            out["pu"][n], out["pd"][n], out["qu"][n], out["qd"][n] = (p[0], p[-1] - lift[-1],
                                                                      qp[0], qp[-1])
            out["vc"][n], out["vd"][n] = vc.sum(), vc[-1]
        return CharacteristicsResult(t, out["pu"], out["pd"], out["qu"], out["qd"],
                                     cavity_volume=out["vc"], downstream_cavity_volume=out["vd"])

    def step_response(self, t_end: float, upstream_pressure=1.0, downstream="blocked",
                      initial_pressure: float = 0.0) -> CharacteristicsResult:
        """Response of the line at rest to an upstream pressure step (PQ causality).

        Parameters
        ----------
        t_end : float
            End time, > 0 [s].
        upstream_pressure : float or callable
            p_u(t) for t >= 0 [Pa]; a constant is a step at t = 0 from ``initial_pressure``.
        downstream : "blocked", float or callable
            Downstream end: "blocked" (q_d = 0) or the imposed flow q_d(t) [m^3/s].
        initial_pressure : float
            Pressure of the line at rest before t = 0 [Pa].

        Returns
        -------
        CharacteristicsResult
            ``t`` [s], ``downstream_pressure`` [Pa] and ``upstream_flow`` [m^3/s] (the PQ-form
            outputs), and the imposed ``upstream_pressure`` and ``downstream_flow``.
        """
        if isinstance(downstream, str):
            if downstream != "blocked":
                raise ValueError(f"downstream must be 'blocked', a flow [m^3/s] or a function of "
                                 f"time; got {downstream!r}")
            downstream = 0.0
        return self.simulate(t_end, upstream_pressure=upstream_pressure,
                             downstream_flow=downstream, initial_pressure=initial_pressure)

    def __repr__(self) -> str:
        return (f"CharacteristicsLine(L={self.line.length:g} m, d={self.line.diameter:g} m, "
                f"n_reaches={self.n_reaches}, dt={self.dt:.4g} s, friction={self.friction!r}, "
                f"weighting={self.weighting!r})")
