"""Line parameters and the exact four-pole models of a hydraulic line (model reference §2).

Conventions: flow positive from end u (upstream) to end d (downstream); the four causal forms
map inputs to outputs in the order of the model reference's table 2.1:

====  ==========  ==========
form  inputs      outputs
====  ==========  ==========
PQ    P_u, Q_d    P_d, Q_u
QP    Q_u, P_d    P_u, Q_d
PP    P_u, P_d    Q_u, Q_d
QQ    Q_u, Q_d    P_u, P_d
====  ==========  ==========
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fluid import Fluid, require_positive
from .bessel import scaled_bessel_i012

__all__ = ["Line", "FORMS", "FORM_PORTS", "check_form", "bessel_ratio"]

FORMS = ("PQ", "QP", "PP", "QQ")

#: Named inputs and outputs of every causal form, in matrix order.
FORM_PORTS = {
    "PQ": (("upstream_pressure", "downstream_flow"), ("downstream_pressure", "upstream_flow")),
    "QP": (("upstream_flow", "downstream_pressure"), ("upstream_pressure", "downstream_flow")),
    "PP": (("upstream_pressure", "downstream_pressure"), ("upstream_flow", "downstream_flow")),
    "QQ": (("upstream_flow", "downstream_flow"), ("upstream_pressure", "downstream_pressure")),
}


def check_form(form: str) -> str:
    """Return the canonical name of a causal form, or raise ValueError naming ``form``.

    Parameters
    ----------
    form : str
        "PQ", "QP", "PP" or "QQ", any case.

    Returns
    -------
    str
        The form in upper case.

    Raises
    ------
    ValueError
        If ``form`` is not one of the four.
    """
    f = str(form).upper()
    if f not in FORMS:
        raise ValueError(f"form must be one of {', '.join(FORMS)}; got {form!r}")
    return f


def bessel_ratio(kappa):
    """I0(kappa)/I2(kappa) for complex kappa with Re(kappa) >= 0, overflow-free (M6).

    Uses exponentially scaled Bessel functions (the scaling cancels in the ratio;
    :func:`hydroline.lines.bessel.scaled_bessel_i012`, NumPy alone); for
    ``abs(kappa) < 1e-3`` the series ``8/kappa^2 + 4/3 + kappa^2/24`` avoids cancellation
    in I2.

    Parameters
    ----------
    kappa : complex or array_like
        ``r sqrt(s/nu)``, the bore radius over the viscous penetration depth, [-].

    Returns
    -------
    complex ndarray
        ``I0(kappa)/I2(kappa)``, same shape as ``kappa``, [-].

    Examples
    --------
    The ratio tends to 1 for large kappa (lossless line) and to ``8/kappa^2 + 4/3`` for
    small kappa (laminar resistance and 4/3 of the plug-flow inertance):

    >>> abs(complex(bessel_ratio(1e4)) - 1) < 1e-3
    True
    >>> k = 1e-4
    >>> round(float(bessel_ratio(k).real) - 8 / k**2, 6)     # 4/3
    1.333333
    """
    kappa = np.asarray(kappa, dtype=complex)
    small = np.abs(kappa) < 1e-3
    k_safe = np.where(small, 1.0, kappa)
    i0, i2 = scaled_bessel_i012(k_safe, (0, 2))
    ratio = i0 / i2
    k2 = np.where(small, kappa, 1.0) ** 2
    series = 8.0 / k2 + 4.0 / 3.0 + k2 / 24.0
    return np.where(small, series, ratio)


@dataclass(frozen=True)
class Line:
    """A uniform hydraulic line (hose or pipe) of circular bore.

    Derived quantities (M2)-(M4), the lumped R, I, C and the exact transfer matrices of the
    four causal forms (M5)-(M7) are methods and properties of the line.

    Parameters
    ----------
    length : float
        Line length L, [m].
    diameter : float
        Inner diameter d, [m].
    fluid : Fluid
        The fluid (density, kinematic viscosity, bulk modulus of the pure oil).
    bulk_modulus : float or None
        Effective bulk modulus beta_e of the oil in this line (oil, wall and air in series,
        see :func:`hydroline.effective_bulk_modulus`), [Pa]; the fluid's when None.
    creep_compliances : tuple of float
        Viscoelastic wall (M44): the Kelvin-Voigt elements' creep compliances J_k of the
        line's volume, ``(1/V) dV/dp`` retarded, [1/Pa]; for a thin wall of material creep
        compliance J_k' this is ``alpha d/e J_k'`` (Covas et al. 2004). Empty: an elastic wall
        (``bulk_modulus`` is then the whole compliance); with elements, ``bulk_modulus`` is
        the instantaneous (high-frequency) one.
    retardation_times : tuple of float
        The elements' retardation times tau_k, [s]; as many as ``creep_compliances``.

    Raises
    ------
    ValueError
        If a length, diameter or modulus is not positive and finite, or ``fluid`` is not a
        :class:`~hydroline.fluid.Fluid`.

    Examples
    --------
    The worked example of the model reference (§2.3): d = 19 mm, nu = 3.2e-5 m^2/s,
    c = 488 m/s (beta_e = rho c^2), L = 3.048 m. Its first blocked-line mode (M9) is at
    c/(4L) = 40 Hz and Dn = 4 nu L/(c d^2) = 2.2e-3 (M4):

    >>> from hydroline import Fluid
    >>> oil = Fluid(870.0, 3.2e-5, 1.5e9)
    >>> line = Line(3.048, 0.019, oil, bulk_modulus=870.0 * 488.0**2)
    >>> round(line.wave_speed, 6), round(line.wave_speed / (4 * line.length), 2)
    (488.0, 40.03)
    >>> round(line.dissipation_number, 6)
    0.002215
    >>> round(line.resistance / (8 * line.impedance * line.dissipation_number), 12)   # R = 8 Z0 Dn
    1.0
    """

    length: float
    diameter: float
    fluid: Fluid
    bulk_modulus: float | None = None
    creep_compliances: tuple = ()
    retardation_times: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "length", require_positive("length", self.length, "m"))
        object.__setattr__(self, "diameter", require_positive("diameter", self.diameter, "m"))
        if not isinstance(self.fluid, Fluid):
            raise ValueError(f"fluid must be a hydroline.Fluid, got {type(self.fluid).__name__}")
        beta = self.fluid.bulk_modulus if self.bulk_modulus is None else self.bulk_modulus
        object.__setattr__(self, "bulk_modulus", require_positive("bulk_modulus", beta, "Pa"))
        J = tuple(require_positive("creep_compliances", j, "1/Pa") for j in self.creep_compliances)
        T = tuple(require_positive("retardation_times", t, "s") for t in self.retardation_times)
        if len(J) != len(T):
            raise ValueError(f"creep_compliances [1/Pa] and retardation_times [s] must be as many; "
                             f"got {len(J)} and {len(T)}")
        if len(set(T)) != len(T):
            raise ValueError(f"retardation_times [s] must differ from one another, got {T}")
        object.__setattr__(self, "creep_compliances", J)
        object.__setattr__(self, "retardation_times", T)

    # ---- viscoelastic wall (M44) --------------------------------------------------------
    @property
    def viscoelastic(self) -> bool:
        """True when the wall has Kelvin-Voigt elements (M44)."""
        return bool(self.creep_compliances)

    def wall_factor(self, s):
        """``W(s) = beta_e/beta(s) = 1 + beta_e sum_k J_k/(1 + s tau_k)`` (M44), [-].

        The line's compliance per volume is ``W(s)/beta_e``: 1 for an elastic wall, rising to
        ``1 + beta_e sum J_k`` at DC.

        Parameters
        ----------
        s : complex or array_like
            Laplace variable, [1/s].

        Returns
        -------
        complex ndarray
            W(s), same shape as ``s``, [-].
        """
        s = np.asarray(s, dtype=complex)
        w = np.ones_like(s)
        for J, tau in zip(self.creep_compliances, self.retardation_times):
            w = w + self.bulk_modulus * J / (1.0 + s * tau)
        return w

    def wall_factor_derivative(self, s):
        """``dW/ds = -beta_e sum_k J_k tau_k/(1 + s tau_k)^2`` (M44), [s].

        Parameters
        ----------
        s : complex or array_like
            Laplace variable, [1/s].

        Returns
        -------
        complex ndarray
            W'(s), same shape as ``s``, [s].
        """
        s = np.asarray(s, dtype=complex)
        d = np.zeros_like(s)
        for J, tau in zip(self.creep_compliances, self.retardation_times):
            d = d - self.bulk_modulus * J * tau / (1.0 + s * tau) ** 2
        return d

    # ---- derived parameters (M2)-(M4) -------------------------------------------------
    @property
    def radius(self) -> float:
        """Inner radius r = d/2, [m]."""
        return 0.5 * self.diameter

    @property
    def area(self) -> float:
        """Bore area A = pi d^2/4, [m^2]."""
        return np.pi * self.diameter**2 / 4.0

    @property
    def wave_speed(self) -> float:
        """Wave speed c = sqrt(beta_e/rho) (M2), [m/s]."""
        return float(np.sqrt(self.bulk_modulus / self.fluid.density))

    @property
    def impedance(self) -> float:
        """Line impedance constant Z0 = rho c / A (M3), [Pa s/m^3]."""
        return self.fluid.density * self.wave_speed / self.area

    @property
    def dissipation_number(self) -> float:
        """Dissipation number Dn = 4 nu L/(c d^2) (M4), [-]."""
        return 4.0 * self.fluid.kinematic_viscosity * self.length / (self.wave_speed * self.diameter**2)

    @property
    def resistance(self) -> float:
        """Laminar (Hagen-Poiseuille) resistance R = 128 rho nu L/(pi d^4) = 8 Z0 Dn, [Pa s/m^3]."""
        return 128.0 * self.fluid.dynamic_viscosity * self.length / (np.pi * self.diameter**4)

    @property
    def inertance(self) -> float:
        """Fluid inertance I = rho L / A, [kg/m^4]."""
        return self.fluid.density * self.length / self.area

    @property
    def capacitance(self) -> float:
        """Line capacitance C = A L / beta_e, [m^3/Pa]."""
        return self.area * self.length / self.bulk_modulus

    @property
    def wave_time(self) -> float:
        """One-way wave travel time L/c, [s]."""
        return self.length / self.wave_speed

    @property
    def volume(self) -> float:
        """Fluid volume A L, [m^3]."""
        return self.area * self.length

    # ---- propagation operator and characteristic impedance -----------------------------
    def propagation(self, s, friction: str = "dissipative", alpha: float = 1.0, beta: float = 1.0):
        """Propagation operator Gamma(s) and characteristic impedance Zc(s), (M6) or (M7).

        A viscoelastic wall (M44) multiplies Gamma by ``sqrt(W(s))`` and divides Zc by it.

        Parameters
        ----------
        s : complex or array_like
            Laplace variable, Re(s) >= 0 for the dissipative model, [1/s].
        friction : str
            "dissipative" (M6) or "linear" (M7).
        alpha, beta : float
            Frequency and damping correction factors of the linear model (M7), [-].

        Returns
        -------
        gamma : complex ndarray
            Gamma(s), same shape as ``s``, [-].
        zc : complex ndarray
            Zc(s), [Pa s/m^3].

        Raises
        ------
        ValueError
            If ``friction`` is neither model.
        """
        s = np.asarray(s, dtype=complex)
        nu = self.fluid.kinematic_viscosity
        if friction == "dissipative":
            kappa = self.radius * np.sqrt(s / nu)
            factor = np.sqrt(bessel_ratio(kappa))
        elif friction == "linear":
            factor = np.sqrt(alpha**2 + 32.0 * alpha * beta * nu / (s * self.diameter**2))
        else:
            raise ValueError(f"friction must be 'dissipative' or 'linear'; got {friction!r}")
        if self.viscoelastic:      # series impedance unchanged, shunt compliance W/beta_e (M44)
            w = np.sqrt(self.wall_factor(s))
            return s * self.wave_time * factor * w, self.impedance * factor / w
        return s * self.wave_time * factor, self.impedance * factor

    @staticmethod
    def form_ports(form: str) -> tuple:
        """The input and output port names of a causality form (:data:`FORM_PORTS`).

        Parameters
        ----------
        form : str
            Causality form, a key of :data:`FORM_PORTS` ("PQ", "QP", "PP", "QQ")

        Returns
        -------
        tuple
            ``(inputs, outputs)``, each a pair of port names such as ``"upstream_pressure"``
        """
        return FORM_PORTS[form]

    def transfer(self, s, form: str = "PQ", friction: str = "dissipative",
                 alpha: float = 1.0, beta: float = 1.0):
        """Exact transfer matrix of a causal form (model reference table 2.1, M5).

        Parameters
        ----------
        s : complex or array_like
            Laplace variable (e.g. ``2j*pi*f``), [1/s].
        form : str
            "PQ", "QP", "PP" or "QQ".
        friction : str
            "dissipative" (M6) or "linear" (M7).
        alpha, beta : float
            Correction factors for the linear model, [-].

        Returns
        -------
        complex ndarray
            Shape ``s.shape + (2, 2)``; entry ``[..., i, j]`` maps input j to output i of
            the form, [Pa/Pa, Pa/(m^3/s), (m^3/s)/Pa or 1 as the entry requires].

        Examples
        --------
        At low frequency the PQ line's pressure-to-pressure gain is 1 and its flow-to-pressure
        entry is minus the laminar resistance (M12):

        >>> from hydroline import MINERAL_OIL
        >>> line = Line(3.048, 0.0159, MINERAL_OIL, bulk_modulus=178e6)
        >>> H = line.transfer(2j * 3.141592653589793 * 1e-4, "PQ")
        >>> round(abs(H[0, 0]), 6), round(-H[0, 1].real / line.resistance, 4)
        (1.0, 1.0)
        """
        form = check_form(form)
        s = np.asarray(s, dtype=complex)
        gamma, zc = self.propagation(s, friction, alpha, beta)
        # Overflow-free hyperbolics via e = exp(-2 Gamma), |e| <= 1 for Re(Gamma) >= 0.
        flip = np.real(gamma) < 0
        g = np.where(flip, -gamma, gamma)
        e = np.exp(-2.0 * g)
        sgn = np.where(flip, -1.0, 1.0)
        sech = 2.0 * np.exp(-g) / (1.0 + e)            # even in Gamma
        tanh = sgn * (1.0 - e) / (1.0 + e)             # odd
        csch = sgn * 2.0 * np.exp(-g) / (1.0 - e)      # odd
        coth = sgn * (1.0 + e) / (1.0 - e)             # odd
        out = np.empty(s.shape + (2, 2), dtype=complex)
        if form == "PQ":
            out[..., 0, 0], out[..., 0, 1] = sech, -zc * tanh
            out[..., 1, 0], out[..., 1, 1] = tanh / zc, sech
        elif form == "QP":
            out[..., 0, 0], out[..., 0, 1] = zc * tanh, sech
            out[..., 1, 0], out[..., 1, 1] = sech, -tanh / zc
        elif form == "PP":
            out[..., 0, 0], out[..., 0, 1] = coth / zc, -csch / zc
            out[..., 1, 0], out[..., 1, 1] = csch / zc, -coth / zc
        else:  # QQ
            out[..., 0, 0], out[..., 0, 1] = zc * coth, -zc * csch
            out[..., 1, 0], out[..., 1, 1] = zc * csch, -zc * coth
        return out

    def steady_state(self, form: str, u):
        """Laminar steady state of the line (M12) for constant inputs ``u`` of a form.

        PQ: P_d = P_u - R Q_d, Q_u = Q_d.  QP: P_u = P_d + R Q_u, Q_d = Q_u.
        PP: Q_u = Q_d = (P_u - P_d)/R.

        Parameters
        ----------
        form : str
            "PQ", "QP" or "PP".
        u : array_like
            The form's two inputs in form order, pressures [Pa] and flows [m^3/s].

        Returns
        -------
        ndarray
            The two outputs in form order, [Pa] and [m^3/s].

        Raises
        ------
        ValueError
            For the QQ form, which has no steady state unless Q_u = Q_d (and then the mean
            pressure is undetermined).
        """
        form = check_form(form)
        a, b = (float(v) for v in u)
        R = self.resistance
        if form == "PQ":
            return np.array([a - R * b, b])
        if form == "QP":
            return np.array([b + R * a, a])
        if form == "PP":
            return np.array([(a - b) / R, (a - b) / R])
        raise ValueError("form QQ has no unique steady state (its pressure level integrates the net flow)")
