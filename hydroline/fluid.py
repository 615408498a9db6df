"""Hydraulic fluid properties (SI units throughout).

The oil is described by its density, kinematic viscosity and the bulk modulus of the pure,
air-free oil; the *effective* bulk modulus of the oil in a hose (oil, hose wall and entrained
air in series, model reference section 2) is what sets a line's wave speed (M2).
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Fluid", "effective_bulk_modulus", "MINERAL_OIL", "require_positive",
           "entrained_air_bulk_modulus", "oil_compliance", "cavity_volume_fraction",
           "chamber_pressure_scale", "cavity_compliance", "chamber_structure", "oil_numbers",
           "ATMOSPHERE"]

#: Standard atmosphere, the pressure at which ``Fluid.air_content`` is stated, [Pa] absolute.
ATMOSPHERE = 101325.0


def require_positive(name: str, value: float, unit: str) -> float:
    """A positive finite number, or ValueError naming the parameter and its unit.

    Parameters
    ----------
    name : str
        Parameter name for the message, e.g. "diameter".
    value : float
        The value, [unit].
    unit : str
        Its SI unit for the message, e.g. "m".

    Returns
    -------
    float
        ``value`` as a float, [unit].

    Raises
    ------
    ValueError
        If the value is zero, negative, NaN or infinite.

    Examples
    --------
    >>> require_positive("diameter", -0.0127, "m")
    Traceback (most recent call last):
    ...
    ValueError: diameter must be a positive finite number in [m], got -0.0127
    """
    value = float(value)
    if not value > 0 or value != value or value == float("inf"):
        raise ValueError(f"{name} must be a positive finite number in [{unit}], got {value!r}")
    return value


_positive = require_positive     # the former private name


@dataclass(frozen=True)
class Fluid:
    """A hydraulic fluid.

    Parameters
    ----------
    density : float
        Mass density rho, [kg/m^3].
    kinematic_viscosity : float
        Kinematic viscosity nu, [m^2/s].
    bulk_modulus : float
        Isentropic bulk modulus of the pure (air-free) oil, [Pa].
    air_content : float
        Volume fraction of entrained (undissolved) free air at atmospheric pressure
        (:data:`ATMOSPHERE`), in [0, 1), [-]; 0: air-free oil (M40).
    air_polytropic_exponent : float
        Polytropic exponent n of the entrained air, 1 (isothermal) ... 1.4 (adiabatic), [-] (M40).
    cavity_pressure : float or None
        Absolute pressure p_cav held by a gas/vapour cavity, [Pa]: below it chambers and
        volumes (M42) and the hose ends whose pressure a line puts out (M45) open a cavity;
        None (a ``Fluid``'s default; a rig's ``cavity_pressure = "off"``): no cavity model
        (pressures may fall below it, as before; the run warns). A rig's oil takes 5 kPa
        unless the rig says otherwise (:func:`hydroline.circuit.rig_fluid`).
    cavity_pressure_drop : float
        Regularisation of the cavity (M42): the pressure falls this much below ``cavity_pressure``
        per unit cavity volume fraction (0 would be an ideal constant-pressure cavity), [Pa].

    Raises
    ------
    ValueError
        If a property is not a positive finite number; the message names it and its unit.

    Examples
    --------
    ISO VG 32 oil at 40 degC (32 cSt); its dynamic viscosity mu = rho nu:

    >>> oil = Fluid(density=870.0, kinematic_viscosity=32e-6, bulk_modulus=1.5e9)
    >>> round(oil.dynamic_viscosity, 5)     # [Pa s]
    0.02784
    """

    density: float
    kinematic_viscosity: float
    bulk_modulus: float
    air_content: float = 0.0
    air_polytropic_exponent: float = 1.0
    cavity_pressure: float | None = None
    cavity_pressure_drop: float = 1e3

    def __post_init__(self):
        object.__setattr__(self, "density", _positive("density", self.density, "kg/m^3"))
        object.__setattr__(self, "kinematic_viscosity",
                           _positive("kinematic_viscosity", self.kinematic_viscosity, "m^2/s"))
        object.__setattr__(self, "bulk_modulus", _positive("bulk_modulus", self.bulk_modulus, "Pa"))
        a = float(self.air_content)
        if not 0.0 <= a < 1.0:
            raise ValueError(f"air_content must lie in [0, 1) [-], got {self.air_content!r}")
        object.__setattr__(self, "air_content", a)
        n = float(self.air_polytropic_exponent)
        if not 1.0 <= n <= 5.0 / 3.0:
            raise ValueError(f"air_polytropic_exponent must lie in [1, 1.667] [-], "
                             f"got {self.air_polytropic_exponent!r}")
        object.__setattr__(self, "air_polytropic_exponent", n)
        if self.cavity_pressure is not None:
            pc = float(self.cavity_pressure)
            if not 0.0 <= pc < 1e7:
                raise ValueError(f"cavity_pressure must lie in [0, 1e7) [Pa] absolute, "
                                 f"got {self.cavity_pressure!r}")
            object.__setattr__(self, "cavity_pressure", pc)
        object.__setattr__(self, "cavity_pressure_drop",
                           _positive("cavity_pressure_drop", self.cavity_pressure_drop, "Pa"))

    @property
    def entrained_air(self) -> bool:
        """True where the oil carries entrained air (M40): ``air_content`` not 0 (or a
        compiled model's symbol for it, :func:`oil_numbers`)."""
        return _symbolic(self.air_content) or self.air_content != 0.0

    @property
    def plain(self) -> bool:
        """True for air-free oil without a cavity model: every compliance is ``V/beta`` (M22)."""
        return not self.entrained_air and self.cavity_pressure is None

    def chamber_model(self) -> tuple:
        """Which of the oil's models a chamber's pressure equation reads (:func:`oil_compliance`,
        M40-M42): nothing for :attr:`plain` oil; its density, viscosity and bulk modulus
        never (a chamber has its own modulus; the hoses take the oil's through their line
        matrices). A compiled chamber's structure holds this instead of the whole oil: the
        numbers of the models it reads are runtime numbers of the compiled model
        (:func:`oil_numbers`), so that oils that differ only in numbers share its library.

        Returns
        -------
        tuple
            ``()`` for plain oil, else ``(entrained air, cavity model)``, each True or False.
        """
        if self.plain:
            return ()
        return (self.entrained_air, self.cavity_pressure is not None)

    @property
    def dynamic_viscosity(self) -> float:
        """Dynamic viscosity mu = rho*nu, [Pa s]."""
        return self.density * self.kinematic_viscosity


def _symbolic(value) -> bool:
    """True for a CasADi expression (a compiled model's symbol for a number)."""
    return type(value).__module__.startswith("casadi")


def oil_numbers(fluid: "Fluid | None", air: bool = True) -> dict:
    """The numbers of the oil's entrained air (M40) and cavity model (M42, M45) that a
    chamber's or a hose end's equations read, as the component's runtime numbers of the
    compiled model (:meth:`~hydroline.engine.Component.compiled_numbers`): a rig that differs
    only in them (another cavity pressure, air content) runs on the same compiled library.
    Whether each model is on (air-free oil, ``cavity_pressure`` None) is structure
    (:meth:`Fluid.chamber_model`). The state scales that follow from them
    (:func:`chamber_pressure_scale`) are runtime numbers as every state scale is.

    Parameters
    ----------
    fluid : Fluid or None
        The rig's oil; None: none.
    air : bool
        Include the entrained air's numbers (a chamber's compliance reads them; a hose end's
        cavity does not).

    Returns
    -------
    dict
        ``"fluid.<field>"`` -> value, [SI]: ``air_content`` [-] and
        ``air_polytropic_exponent`` [-] with entrained air, ``cavity_pressure`` [Pa] and
        ``cavity_pressure_drop`` [Pa] with a cavity model; empty for plain oil.

    Examples
    --------
    >>> oil = Fluid(870.0, 32e-6, 1.4e9, cavity_pressure=5e3)
    >>> oil_numbers(oil)
    {'fluid.cavity_pressure': 5000.0, 'fluid.cavity_pressure_drop': 1000.0}
    """
    if fluid is None:
        return {}
    out = {}
    if air and fluid.entrained_air:
        out["fluid.air_content"] = fluid.air_content
        out["fluid.air_polytropic_exponent"] = fluid.air_polytropic_exponent
    if fluid.cavity_pressure is not None:
        out["fluid.cavity_pressure"] = fluid.cavity_pressure
        out["fluid.cavity_pressure_drop"] = fluid.cavity_pressure_drop
    return out


def chamber_structure(attributes: dict) -> dict:
    """A chamber component's structure attributes with its oil standing as what its pressure
    equation reads of it (:meth:`Fluid.chamber_model`), for
    :meth:`~hydroline.engine.Component.structure_attributes` of the actuator and the
    hydraulic volume.

    Parameters
    ----------
    attributes : dict
        Name -> value or mark, as the component's base class gives them (changed in place).

    Returns
    -------
    dict
        The same dict, its ``"fluid"`` entry (where not None) replaced by
        ``("chamber model", fluid.chamber_model())``.
    """
    if attributes.get("fluid") is not None:
        attributes["fluid"] = ("chamber model", attributes["fluid"].chamber_model())
    return attributes


#: ISO VG 32 mineral hydraulic oil near 40 degC: rho = 870 kg/m^3, nu = 32 cSt
#: (ISO 3448 grade mid-point), pure-oil bulk modulus 1.5 GPa (McCloy & Martin,
#: "Control of Fluid Power", typical mineral oil value).
MINERAL_OIL = Fluid(density=870.0, kinematic_viscosity=3.2e-5, bulk_modulus=1.5e9)


def effective_bulk_modulus(oil_bulk_modulus: float, wall_bulk_modulus: float | None = None,
                           air_fraction: float = 0.0, pressure: float | None = None,
                           polytropic_exponent: float = 1.0) -> float:
    """Effective bulk modulus of oil in a compliant hose, compliances in series.

    ``1/beta_e = 1/beta_oil + 1/beta_wall + (V_air/V_total)/beta_air`` (model reference,
    section 2), with the air's bulk modulus ``beta_air = m * p`` (polytropic gas at absolute
    pressure p).

    Parameters
    ----------
    oil_bulk_modulus : float
        Bulk modulus of the pure oil, [Pa].
    wall_bulk_modulus : float or None
        Effective bulk modulus of the hose wall, ``V dp/dV`` of the hose volume alone (for a
        thin elastic tube ``E t / d``), [Pa]; None for a rigid wall.
    air_fraction : float
        Volume fraction of entrained (undissolved) air at ``pressure``, in [0, 1), [-].
    pressure : float or None
        Absolute pressure at which the air fraction is given, [Pa]; required when
        ``air_fraction > 0``.
    polytropic_exponent : float
        Exponent m of the air, 1 (isothermal) ... 1.4 (adiabatic), [-].

    Returns
    -------
    float
        Effective bulk modulus beta_e, [Pa].

    Raises
    ------
    ValueError
        If a modulus or pressure is not positive and finite, the air fraction is outside
        [0, 1), or ``pressure`` is missing with air present.

    Examples
    --------
    Oil (1.5 GPa) in a hose whose wall alone has 300 MPa: ``1/(1/1.5e9 + 1/3e8)`` = 250 MPa,
    and 0.5 % of isothermal air at 20.7 MPa absolute (``beta_air = p``) brings it to
    ``1/(4e-9 + 2.415e-10)`` = 235.8 MPa:

    >>> round(effective_bulk_modulus(1.5e9, 3e8) / 1e6, 6)
    250.0
    >>> round(effective_bulk_modulus(1.5e9, 3e8, air_fraction=0.005, pressure=20.7e6) / 1e6, 1)
    235.8
    """
    compliance = 1.0 / _positive("oil_bulk_modulus", oil_bulk_modulus, "Pa")
    if wall_bulk_modulus is not None:
        compliance += 1.0 / _positive("wall_bulk_modulus", wall_bulk_modulus, "Pa")
    if air_fraction:
        if not 0 < air_fraction < 1:
            raise ValueError(f"air_fraction must lie in [0, 1) [-], got {air_fraction!r}")
        if pressure is None:
            raise ValueError("pressure [Pa] (absolute) is required when air_fraction > 0")
        beta_air = _positive("polytropic_exponent", polytropic_exponent, "-") * _positive(
            "pressure", pressure, "Pa")
        compliance += air_fraction / beta_air
    return 1.0 / compliance


def entrained_air_bulk_modulus(pressure, oil_bulk_modulus: float, air_content: float,
                               polytropic_exponent: float = 1.0,
                               reference_pressure: float = ATMOSPHERE):
    """Effective bulk modulus of oil with entrained free air at an absolute pressure (M40).

    A fixed mass of mixture holds, at the reference (atmospheric) pressure ``p0``, the air
    volume fraction ``a``; the oil is compressed with its constant modulus ``K_L``, the air
    polytropically (``p V^n`` constant), and no air dissolves or comes out of solution
    (Merritt 1967, section 2.6; the "model based on the definition of the bulk modulus" of
    Gholizadeh, Burton & Schoenau 2011). Per unit mixture volume at ``p0``::

        v_L(p) = (1 - a) exp(-(p - p0)/K_L),    v_g(p) = a (p0/p)^(1/n)
        K_eff(p) = -v dp/dv = (v_L + v_g) / (v_L/K_L + v_g/(n p))

    Evaluates on numbers and on CasADi expressions (:mod:`hydroline.engine.ops`).

    Parameters
    ----------
    pressure : float or CasADi expression
        Absolute pressure p > 0, [Pa].
    oil_bulk_modulus : float
        K_L of the air-free oil (with its wall where the caller lumps one in), [Pa].
    air_content : float
        a, free-air volume fraction at ``reference_pressure``, [-].
    polytropic_exponent : float
        n of the air, [-].
    reference_pressure : float
        p0, the pressure at which ``air_content`` is stated, [Pa] absolute.

    Returns
    -------
    float or CasADi expression
        K_eff(p), [Pa]; ``oil_bulk_modulus`` itself (the same object) when ``air_content`` is 0.

    Examples
    --------
    1 % of isothermal air in 1.5 GPa oil at 1 MPa: ``v_L = 0.99 exp(-0.000599) = 0.989407``,
    ``v_g = 0.01 * 0.101325``, ``K_eff = 0.990420/(0.989407/1.5e9 + 0.00101325/1e6)``
    = 592.05 MPa; at 20 MPa the air is 5.1e-5 of the volume and K_eff is 1.494 GPa:

    >>> round(float(entrained_air_bulk_modulus(1e6, 1.5e9, 0.01)) / 1e6, 2)
    592.05
    >>> round(float(entrained_air_bulk_modulus(20e6, 1.5e9, 0.01)) / 1e9, 3)
    1.494
    """
    if not _symbolic(air_content) and not air_content:
        return oil_bulk_modulus
    from .engine import ops      # here: the lines import this module without the engine

    a, n, p0, K = air_content, polytropic_exponent, reference_pressure, oil_bulk_modulus
    v_l = (1.0 - a) * ops.exp(-(pressure - p0) / K)
    v_g = a * ops.power(p0 / pressure, 1.0 / n)
    return (v_l + v_g) / (v_l / K + v_g / (n * pressure))


def cavity_volume_fraction(pressure, cavity_pressure: float, pressure_drop: float):
    """Gas/vapour cavity volume over the chamber volume at an absolute pressure (M42).

    Zero at and above ``p_cav``; below it the cavity compliance per unit volume rises as a
    smoothstep over ``delta`` to ``1/delta`` and stays there, so the pressure falls ``delta``
    per unit cavity fraction (a stiff plateau regularising the ideal constant-pressure
    cavity; the model is C1 in p). With ``x = (p_cav - p)/delta``::

        -dphi/dp = (3 x^2 - 2 x^3)/delta,  phi = x^3 - x^4/2   for 0 <= x <= 1
        -dphi/dp = 1/delta,                phi = x - 1/2       for x > 1

    Parameters
    ----------
    pressure : float or CasADi expression
        Absolute pressure, [Pa].
    cavity_pressure : float
        p_cav, [Pa] absolute.
    pressure_drop : float
        delta, [Pa].

    Returns
    -------
    float or CasADi expression
        phi >= 0, [-].

    Examples
    --------
    >>> float(cavity_volume_fraction(2e3, 1e3, 1e3)), float(cavity_volume_fraction(-1e3, 1e3, 1e3))
    (0.0, 1.5)
    """
    import numpy as np

    from .engine import ops

    x = ops.fmax((cavity_pressure - pressure) / pressure_drop, 0.0)
    if not ops.is_symbolic(x) and not np.any(np.asarray(x) > 0):   # (no cavity in a run)
        return x
    xs = ops.fmin(x, 1.0)
    return xs**3 - 0.5 * xs**4 + ops.fmax(x - 1.0, 0.0)


def chamber_pressure_scale(nominal_pressure: float, fluid: "Fluid | None") -> float:
    """Typical magnitude of a chamber's pressure state (the integrators' absolute tolerance is
    ``atol_scale`` times it, the steady state's residual is scaled by it), [Pa].

    Without a cavity model the chamber's nominal pressure. With one (M42), at most
    ``100 delta``: a cavity closing under an inflow hands the chamber's compliance from
    ``V/delta`` to ``V/K`` within ``delta sqrt(delta / 3K)`` of ``p_cav`` (0.5 Pa at
    delta = 1 kPa, K = 1.4 GPa). An absolute tolerance of 1 Pa (the default 1e-7 of a 10 MPa
    scale) let BDF (CVODES, SciPy, the compiled core) step over that hand-over and accept a
    step that fell ~7 kPa while dp/dt was positive, leaving a cavity of several chamber
    volumes that no flow made (an oil balance missing by the whole cavity); which run did so
    was set by rounding in the rest state. At ``100 delta`` the tolerance is 0.01 Pa.

    Parameters
    ----------
    nominal_pressure : float
        The chamber's nominal pressure, [Pa].
    fluid : Fluid or None
        The rig's oil; None: plain oil.

    Returns
    -------
    float
        The scale, [Pa].

    Examples
    --------
    >>> oil = Fluid(870.0, 32e-6, 1.4e9, cavity_pressure=5e3)
    >>> chamber_pressure_scale(1e7, oil), chamber_pressure_scale(1e7, None)
    (100000.0, 10000000.0)
    """
    if fluid is None or fluid.cavity_pressure is None:
        return float(nominal_pressure)
    return min(float(nominal_pressure), 100.0 * fluid.cavity_pressure_drop)


def oil_compliance(volume, pressure, bulk_modulus: float, fluid: "Fluid | None"):
    """``dV_oil/dp`` of a chamber of oil, entrained air and a cavity: ``V/K_eff(p) + V dphi/dp``
    (M40, M42), the denominator of every chamber pressure equation (M22, M41), [m^3/Pa].

    Parameters
    ----------
    volume : float or CasADi expression
        Chamber volume V, [m^3].
    pressure : float or CasADi expression
        Its absolute pressure, [Pa].
    bulk_modulus : float
        The chamber's oil bulk modulus (the component's), [Pa].
    fluid : Fluid or None
        The rig's oil: its air content and cavity model; None or a :attr:`Fluid.plain` fluid:
        ``V/beta``.

    Returns
    -------
    float or CasADi expression
        The compliance, [m^3/Pa].
    """
    if fluid is None or fluid.plain:
        return volume / bulk_modulus
    from .engine import ops

    K = entrained_air_bulk_modulus(ops.fmax(pressure, 1e3), bulk_modulus, fluid.air_content,
                                   fluid.air_polytropic_exponent)
    c = volume / K
    if fluid.cavity_pressure is not None:
        c = c + cavity_compliance(volume, pressure, fluid)
    return c


def cavity_compliance(volume, pressure, fluid: "Fluid"):
    """``-dV_cav/dp`` of a gas/vapour cavity (M42): ``V sigma(x)/delta``, the cavity's share of
    a chamber's compliance (:func:`oil_compliance`) and of a hose end's (M45), [m^3/Pa].

    With ``x = (p_cav - p)/delta``, ``sigma = 3 x^2 - 2 x^3`` for ``0 <= x <= 1`` and 1 beyond:
    zero at and above ``p_cav``, ``V/delta`` on the cavity's plateau; the derivative of
    ``-V`` :func:`cavity_volume_fraction`.

    Parameters
    ----------
    volume : float or CasADi expression
        Reference volume V of the cavity law (a chamber's volume, a hose's bore volume), [m^3].
    pressure : float, ndarray or CasADi expression
        Absolute pressure, [Pa].
    fluid : Fluid
        The oil, with ``cavity_pressure`` (p_cav, not None) and ``cavity_pressure_drop``
        (delta).

    Returns
    -------
    float, ndarray or CasADi expression
        ``V sigma/delta >= 0``, [m^3/Pa].

    Examples
    --------
    Half a drop below p_cav the smoothstep is at 1/2; on the plateau ``V/delta``:

    >>> oil = Fluid(870.0, 3.2e-5, 1.5e9, cavity_pressure=5e3, cavity_pressure_drop=1e3)
    >>> float(cavity_compliance(2.0, 4.5e3, oil)), float(cavity_compliance(2.0, 0.0, oil))
    (0.001, 0.002)
    """
    from .engine import ops

    d = fluid.cavity_pressure_drop
    x = ops.fmin(ops.fmax((fluid.cavity_pressure - pressure) / d, 0.0), 1.0)
    return volume / d * (3.0 * x**2 - 2.0 * x**3)          # -dphi/dp, the cavity
