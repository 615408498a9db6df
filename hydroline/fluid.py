"""Hydraulic fluid properties (SI units throughout).

The oil is described by its density, kinematic viscosity and the bulk modulus of the pure,
air-free oil; the *effective* bulk modulus of the oil in a hose (oil, hose wall and entrained
air in series, model reference section 2) is what sets a line's wave speed (M2).
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Fluid", "effective_bulk_modulus", "MINERAL_OIL", "require_positive"]


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

    def __post_init__(self):
        object.__setattr__(self, "density", _positive("density", self.density, "kg/m^3"))
        object.__setattr__(self, "kinematic_viscosity",
                           _positive("kinematic_viscosity", self.kinematic_viscosity, "m^2/s"))
        object.__setattr__(self, "bulk_modulus", _positive("bulk_modulus", self.bulk_modulus, "Pa"))

    @property
    def dynamic_viscosity(self) -> float:
        """Dynamic viscosity mu = rho*nu, [Pa s]."""
        return self.density * self.kinematic_viscosity


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
